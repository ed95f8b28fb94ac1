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



def test_an_arm_with_dry_friction_gets_its_coulomb_friction_while_the_reference_moves_and_reaches_its_goals(
        tmp_path):
    """Oracle: the same arm without friction loss; its feedforward plus frictionloss sign(qd_ref) is the friction
    arm's. With it the friction arm's nominal moves reach their goals (an arm of makers' kind: motor armature on
    every joint, 1.2 N m of friction loss; without it they ended short)."""
    from arm_suite import chain

    from mjtraj.study import compare, scenario_for_model

    links = [("0 0 1", "-3 3", 0.15, 3.0), ("0 1 0", "-2 2", 0.3, 2.0), ("0 1 0", "-2.5 2.5", 0.25, 0.3),
             ("0 0 1", "-3 3", 0.06, 0.2)]
    rough, smooth = tmp_path / "rough.xml", tmp_path / "smooth.xml"
    rough.write_text(chain("rough", links, joint_extra=' damping="1" armature="0.01" frictionloss="1.2"'))
    smooth.write_text(chain("smooth", links, joint_extra=' damping="1" armature="0.01"'))
    a, b = scenario_for_model(rough), scenario_for_model(smooth)
    ref = a.planner("cubic").plan(a.task, a.model)
    expected = feedforward(b.model, ref) + 1.2 * np.sign(ref.qd[:-1])
    np.testing.assert_array_equal(feedforward(a.model, ref), expected)
    result = compare(a)
    move = float(np.max(np.abs(a.task.qg - a.task.q0)))
    for planner in ("cubic", "quintic", "trapezoidal"):
        assert result.metrics[planner].terminal_err < 0.2 * move, planner
