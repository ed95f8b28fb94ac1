"""The clairvoyant floor: a closed-form LQ oracle on a linear plant, finite differences for its derivatives, the
replay through the closed loop, the goal constraint, and no controller ever below it."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from mjtraj.core.floor import _Problem, clairvoyant_floor
from mjtraj.core.model import JointInfo
from mjtraj.core.planners.shooting import Shooting
from mjtraj.core.settle import held
from mjtraj.domain.families import draw_scenario, perturbed_plant
from mjtraj.domain.floor import STARTS, floor_of, replay
from mjtraj.domain.pipeline import GOAL_TOLERANCE, Job, execute_batch
from mjtraj.exceptions import InvalidInputError

ROTOR = """
<mujoco>
  <option timestep="0.02" integrator="RK4" gravity="0 0 0"/>
  <worldbody>
    <body>
      <joint name="spin" type="hinge" axis="0 0 1" damping="{damping}"/>
      <inertial pos="0 0 0" mass="1" diaginertia="{inertia} {inertia} {inertia}"/>
    </body>
  </worldbody>
  <actuator><motor joint="spin" ctrlrange="-1000 1000"/></actuator>
</mujoco>
"""


def rk4_map(inertia: float, damping: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """RK4's exact one-step map of the rotor theta'' = (u - b theta') / I under a torque held over the step."""
    A = np.array([[0.0, 1.0], [0.0, -damping / inertia]])
    B = np.array([[0.0], [1.0 / inertia]])
    hA = h * A
    eye = np.eye(2)
    Ad = eye + hA + hA @ hA / 2 + hA @ hA @ hA / 6 + hA @ hA @ hA @ hA / 24
    Bd = h * (eye + hA / 2 + hA @ hA / 6 + hA @ hA @ hA / 24) @ B
    return Ad, Bd


def predicted(Ad: np.ndarray, Bd: np.ndarray, x0: np.ndarray, N: int) -> tuple[np.ndarray, np.ndarray]:
    """The linear map's states x_k = Phi_k + Gamma_k U, k = 0..N, from x0 under torques U (N,): Phi (N+1, 2) and
    Gamma (N+1, 2, N), by the recursion x_{k+1} = Ad x_k + Bd u_k."""
    Gamma, Phi = np.zeros((N + 1, 2, N)), np.zeros((N + 1, 2))
    x = x0.copy()
    for k in range(N + 1):
        Phi[k] = x
        x = Ad @ x
        if k < N:
            Gamma[k + 1] = Ad @ Gamma[k]
            Gamma[k + 1, :, k] = Bd[:, 0]
    return Phi, Gamma


def test_on_a_linear_plant_without_active_bounds_the_floor_is_the_closed_form_lq_tracking_solution():
    inertia, damping, N, h = 0.3, 0.4, 40, 0.02
    plant = mujoco.MjModel.from_xml_string(ROTOR.format(inertia=inertia, damping=damping))
    t = np.arange(N + 1) * h
    q_ref = (0.8 * (3 * (t / t[-1]) ** 2 - 2 * (t / t[-1]) ** 3))[:, None]
    qd_ref = np.gradient(q_ref[:, 0], h)[:, None]
    q_diag, r_diag = np.array([4.0, 0.1]), np.array([0.05])
    found = clairvoyant_floor(plant, q_ref, qd_ref, q_diag, r_diag, np.array([1000.0]), goal_radius=10.0,
                              starts={"zero": np.zeros((N, 1))})
    # closed form: x_k = Ad^k x0 + sum_j Ad^(k-1-j) Bd u_j; J = |W (Phi x0 + Gamma U - r)|^2 + |sqrt(R) U|^2
    x_ref = np.concatenate([q_ref, qd_ref], axis=1)
    Phi, Gamma = predicted(*rk4_map(inertia, damping, h), x_ref[0], N)
    w = np.sqrt(q_diag)
    rows = (Gamma[1:N] * w[None, :, None]).reshape(-1, N)
    target = ((x_ref[1:N] - Phi[1:N]) * w).ravel()
    system = np.vstack([rows, np.sqrt(r_diag[0]) * np.eye(N)])
    U = np.linalg.lstsq(system, np.concatenate([target, np.zeros(N)]), rcond=None)[0]
    d = x_ref[0] - x_ref[0]
    best = float(np.sum((system @ U - np.concatenate([target, np.zeros(N)])) ** 2) + d @ (q_diag * d))
    assert found.converged
    np.testing.assert_allclose(found.torques[:, 0], U, rtol=1e-6, atol=1e-6 * np.abs(U).max())
    assert found.cost == pytest.approx(best, rel=1e-9)


def test_the_gauss_newton_gradient_and_the_goal_constraints_gradient_match_finite_differences(scenario, model):
    fs = draw_scenario("nominal", 1, 3, model, scenario.task.dt)
    ref = scenario.planner("cubic").plan(fs.task, model)
    q_diag, r_diag = scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit)
    x_ref = np.concatenate([ref.q, ref.qd], axis=1)
    problem = _Problem(Shooting(model, x_ref[0].copy(), x_ref[-1].copy(), np.zeros((6, 6)), np.zeros((3, 3)),
                                ref.steps, 1e-7), x_ref, np.sqrt(q_diag), np.sqrt(r_diag), 0.05)
    u = np.random.default_rng(0).uniform(-2.0, 2.0, ref.steps * 3)
    _, gradient, terminal = problem.linearised(u)
    direction = np.random.default_rng(1).standard_normal(u.size)
    step = 1e-5
    plus, minus = problem.rollout(u + step * direction), problem.rollout(u - step * direction)
    assert (plus[0] - minus[0]) / (2 * step) == pytest.approx(2.0 * gradient @ direction, rel=1e-6)
    assert (plus[1] - minus[1]) / (2 * step) == pytest.approx(terminal @ direction, rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("family", ["nominal", "aggressive"])
def test_the_floors_torques_replayed_through_the_closed_loop_give_its_cost_and_every_start_agrees(
        family, scenario, model):
    fs = draw_scenario(family, 1, 2, model, scenario.task.dt)
    ref = scenario.planner("cubic").plan(fs.task, model)
    job = Job(ref, scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit))
    floor = floor_of(model, scenario.loop, job, displacement=float(np.max(np.abs(fs.task.displacement))),
                     every_start=True)
    assert floor.cost == pytest.approx(floor.solver_cost, rel=1e-12)
    again = replay(model, scenario.loop, job, floor.torques)
    assert again.status == "ok" and again.metrics["cost"] == floor.cost
    assert floor.terminal_err <= floor.goal_radius
    assert set(floor.starts) == set(STARTS) - {"oracle"}  # the oracle runs on perturbed plants only
    spread = max(floor.starts.values()) - min(floor.starts.values())
    assert spread <= 1e-8 * floor.cost  # a smooth plant: every start reaches the same minimum
    assert np.abs(floor.torques).max() <= 60.0


@pytest.mark.parametrize("family, index", [("nominal", 0), ("nominal", 4), ("aggressive", 0), ("aggressive", 3),
                                           ("mismatch", 3)])
def test_no_controller_scores_below_the_floor(family, index, scenario, model):
    fs = draw_scenario(family, 1, index, model, scenario.task.dt)
    plant = perturbed_plant(model) if fs.perturbation is not None else None
    ref = scenario.planner("cubic").plan(fs.task, model)
    job = Job(ref, scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit), fs.perturbation)
    floor = floor_of(model, scenario.loop, job, plant=plant, starts=("pid",))
    for law in ("pid", "computed_torque", "adaptive_computed_torque"):
        _, outcomes = execute_batch(model, dataclasses.replace(scenario.loop, controller=law), [job], plant=plant)
        assert outcomes[0].metrics["cost"] >= floor.cost, law


def test_the_goal_constraint_binds_where_the_unconstrained_optimum_stops_short(scenario, model):
    fs = draw_scenario("aggressive", 1, 3, model, scenario.task.dt)
    ref = scenario.planner("cubic").plan(fs.task, model)
    q_diag, r_diag = scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit)
    limit = JointInfo.of(model).torque_limit
    start = {"zero": np.zeros((ref.steps, 3))}
    loose = clairvoyant_floor(model, ref.q, ref.qd, q_diag, r_diag, limit, goal_radius=10.0, starts=start)
    radius = 0.25 * loose.terminal_err
    tight = clairvoyant_floor(model, ref.q, ref.qd, q_diag, r_diag, limit, goal_radius=radius, starts=start)
    assert loose.terminal_err > 0.05
    assert tight.terminal_err <= radius
    assert tight.cost > loose.cost


def test_bad_configuration_and_starts_are_refused_by_name(scenario, model):
    ref = scenario.planner("cubic").plan(scenario.task, model)
    job = Job(ref, scenario.scoring.weights(scenario.task, JointInfo.of(model).torque_limit))
    with pytest.raises(InvalidInputError, match=r"^config: the floor models native gravity compensation at one "
                                                r"integrator step per period; got gravity_comp='zoh', substeps=1$"):
        floor_of(model, dataclasses.replace(scenario.loop, gravity_comp="zoh"), job)
    with pytest.raises(InvalidInputError, match=r"^starts: expected at least one control law, got none$"):
        floor_of(model, scenario.loop, job, starts=())
    assert GOAL_TOLERANCE == 0.2


def _mismatch_problem(scenario, model, index: int) -> tuple[_Problem, np.ndarray]:
    """The floor's problem on mismatch scenario `index`'s true plant (dry friction, per-link gravity compensation),
    and the torques PID applies there."""
    from mjtraj.domain.floor import true_plant

    fs = draw_scenario("mismatch", 1, index, model, scenario.task.dt)
    plant = perturbed_plant(model)
    ref = scenario.planner("cubic").plan(fs.task, model)
    job = Job(ref, scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit), fs.perturbation)
    rollout, _ = execute_batch(model, scenario.loop, [job], plant=plant)
    truth = true_plant(plant, fs.perturbation)
    x_ref = np.concatenate([ref.q, ref.qd], axis=1)
    shooting = Shooting(truth, x_ref[0].copy(), x_ref[-1].copy(), np.zeros((6, 6)), np.zeros((3, 3)), ref.steps,
                        1e-7, partial=True)
    return _Problem(shooting, x_ref, np.sqrt(job.weights[0]), np.sqrt(job.weights[1]), 0.05), rollout.dtau[0]


@pytest.mark.slow
def test_on_a_plant_with_dry_friction_and_per_link_gravity_compensation_the_step_jacobians_match_differences(
        scenario, model):
    problem, torques = _mismatch_problem(scenario, model, 3)
    shooting = problem.shooting
    X = shooting.rollout(torques)
    A, B = shooting.jacobians(X, torques)
    counts = shooting.jacobian_counts
    assert counts["analytic"] >= 0.5 * torques.shape[0] and counts["differenced"] >= 1  # both kinds of sample
    A_fd, B_fd = shooting.differenced(X, torques)
    np.testing.assert_allclose(A, A_fd, atol=1e-6)  # forward differences' own error
    np.testing.assert_allclose(B, B_fd, atol=1e-6)


def test_the_gravity_tree_gives_mujocos_gravity_torque_and_its_derivative_matches_differences(scenario, model):
    from mjtraj.core.planners.rigid_body import RigidBody

    problem, _ = _mismatch_problem(scenario, model, 3)
    plant = problem.shooting.model
    assert np.ptp(plant.body_gravcomp[1:]) > 0.0 and np.all(plant.dof_frictionloss > 0.0)
    assert RigidBody.of(plant) is None  # the planners' rule does not hold it
    tree = RigidBody.of(plant, plant_forces=True)
    q = np.random.default_rng(2).uniform(-2.0, 2.0, (5, 3))
    held, d_held = tree.gravity.gravity(q - tree.qpos0)
    data = mujoco.MjData(plant)
    for k in range(5):  # at rest: the bias is gravity, less what the passive gravity compensation carries
        data.qpos[:], data.qvel[:] = q[k], 0.0
        mujoco.mj_forward(plant, data)
        np.testing.assert_allclose(held[k], data.qfrc_bias - data.qfrc_gravcomp, atol=1e-12)
    step = 1e-6
    for j in range(3):
        e = np.eye(3)[j] * step
        fd = (tree.gravity.gravity(q - tree.qpos0 + e)[0] - tree.gravity.gravity(q - tree.qpos0 - e)[0]) / (2 * step)
        np.testing.assert_allclose(d_held[:, :, j], fd, atol=1e-8)


def test_the_structured_gauss_newton_hessian_and_gradient_equal_the_sensitivities_product(scenario, model):
    problem, torques = _mismatch_problem(scenario, model, 1)
    u = torques.ravel()
    hessian, gradient, _ = problem.linearised(u)
    U, X, _, S = problem.shooting.evaluate(u)
    N, n = U.shape
    flat = (S[1:N] * problem.q_root[None, :, None]).reshape(-1, N * n)
    residual = ((X - problem.x_ref)[1:N] * problem.q_root).ravel()
    dense = flat.T @ flat + np.diag(np.tile(problem.r_root**2, N))
    np.testing.assert_allclose(hessian, dense, rtol=1e-12, atol=1e-12 * np.abs(dense).max())
    np.testing.assert_allclose(gradient, flat.T @ residual + (U * problem.r_root**2).ravel(), rtol=1e-12,
                               atol=1e-12 * np.abs(gradient).max())


@pytest.mark.slow
def test_by_default_only_the_best_ranked_start_is_solved_and_every_start_finds_no_higher_floor(scenario, model):
    fs = draw_scenario("mismatch", 1, 2, model, scenario.task.dt)
    plant = perturbed_plant(model)
    ref = scenario.planner("cubic").plan(fs.task, model)
    job = Job(ref, scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit), fs.perturbation)
    one = floor_of(model, scenario.loop, job, plant=plant)
    every = floor_of(model, scenario.loop, job, plant=plant, every_start=True)
    solved = [name for name, cost in one.starts.items() if not np.isnan(cost)]
    assert solved == [one.start]
    assert every.starts[one.start] == one.starts[one.start]  # the same solve, bit for bit
    assert every.cost <= one.cost
    assert all(not np.isnan(cost) for cost in every.starts.values())


@pytest.mark.slow
def test_the_env_reports_an_episodes_floor_where_asked_and_it_is_that_episodes_floor(scenario, model):
    import gymnasium as gym

    import mjtraj  # noqa: F401 - registers the envs

    env = gym.make("UR5Track-v1", floor=True, family="mismatch")
    env.reset(seed=5)
    core = env.unwrapped._core
    job = Job(core.references[0], (core._q_diag[0].copy(), core._r_diag[0].copy()), core.plants[0])
    move = float(np.max(np.abs(core.tasks[0].displacement)))
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(3))
        done = terminated or truncated
    alone = floor_of(model, core.settings.loop, job, plant=core.plant, displacement=move)
    metrics = info["metrics"]
    assert metrics["floor"] == pytest.approx(alone.cost, rel=1e-9)
    assert metrics["cost_over_floor"] == metrics["cost"] / metrics["floor"] and metrics["cost"] >= metrics["floor"]
    with pytest.raises(InvalidInputError, match=r"^floor: the floor models native gravity compensation"):
        gym.make("UR5Track-v1", floor=True, gravity_comp="zoh")


@pytest.mark.slow
def test_on_a_mismatched_plant_no_law_of_the_table_scores_below_the_floor_the_oracle_included(scenario, model):
    """Mismatch scenario 6 of seed 1, where the adaptive law told the true plant had scored 1.5 % below the floor
    of the four classical starts: every law of the benchmark's table starts a solve, so none scores below it
    (the oracle's execution replayed independently through the pipeline)."""
    from mjtraj.domain.oracle import TrueParameters

    fs = draw_scenario("mismatch", 1, 6, model, scenario.task.dt)
    plant = perturbed_plant(model)
    ref = scenario.planner("cubic").plan(fs.task, model)
    job = Job(ref, scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit), fs.perturbation)
    floor = floor_of(model, scenario.loop, job, plant=plant, displacement=float(np.max(np.abs(fs.task.displacement))))
    assert set(floor.controllers) == set(STARTS)
    assert all(floor.cost <= cost for cost in floor.controllers.values())
    _, (oracle,) = execute_batch(model, dataclasses.replace(scenario.loop, controller="adaptive_computed_torque"),
                                 [job], plant=plant, actor=TrueParameters())
    assert oracle.metrics["cost"] == floor.controllers["oracle"] >= floor.cost


def test_on_a_linear_plant_the_at_rest_floor_is_the_convex_qps_exact_solution():
    """Protocol v2's floor (`AtRest`: 4 n linear rows on the last state) on a rotor, where the problem is a convex
    QP in the torques with two two-sided rows (the last state's position and speed): its exact solution, by
    enumerating which bound of each row is active and solving the KKT system of each (the least feasible cost of
    the nine is the optimum of a convex problem), is the floor; the rule binds (the floor without it ends outside).
    (OSQP was the oracle before: its ADMM, at the oldest version pyproject allows, stopped 3e-6 above the optimum.)"""
    import itertools

    from mjtraj.core.floor import DEFAULT_SETTINGS, AtRest

    inertia, damping, N, S, h = 0.3, 0.4, 30, 10, 0.02
    plant = mujoco.MjModel.from_xml_string(ROTOR.format(inertia=inertia, damping=damping))
    t = np.arange(N + 1) * h
    motion = 0.8 * (3 * (t / t[-1]) ** 2 - 2 * (t / t[-1]) ** 3)
    q_ref = np.concatenate([motion, np.full(S, motion[-1])])[:, None]
    qd_ref = np.concatenate([np.gradient(motion, h), np.zeros(S)])[:, None]
    q_diag, r_diag = np.array([0.5, 0.01]), np.array([0.2])
    rule = AtRest(np.array([0.8]), 0.004, 0.02)
    T = N + S
    loose = clairvoyant_floor(plant, q_ref, qd_ref, q_diag, r_diag, np.array([1000.0]), goal_radius=10.0,
                              starts={"zero": np.zeros((T, 1))})
    found = clairvoyant_floor(plant, q_ref, qd_ref, q_diag, r_diag, np.array([1000.0]), at_rest=rule,
                              starts={"zero": np.zeros((T, 1))})
    x_ref = np.concatenate([q_ref, qd_ref], axis=1)
    Phi, Gamma = predicted(*rk4_map(inertia, damping, h), x_ref[0], T)
    end = lambda U: Phi[T] + Gamma[T] @ U  # noqa: E731
    assert abs(end(loose.torques[:, 0])[0] - 0.8) > rule.band or abs(end(loose.torques[:, 0])[1]) > rule.speed
    w = np.sqrt(q_diag)
    rows = (Gamma[1:T] * w[None, :, None]).reshape(-1, T)
    target = ((x_ref[1:T] - Phi[1:T]) * w).ravel()
    system = np.vstack([rows, np.sqrt(r_diag[0]) * np.eye(T)])
    goal = np.concatenate([target, np.zeros(T)])
    aim = DEFAULT_SETTINGS.goal_margin * np.array([rule.band, rule.speed])
    centre = np.array([0.8, 0.0]) - Phi[T]
    C = Gamma[T]
    H, g = system.T @ system, system.T @ goal

    def exact(low, high):
        """The convex QP's optimum with the last state's rows in [low, high]: the least feasible cost of the nine
        active sets (each a KKT solve)."""
        candidates = []
        for sides in itertools.product((None, "low", "high"), repeat=2):
            active = [i for i in range(2) if sides[i] is not None]
            values = np.array([low[i] if sides[i] == "low" else high[i] for i in active])
            kkt = np.block([[H, C[active].T], [C[active], np.zeros((len(active), len(active)))]])
            U = np.linalg.solve(kkt, np.concatenate([g, values]))[:T]
            if np.all(C @ U >= low - 1e-12) and np.all(C @ U <= high + 1e-12):
                candidates.append((float(np.sum((system @ U - goal) ** 2)), U))
        return min(candidates, key=lambda c: c[0])

    best, U = exact(centre - aim, centre + aim)
    assert np.abs(U).max() < 1000.0  # the torque box is inactive: the nine solves are the whole problem
    # The solve stops where the aimed rows hold within `reached` of their bound (DAQP 0.5, the declared floor, stops
    # a few 1e-6 outside): its end lies inside the rule itself, and its cost is sandwiched between the exact optimum
    # over the box it actually reached (a lower bound: that box holds it) and the exact optimum over the aimed box
    # plus the convergence test's relative 1e-6.
    end_rows = C @ found.torques[:, 0] - centre
    assert abs(end(found.torques[:, 0])[0] - 0.8) <= rule.band and abs(end(found.torques[:, 0])[1]) <= rule.speed
    assert np.all(np.abs(end_rows) <= aim * (1 + DEFAULT_SETTINGS.reached))
    widened = np.maximum(aim, np.abs(end_rows))
    lower, _ = exact(centre - widened, centre + widened)
    assert lower * (1 - 1e-12) <= found.cost <= best * (1 + 1e-6)
    np.testing.assert_allclose(found.torques[:, 0], U, rtol=1e-5, atol=1e-5 * np.abs(U).max())
    assert found.cost > loose.cost


def test_the_at_rest_rows_gradient_matches_finite_differences(scenario, model):
    from mjtraj.core.floor import AtRest

    fs = draw_scenario("aggressive", 1, 3, model, scenario.task.dt)
    ref = held(scenario.planner("cubic").plan(fs.task, model), 25, fs.task.qg)
    q_diag, r_diag = scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit)
    x_ref = np.concatenate([ref.q, ref.qd], axis=1)
    problem = _Problem(Shooting(model, x_ref[0].copy(), x_ref[-1].copy(), np.zeros((6, 6)), np.zeros((3, 3)),
                                ref.steps, 1e-7), x_ref, np.sqrt(q_diag), np.sqrt(r_diag), np.inf,
                       AtRest(fs.task.qg, 0.01, 0.05))
    u = np.random.default_rng(0).uniform(-2.0, 2.0, ref.steps * 3)
    _, _, terminal = problem.linearised(u)
    assert terminal.shape == (12, ref.steps * 3)
    direction = np.random.default_rng(1).standard_normal(u.size)
    step = 1e-5
    plus, minus = problem.rollout(u + step * direction), problem.rollout(u - step * direction)
    np.testing.assert_allclose((plus[1] - minus[1]) / (2 * step), terminal @ direction, rtol=1e-5,
                               atol=1e-7 * np.abs(terminal @ direction).max())


@pytest.mark.slow
@pytest.mark.parametrize("family, index", [("nominal", 0), ("aggressive", 3), ("mismatch", 3)])
def test_protocol_v2s_floor_replays_at_rest_and_no_law_at_rest_scores_below_it(family, index, scenario, model):
    """The v2 floor's torques replayed through the closed loop (settle window and all) end at rest at the goal with
    the solver's J_settle; every starting law that came to rest scores at or above it; on a mismatch plant every start
    is solved and the floor without a law's own start is never below the floor."""
    from mjtraj.core.settle import SETTLE_SPEED, Settle

    fs = draw_scenario(family, 1, index, model, scenario.task.dt)
    plant = perturbed_plant(model) if fs.perturbation is not None else None
    motion = scenario.planner("cubic").plan(fs.task, model)
    job = Job(held(motion, 25, fs.task.qg), scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit),
              fs.perturbation, settle=Settle.of(fs.task, motion.steps, 25))
    floor = floor_of(model, scenario.loop, job, plant=plant)
    again = replay(model, scenario.loop, job, floor.torques, plant=plant)
    assert again.status == "ok" and again.metrics["cost"] == floor.cost
    assert again.metrics["end_err"] <= job.settle.band and again.metrics["end_speed"] <= SETTLE_SPEED
    assert floor.cost == pytest.approx(floor.solver_cost, rel=1e-9)
    at_rest = {law: cost for law, cost in floor.controllers.items() if np.isfinite(cost)}
    assert at_rest and all(cost >= floor.cost for cost in at_rest.values()), at_rest
    if fs.perturbation is not None:
        assert not any(np.isnan(list(floor.starts.values())))  # every start solved
        # the starts hold the solver's costs (the floor's own is its replay's, equal to round-off)
        assert all(floor.without(law) >= floor.solver_cost for law in floor.controllers)


def test_the_solvers_tunables_are_settings_in_the_open(scenario, model):
    """`FloorSettings` reaches the solve (a loose stall test stops it earlier, no lower than the default's floor; a
    cap of one iteration leaves it short of the goal) and refuses a bad value by name; the defaults are the published
    floors' (the golden floors pin them)."""
    from mjtraj.core.floor import DEFAULT_SETTINGS, FloorSettings
    from mjtraj.exceptions import SolverError

    fs = draw_scenario("aggressive", 1, 3, model, scenario.task.dt)
    ref = scenario.planner("cubic").plan(fs.task, model)
    job = Job(ref, scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit))
    move = float(np.max(np.abs(fs.task.displacement)))
    full = floor_of(model, scenario.loop, job, displacement=move, starts=("pid",))
    loose = floor_of(model, scenario.loop, job, displacement=move, starts=("pid",), settings=FloorSettings(stall=0.5))
    assert loose.iterations < full.iterations and loose.cost > full.cost
    with pytest.raises(SolverError, match=r"no start reached the goal"):
        floor_of(model, scenario.loop, job, displacement=move, starts=("pid",), settings=FloorSettings(max_iter=1))
    assert DEFAULT_SETTINGS == FloorSettings()
    with pytest.raises(InvalidInputError, match=r"^settings.goal_margin: expected a number > 0 and <= 1, got 1.5$"):
        FloorSettings(goal_margin=1.5)
    with pytest.raises(InvalidInputError, match=r"^settings.stall: expected a number > 0, got 0.0$"):
        FloorSettings(stall=0.0)
