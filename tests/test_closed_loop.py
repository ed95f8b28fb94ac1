"""The one closed loop: control law by hand, batch == single bit for bit, exact tracking of a realisable
reference, gravity-compensation modes, divergence isolation."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from mjtraj.closed_loop import ClosedLoop
from mjtraj.controller import PIDGains, control_law
from mjtraj.exceptions import InvalidInputError
from mjtraj.feedforward import feedforward
from mjtraj.planners import make
from mjtraj.reference import Reference


def test_control_law_by_hand():
    gains = PIDGains.create([10.0, 20.0], [1.0, 2.0], [3.0, 4.0], 2)
    e, ed, I = np.array([[0.1, -0.2]]), np.array([[1.0, 0.5]]), np.array([[0.01, 0.02]])
    out = control_law(e, ed, I, np.array([[5.0, 70.0]]), gains, np.array([60.0, 60.0]), 0.02)
    # I = [0.012, 0.016]; fb = [1 + 0.012 + 3, -4 + 0.032 + 2] = [4.012, -1.968]
    np.testing.assert_allclose(out.integral, [[0.012, 0.016]], atol=1e-15)
    np.testing.assert_allclose(out.tau_fb, [[4.012, -1.968]], atol=1e-12)
    np.testing.assert_allclose(out.dtau, [[9.012, 60.0]], atol=1e-12)
    np.testing.assert_array_equal(out.saturated, [[False, True]])
    clamp = control_law(e, ed, I, np.array([[5.0, 70.0]]), gains, np.array([60.0, 60.0]), 0.02, anti_windup="clamp")
    np.testing.assert_allclose(clamp.integral, [[0.012, 0.02]], atol=1e-15)  # frozen on the saturated joint
    torque = control_law(e, ed, I, np.zeros((1, 2)), gains, np.array([60.0, 60.0]), 0.02,
                         override=np.array([[-80.0, 3.0]]))
    np.testing.assert_array_equal(torque.dtau, [[-60.0, 3.0]])
    np.testing.assert_array_equal(torque.tau_fb, [[0.0, 0.0]])


def test_batch_equals_single_runs_bit_for_bit(model, scenario, task):
    refs = [make(name).plan(task, model) for name in ("optimal", "cubic", "quintic", "trapezoidal")]
    batch = ClosedLoop(model, scenario.loop, nsim=4).run(refs)
    for b, ref in enumerate(refs):
        single = ClosedLoop(model, scenario.loop, nsim=1).run([ref])
        for name in ("q", "qd", "e", "ed", "tau_ff", "tau_fb", "dtau", "saturated", "q_final"):
            np.testing.assert_array_equal(getattr(single, name)[0], getattr(batch, name)[b], err_msg=name)


def realisable_reference(model, rng, steps=60, substeps=1):
    """Simulate the nominal plant under random torques; the samples are a reference it can follow exactly."""
    data = mujoco.MjData(model)
    data.qpos[:] = [0.2, -1.2, 0.6]
    u = rng.uniform(-20, 20, size=(steps, 3))
    q, qd = [data.qpos.copy()], [data.qvel.copy()]
    for k in range(steps):
        data.ctrl[:] = u[k]
        for _ in range(substeps):
            mujoco.mj_step(model, data)
        q.append(data.qpos.copy())
        qd.append(data.qvel.copy())
    dt = model.opt.timestep * substeps
    return Reference("realisable", np.arange(steps + 1) * dt, np.array(q), np.array(qd),
                     np.zeros((steps + 1, 3)), u_plan=u)


@pytest.mark.parametrize("substeps", [1, 4])
def test_exact_tracking_of_a_realisable_reference(model, scenario, rng, substeps):
    """With the plan's own torque as feedforward, the plant follows its own trajectory: every error is zero."""
    fine = mujoco.MjModel.from_xml_path(str(__import__("mjtraj.model").model.default_model_path()))
    fine.opt.timestep = model.opt.timestep / substeps
    ref = realisable_reference(fine, rng, substeps=substeps)
    config = dataclasses.replace(scenario.loop, feedforward="planned", substeps=substeps)
    rollout = ClosedLoop(model, config).run([ref])
    assert np.max(np.abs(rollout.e)) == 0.0 and np.max(np.abs(rollout.ed)) == 0.0
    np.testing.assert_array_equal(rollout.dtau[0], ref.u_plan)


@pytest.mark.parametrize("mode", ["native", "zoh"])
def test_holding_a_pose(model, scenario, mode):
    """A constant reference at a loaded pose: gravity compensation alone holds it (no correction needed)."""
    pose = np.array([0.3, -0.4, 1.2])
    ref = Reference("hold", np.arange(51) * 0.02, np.tile(pose, (51, 1)), np.zeros((51, 3)), np.zeros((51, 3)))
    rollout = ClosedLoop(model, dataclasses.replace(scenario.loop, gravity_comp=mode)).run([ref])
    assert np.max(np.abs(rollout.e)) < 1e-12
    assert np.max(np.abs(rollout.dtau)) < 1e-9


def test_zoh_differs_from_native_on_a_moving_arm(model, scenario, task):
    ref = make("cubic").plan(task, model)
    native = ClosedLoop(model, scenario.loop).run([ref])
    zoh = ClosedLoop(model, dataclasses.replace(scenario.loop, gravity_comp="zoh")).run([ref])
    gap = np.max(np.abs(native.e - zoh.e))
    assert 1e-5 < gap < 0.05


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


def test_divergence_is_detected_per_scenario(model, scenario, task):
    """A reference that jumps 1 rad exceeds the error bound: that scenario is frozen and marked, while the
    other scenario of the same batch runs on exactly as it would alone."""
    cubic = make("cubic").plan(task, model)
    q = cubic.q.copy()
    q[40:] += 1.0
    jump = Reference("jump", cubic.t, q, cubic.qd, cubic.qdd)
    config = dataclasses.replace(scenario.loop, divergence_bound=0.5)
    both = ClosedLoop(model, config, nsim=2).run([jump, cubic])
    assert both.diverged.tolist() == [True, False]
    assert both.diverged_step[0] == 39                       # the step whose next error is the jump
    assert np.all(np.isnan(both.e[0, 40:])) and np.all(np.isfinite(both.e[0, :40]))
    alone = ClosedLoop(model, config, nsim=1).run([cubic])
    np.testing.assert_array_equal(both.e[1], alone.e[0])


def test_bad_loop_options(scenario):
    for field, value, valid in (("feedforward", "model", "inverse, planned, none"),
                                ("ff_accel", "mean", "sample, step_average"),
                                ("gravity_comp", "off", "native, zoh"), ("anti_windup", "reset", "none, clamp")):
        with pytest.raises(InvalidInputError, match=rf"^{field}: unknown value '{value}'; valid: {valid}$"):
            dataclasses.replace(scenario.loop, **{field: value})


def test_references_must_match_the_control_period(model, scenario, task):
    from mjtraj.task import Task

    slow = make("cubic").plan(Task.create(task.q0, task.qg, 2.0, 0.04), model)
    with pytest.raises(InvalidInputError, match=r"^references: expected the control period dt=0.02 s of the model, "
                                                r"got 0.04 s from 'cubic'$"):
        ClosedLoop(model, scenario.loop).run([slow])
