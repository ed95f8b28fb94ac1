"""The one closed loop: control law by hand, batch == single bit for bit, exact tracking of a realisable
reference, gravity-compensation modes, divergence isolation."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.model import default_model_path
from mjtraj.core.planners import make
from mjtraj.core.reference import Reference
from mjtraj.exceptions import InvalidInputError


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



def test_batch_equals_single_runs_bit_for_bit(model, scenario, task):
    refs = [make(name).plan(task, model) for name in ("optimal", "cubic", "quintic", "trapezoidal")]
    batch = ClosedLoop(model, scenario.loop, nsim=4).run(refs)
    for b, ref in enumerate(refs):
        single = ClosedLoop(model, scenario.loop, nsim=1).run([ref])
        for name in ("q", "qd", "e", "ed", "tau_ff", "tau_fb", "dtau", "saturated", "q_final"):
            np.testing.assert_array_equal(getattr(single, name)[0], getattr(batch, name)[b], err_msg=name)



@pytest.mark.parametrize("substeps", [1, 4])
def test_exact_tracking_of_a_realisable_reference(model, scenario, rng, substeps):
    """With the plan's own torque as feedforward, the plant follows its own trajectory: every error is zero."""
    fine = mujoco.MjModel.from_xml_path(str(default_model_path()))
    fine.opt.timestep = model.opt.timestep / substeps
    ref = realisable_reference(fine, rng, substeps=substeps)
    config = dataclasses.replace(scenario.loop, feedforward="planned", substeps=substeps)
    rollout = ClosedLoop(model, config).run([ref])
    assert np.max(np.abs(rollout.e)) == 0.0 and np.max(np.abs(rollout.ed)) == 0.0
    np.testing.assert_array_equal(rollout.dtau[0], ref.u_plan)



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
    from mjtraj.core.task import Task

    slow = make("cubic").plan(Task.create(task.q0, task.qg, 2.0, 0.04), model)
    with pytest.raises(InvalidInputError, match=r"^references: expected the control period dt=0.02 s of the model, "
                                                r"got 0.04 s from 'cubic'$"):
        ClosedLoop(model, scenario.loop).run([slow])



def test_the_number_of_periods_is_bounded(scenario):
    from mjtraj.core.task import MAX_STEPS, Task

    with pytest.raises(InvalidInputError, match=rf"^duration, dt: expected at most MAX_STEPS = {MAX_STEPS} control "
                                                r"periods, got 2.0 s / 1e-09 s = 2e\+09$"):
        Task.create(scenario.task.q0, scenario.task.qg, 2.0, 1e-9)


def test_restarting_every_simulation_on_another_length_starts_the_batch_afresh(model, scenario, rng):
    """Oracle: a fresh loop started on the same references (in row order)."""
    refs = [realisable_reference(model, rng, steps=30) for _ in range(3)]
    longer = [realisable_reference(model, rng, steps=45) for _ in range(3)]
    loop = ClosedLoop(model, scenario.loop, nsim=3)
    loop.start(refs)
    for _ in range(7):
        loop.step()
    loop.restart([2, 0, 1], [longer[2], longer[0], longer[1]])
    fresh = ClosedLoop(model, scenario.loop, nsim=3)
    fresh.start(longer)
    assert loop.steps == 45
    for _ in range(45):
        loop.step()
        fresh.step()
    np.testing.assert_array_equal(loop.rollout().e, fresh.rollout().e)


@pytest.mark.parametrize("controller", ["pid", "adaptive_computed_torque"])
def test_references_of_several_lengths_run_side_by_side_as_each_alone(model, scenario, rng, controller):
    """Oracle: each simulation run alone on its reference. Started on references of 30, 45 and 20 periods, then
    the shortest restarted on 50 (longer than the arrays were) and another on 25 (shorter): every episode's
    records, final state and metrics equal its own single-simulation loop's, bit for bit; each ends at its own N
    (`done`, `ends`); a rollout of simulations of several lengths is refused, one of one length is not."""
    import dataclasses

    config = dataclasses.replace(scenario.loop, controller=controller)
    lengths = [30, 45, 20]
    refs = [realisable_reference(model, rng, steps=n) for n in lengths]
    later = {2: realisable_reference(model, rng, steps=50), 0: realisable_reference(model, rng, steps=25)}
    loop = ClosedLoop(model, config, nsim=3)
    loop.start(refs)
    np.testing.assert_array_equal(loop.ends, lengths)
    episodes = []
    for k in range(70):
        if k == 20:
            assert loop.done.tolist() == [False, False, True]
            episodes.append((refs[2], loop.rollout([2])))
            loop.restart([2], [later[2]])
        if k == 30:
            assert loop.done[0] and not loop.done[1]
            episodes.append((refs[0], loop.rollout([0])))
            loop.restart([0], [later[0]])
        loop.step()
    assert loop.done.all() and loop.steps == 50  # room for the longest
    np.testing.assert_array_equal(loop.ends, [25, 45, 50])
    episodes += [(later[0], loop.rollout([0])), (refs[1], loop.rollout([1])), (later[2], loop.rollout([2]))]
    with pytest.raises(InvalidInputError, match=r"^ids: expected simulations running references of one length, got "
                                                r"N from 25 to 50$"):
        loop.rollout()
    for ref, got in episodes:
        alone = ClosedLoop(model, config, nsim=1).run([ref])
        for name in ("q", "qd", "e", "dtau", "tau_fb", "saturated"):
            np.testing.assert_array_equal(getattr(got, name), getattr(alone, name), err_msg=name)
        np.testing.assert_array_equal(got.q_final, alone.q_final)
        np.testing.assert_array_equal(got.e_final, alone.e_final)


def test_a_previewing_law_refuses_references_of_several_lengths(model, scenario, rng):
    import dataclasses

    config = dataclasses.replace(scenario.loop, controller="mpc")
    refs = [realisable_reference(model, rng, steps=n) for n in (30, 20)]
    with pytest.raises(InvalidInputError, match=r"^references: the control law 'mpc' previews the reference; give it "
                                                r"references of one length per batch, got N from 20 to 30$"):
        ClosedLoop(model, config, nsim=2).start(refs)


def test_noise_of_the_wrong_shape_is_refused_naming_the_shape_expected(model, scenario, rng):
    refs = [realisable_reference(model, rng, steps=n) for n in (30, 20)]
    loop = ClosedLoop(model, scenario.loop, nsim=2)
    with pytest.raises(InvalidInputError, match=r"^noise: expected finite values of shape \(30, 2, 6\) \(the longest "
                                                r"reference's N\), got shape \(20, 2, 6\)$"):
        loop.start(refs, noise=np.zeros((20, 2, 6)))
    with pytest.raises(InvalidInputError, match=r"^noise: expected finite values of shape \(30, 2, 6\), got shape "
                                                r"\(30, 2, 6\)$"):
        loop.start([refs[0], refs[0]], noise=np.full((30, 2, 6), np.nan))
