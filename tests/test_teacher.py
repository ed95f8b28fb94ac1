"""Teachers: any control law's command at the states of a running loop (`ClosedLoop.teach`), for imitation. The
oracle is the loop itself: a teacher of the loop's own law answers, every period, the command the loop applies, bit
for bit, on the fast path and off it (references of several lengths), with noise and a settle window; a teacher
changes nothing the loop does; driven by another law, a teacher's answer is its law's command at that state."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.settle import held
from mjtraj.domain.families import draw_scenario
from mjtraj.exceptions import InvalidInputError

LAWS = ("pid", "computed_torque", "adaptive_computed_torque", "mpc", "adaptive_mpc")


def _references(scenario, model, family: str, indices, window: int = 0):
    out = []
    for i in indices:
        drawn = draw_scenario(family, 0, i, model, scenario.task.dt)
        out.append(held(scenario.planner("cubic").plan(drawn.task, model), window, drawn.task.qg))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("law", LAWS)
def test_a_teacher_of_the_loops_own_law_answers_the_loops_command_bit_for_bit(law, scenario, model):
    """Two nominal references with measurement noise and a settle window (the predictive laws' v2 path)."""
    refs = _references(scenario, model, "nominal", [0, 0], window=5)
    config = dataclasses.replace(scenario.loop, controller=law)
    loop = ClosedLoop(model, config, nsim=2, teachers=(law,))
    noise = np.random.default_rng(0).standard_normal((refs[0].steps, 2, 2 * model.nv)) * 1e-3
    loop.start(refs, noise=noise)
    alone = ClosedLoop(model, config, nsim=2)
    alone.start(refs, noise=noise)
    for _ in range(loop.steps):
        answer = loop.teach(law)
        again = loop.teach(law)
        step = loop.step()
        assert again is answer
        np.testing.assert_array_equal(answer.dtau, step.control.dtau)
        np.testing.assert_array_equal(alone.step().control.dtau, step.control.dtau)  # the teacher changed nothing
    np.testing.assert_array_equal(loop.rollout().dtau, alone.rollout().dtau)


@pytest.mark.parametrize("law", ["pid", "adaptive_computed_torque"])
def test_off_the_fast_path_a_teacher_still_answers_the_loops_command(law, scenario, model):
    """References of several lengths (the aggressive family's) run side by side: each simulation at its own period,
    the shorter one ended first (its answers unused)."""
    refs = _references(scenario, model, "aggressive", [0, 1, 2])
    assert len({r.steps for r in refs}) > 1
    loop = ClosedLoop(model, dataclasses.replace(scenario.loop, controller=law), nsim=3, teachers=(law,))
    loop.start(refs)
    while not loop.done.all():
        live = ~loop.done
        answer = loop.teach(law)
        step = loop.step()
        np.testing.assert_array_equal(answer.dtau[live], step.control.dtau[live])


@pytest.mark.slow
@pytest.mark.parametrize("teacher", ["adaptive_computed_torque", "mpc"])
def test_a_teacher_shadows_every_period_whether_or_not_it_is_asked(teacher, scenario, model):
    """PID drives; the teacher's state (the adaptive estimate, the predictive law's prediction and disturbance)
    advances every period along PID's motion, so its answer at the last period is the same asked every period or
    only then; and it is its own law's command, not PID's."""
    refs = _references(scenario, model, "nominal", [3, 4])
    loops = [ClosedLoop(model, scenario.loop, nsim=2, teachers=(teacher,)) for _ in range(2)]
    for loop in loops:
        loop.start(refs)
    differs = False
    for _ in range(refs[0].steps - 1):
        answer = loops[0].teach(teacher)
        step = loops[0].step()
        loops[1].step()
        differs |= not np.array_equal(answer.dtau, step.control.dtau)
    np.testing.assert_array_equal(loops[0].teach(teacher).dtau, loops[1].teach(teacher).dtau)
    assert differs


@pytest.mark.parametrize("teacher", ["mpc", pytest.param("adaptive_mpc", marks=pytest.mark.slow)])
def test_a_predictive_teacher_counts_the_command_the_loop_applied(teacher, scenario, model):
    """PID drives, with noise and a settle window (protocol v2's filter). The teacher answers, every period, what
    its law commands in its own loop when that loop applies the same torques (the oracle: the law running the loop,
    with the residual that makes it apply PID's command): its filter counts the applied command, not its own, so it
    does not take their difference for a disturbance."""
    refs = _references(scenario, model, "nominal", [3, 4], window=5)
    noise = np.random.default_rng(1).standard_normal((refs[0].steps, 2, 2 * model.nv)) * 1e-3
    shadow = ClosedLoop(model, scenario.loop, nsim=2, teachers=(teacher,))
    own = ClosedLoop(model, dataclasses.replace(scenario.loop, controller=teacher), nsim=2, teachers=(teacher,))
    for loop in (shadow, own):
        loop.start(refs, noise=noise)
    for _ in range(refs[0].steps):
        answer, commanded = shadow.teach(teacher), own.teach(teacher)
        np.testing.assert_allclose(answer.dtau, commanded.dtau, rtol=1e-9, atol=1e-9)
        applied = shadow.step().control.dtau
        own.step(residual=applied - (commanded.tau_ff + commanded.tau_fb))  # its command, before the saturation
    np.testing.assert_allclose(own.rollout().q, shadow.rollout().q, rtol=0, atol=1e-12)  # the same motion


def test_teachers_are_named_control_laws(scenario, model):
    with pytest.raises(InvalidInputError, match=r"^teachers: expected control laws or estimators among .*mpc_filter, "
                                                r"got 'teacher'$"):
        ClosedLoop(model, scenario.loop, teachers=("teacher",))
    loop = ClosedLoop(model, scenario.loop, teachers=("mpc",))
    loop.start(_references(scenario, model, "nominal", [0]))
    with pytest.raises(InvalidInputError, match=r"^name: expected one of the loop's teachers \(mpc\), got 'pid'$"):
        loop.teach("pid")
    assert loop.teachers == ("mpc",)


def test_the_vector_envs_teacher_answers_its_law_when_the_env_runs_that_law():
    """The env's `teacher` option: a vector env whose law is `mpc`, asked what its `mpc` teacher commands before
    each zero-residual step, gets the torque that step applies (the oracle: the env's loop's record of it)."""
    import gymnasium as gym
    import mjtraj.envs  # noqa: F401

    env = gym.make_vec("UR5Track-v2", num_envs=2, vectorization_mode="vector_entry_point", controller="mpc",
                       teacher="mpc")
    env.reset(seed=5)
    loop = env.unwrapped.loop
    for _ in range(10):
        k = int(loop.periods[0])
        answer = loop.teach("mpc").dtau.copy()
        env.step(np.zeros((2, 3)))
        np.testing.assert_array_equal(answer, loop.rollout().dtau[:, k])
    env.close()


def test_mpcs_filter_alone_estimates_what_mpc_plans_from(scenario, model):
    """`mpc_filter` (mpc's Kalman filter without its QP) and `mpc` shadow one loop on mismatched plants with noise and
    a settle window, driven by commands neither gives (PID's plus a random torque); the oracle is `mpc` itself: every
    period the filter's estimate (the period counter, the torque disturbance and its covariance, corrected by the
    period's measurement) is mpc's, to rounding; their predictions differ by their own commands until the loop
    counts the one it applied. The disturbance is far from 0 (the plants' payloads), so the check has something to
    hold."""
    from mjtraj.core.mpc import disturbance_of
    from mjtraj.domain.families import perturbed_plant, plant_fields

    drawn = [draw_scenario("mismatch", 0, i, model, scenario.task.dt) for i in (0, 1)]
    refs = [held(scenario.planner("cubic").plan(d.task, model), 10, d.task.qg) for d in drawn]
    refs = [refs[0], refs[0]] if refs[0].steps != refs[1].steps else refs
    plant = perturbed_plant(model)
    loop = ClosedLoop(model, scenario.loop, nsim=2, plant=plant,
                      plant_fields=plant_fields(plant, [d.perturbation for d in drawn]),
                      teachers=("mpc", "mpc_filter"))
    noise = np.random.default_rng(2).standard_normal((refs[0].steps, 2, 2 * model.nv)) * 1e-3
    loop.start(refs, noise=noise, sensor=1e-3)
    rng = np.random.default_rng(3)
    largest = 0.0
    for _ in range(loop.steps):
        theirs, mine = loop.teach("mpc").state, loop.teach("mpc_filter").state
        corrected = np.r_[0, 1 + 2 * model.nv:theirs.shape[1]]  # the prediction is each one's own command's
        np.testing.assert_allclose(mine[:, corrected], theirs[:, corrected], rtol=1e-9, atol=1e-9)
        largest = max(largest, float(np.abs(disturbance_of(mine, model.nv)).max()))
        loop.step(residual=rng.normal(0.0, 2.0, (2, model.nv)))
    assert largest > 1.0  # N m


def test_the_env_observes_mpcs_filter_as_the_loop_runs_it():
    """observe_disturbance appends the filter's torque disturbance over the saturation, after observe_plant's place
    and before observe_task's (the oracle: the loop's own `mpc_filter` shadow, read beside the env); it needs a
    settle window."""
    import gymnasium as gym
    import mjtraj.envs  # noqa: F401

    from mjtraj.core.mpc import disturbance_of

    env = gym.make_vec("UR5Track-v2", num_envs=2, vectorization_mode="vector_entry_point", family="mismatch",
                       controller="pid", action_mode="torque", observe_disturbance=True)
    plain = gym.make_vec("UR5Track-v2", num_envs=2, vectorization_mode="vector_entry_point", family="mismatch",
                         controller="pid", action_mode="torque")
    obs, _ = env.reset(seed=4)
    other, _ = plain.reset(seed=4)
    assert obs.shape[1] == other.shape[1] + 3
    loop = env.unwrapped.loop
    for _ in range(20):
        d = disturbance_of(loop.teach("mpc_filter").state, 3) / 60.0
        np.testing.assert_array_equal(obs[:, -5:-2], d)
        np.testing.assert_array_equal(np.delete(obs, [-5, -4, -3], axis=1), other)
        action = np.full((2, 3), 0.05)
        obs, *_ = env.step(action)
        other, *_ = plain.step(action)
    assert np.abs(obs[:, -5:-2]).max() > 0
    env.close()
    plain.close()
    with pytest.raises(InvalidInputError, match=r"^observe_disturbance: .* expected settle > 0, got settle=0.0$"):
        gym.make("UR5Track-v1", observe_disturbance=True)


def test_a_predictive_teacher_answers_between_an_episodes_end_and_the_vector_envs_restart():
    """The vector env restarts an ended episode at the next step: asked in between (its answer unused), `mpc` reads
    its plan's last period instead of past its end, and the next episode's answers are its law's again."""
    import gymnasium as gym
    import mjtraj.envs  # noqa: F401

    env = gym.make_vec("UR5Track-v2", num_envs=1, vectorization_mode="vector_entry_point", controller="mpc",
                       teacher="mpc")
    env.reset(seed=6)
    loop = env.unwrapped.loop
    ended = False
    while not ended:
        _, _, terminated, truncated, _ = env.step(np.zeros((1, 3)))
        ended = bool(terminated[0] or truncated[0])
    assert loop.done.all()
    assert np.all(np.isfinite(loop.teach("mpc").dtau))
    env.step(np.zeros((1, 3)))  # the restart
    k = int(loop.periods[0])
    answer = loop.teach("mpc").dtau.copy()
    env.step(np.zeros((1, 3)))
    np.testing.assert_array_equal(answer, loop.rollout().dtau[:, k])
    env.close()


def test_mpc_filters_compiled_period_is_its_numpy_one(scenario, model):
    """The compiled filter (`mjtraj.core.filter_kernel`) against the NumPy path of the same law (`mpc`'s own code),
    from the same state every period of a loop on mismatched plants with noise, fresh periods included: the same
    estimate, prediction and covariance to rounding, the same command."""
    from mjtraj.domain.families import perturbed_plant, plant_fields

    drawn = [draw_scenario("mismatch", 0, i, model, scenario.task.dt) for i in (2, 2)]
    refs = [held(scenario.planner("cubic").plan(d.task, model), 10, d.task.qg) for d in drawn]
    plant = perturbed_plant(model)
    loop = ClosedLoop(model, scenario.loop, nsim=2, plant=plant,
                      plant_fields=plant_fields(plant, [d.perturbation for d in drawn]), teachers=("mpc_filter",))
    noise = np.random.default_rng(4).standard_normal((refs[0].steps, 2, 2 * model.nv)) * 1e-3
    loop.start(refs, noise=noise, sensor=1e-3)
    law = loop._teachers["mpc_filter"]  # noqa: SLF001 - the law itself, to call both paths
    rng = np.random.default_rng(5)
    zero, limit = np.zeros((2, model.nv)), np.tile(loop.limit, (2, 1))
    for _ in range(loop.steps):
        state = loop._state.teachers["mpc_filter"].law_state.copy()  # noqa: SLF001
        measured = np.concatenate(loop.measured(), axis=1)
        residual = rng.normal(0.0, 1.0, (2, model.nv))
        mine = law._compiled(state, measured, zero, limit, zero, residual)  # noqa: SLF001
        theirs = law._numpy(state, measured, zero, limit, zero, residual)  # noqa: SLF001
        np.testing.assert_allclose(mine.state, theirs.state, rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(mine.dtau, theirs.dtau)
        loop.step(residual=rng.normal(0.0, 2.0, (2, model.nv)))
