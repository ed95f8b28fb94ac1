"""The exact active-set Riccati solver against OSQP on the paper's QP."""


from __future__ import annotations

import numpy as np

from mjtraj.core.planners import make
from mjtraj.core.task import random_task


def test_active_set_riccati_equals_osqp(model, rng):
    """The exact solver and OSQP agree on random tasks, with and without active torque bounds."""
    tasks = [random_task(rng, model, max_displacement=1.5, duration=T, dt=0.02) for T in (2.0, 0.6, 0.8) * 4]
    auto, osqp = make("optimal"), make("optimal", solver="osqp")
    plans = auto.plan_many(tasks, model)
    active = 0
    for task, ref in zip(tasks, plans, strict=True):
        try:
            expected = osqp.plan(task, model)
        except Exception as e:  # noqa: BLE001
            assert type(ref) is type(e)
            continue
        assert ref.info["solver"] == "riccati-active-set"
        active += ref.info["active_bounds"] > 0
        np.testing.assert_allclose(ref.u_plan, expected.u_plan, atol=1e-6)
        assert ref.info["objective"] <= expected.info["objective"] * (1 + 1e-9)
        assert ref.info["terminal_residual"] < 1e-9
    assert active >= 2  # the bounds bind in some of them

