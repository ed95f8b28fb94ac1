"""Feedforward modes: inverse dynamics by definition, and the planned mode's need for u_plan."""


from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjtraj.core.feedforward import feedforward
from mjtraj.core.planners import make
from mjtraj.exceptions import InvalidInputError


def test_feedforward_inverse_by_definition(model, task):
    ref = make("quintic").plan(task, model)
    ff = feedforward(model, ref)
    data = mujoco.MjData(model)
    k = 37
    data.qpos[:], data.qvel[:] = ref.q[k], ref.qd[k]
    mujoco.mj_forward(model, data)
    D = np.zeros((3, 3))
    mujoco.mj_fullM(model, data, D)
    # ID - G = D qdd + C qd = D qdd + (bias - G)
    np.testing.assert_allclose(ff[k], D @ ref.qdd[k] + data.qfrc_bias - data.qfrc_gravcomp, atol=1e-9)
    step = feedforward(model, ref, accel="step_average")
    np.testing.assert_allclose(step[k], D @ ((ref.qd[k + 1] - ref.qd[k]) / task.dt) + data.qfrc_bias
                               - data.qfrc_gravcomp, atol=1e-9)
    np.testing.assert_array_equal(feedforward(model, ref, mode="none"), 0.0)


def test_planned_feedforward_needs_u_plan(model, task):
    with pytest.raises(InvalidInputError, match=r"^feedforward: mode 'planned' needs a planner that publishes u_plan; "
                                                r"the 'cubic' reference has none; valid for it: inverse, none$"):
        feedforward(model, make("cubic").plan(task, model), mode="planned")

