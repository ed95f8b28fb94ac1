"""The stated PID gain rule, re-derived from the inertia each joint presents."""


from __future__ import annotations

import numpy as np

from mjtraj.core.gains import gain_rule


def test_gains_follow_the_rule(model, scenario):
    rule = gain_rule(model, scenario.task.q0, scenario.task.qg, scenario.task.dt)
    for name in ("kp", "ki", "kd"):
        np.testing.assert_allclose(getattr(scenario.loop.gains, name), getattr(rule, name), rtol=1e-12)

