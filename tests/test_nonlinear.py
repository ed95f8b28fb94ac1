"""The nonlinear planners: realisable on the model, every constraint held, first-order optimal, the linear planner in
the small-move limit, the effort bound below every other plan, and one-line errors."""

from __future__ import annotations

import copy
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from oracles import short_task

from mjtraj.core.model import JointInfo
from mjtraj.core.planners import default_names, make
from mjtraj.core.planners.nonlinear import _Metric
from mjtraj.core.planners.shooting import PathLimits, Shooting
from mjtraj.core.task import Task
from mjtraj.exceptions import InfeasibleError, InvalidInputError, SolverError


@pytest.fixture(scope="module")
def effort(model):
    """The effort bound of a 0.3 rad move in 0.5 s (no path constraint near its limit)."""
    task = short_task(model, 0.3)
    return task, make("nonlinear_min_effort").plan(task, model)


@pytest.fixture(scope="module")
def plans(model):
    """Both planners on a 1.5 rad move in 0.6 s, which the speed limit constrains."""
    task = short_task(model, 1.5, duration=0.6)
    return task, make("nonlinear_min_effort").plan(task, model), make("nonlinear_optimal").plan(task, model)


def replay(model, task, U):
    """States (N+1, 2n) of the model under U from rest at q0 (an independent rollout with mj_step)."""
    data = mujoco.MjData(model)
    data.qpos[:] = task.q0
    X = [np.concatenate([data.qpos, data.qvel])]
    for u in U:
        data.ctrl[:] = u
        mujoco.mj_step(model, data)
        X.append(np.concatenate([data.qpos, data.qvel]))
    return np.array(X)


def test_a_plan_is_its_torques_rollout_and_holds_every_constraint(model, effort):
    check_plan(model, *effort)


@pytest.mark.slow
@pytest.mark.parametrize("which", [1, 2])
def test_plans_along_the_speed_limit_hold_every_constraint(model, plans, which):
    check_plan(model, plans[0], plans[which])


def check_plan(model, task, ref):
    """The plan is the rollout of its torques on the model and holds the goal, ranges, speed and torque limits."""
    X = replay(model, task, ref.u_plan)
    n = task.n
    np.testing.assert_allclose(X[:, :n], ref.q, rtol=0, atol=1e-8)  # the last sample is set to the goal
    np.testing.assert_allclose(X[:, n:], ref.qd, rtol=0, atol=1e-8)
    np.testing.assert_array_equal(X[:-1, :n], ref.q[:-1])  # exactly the rollout before it
    joints = JointInfo.of(model)
    assert np.all(np.abs(ref.qd) <= np.pi * (1 + 1e-8))
    assert np.all((ref.q >= joints.lower) & (ref.q <= joints.upper))
    assert np.all(np.abs(ref.u_plan) <= joints.torque_limit)
    assert ref.info["terminal_residual"] < 1e-8
    assert not set(default_names()) & {"nonlinear_optimal", "nonlinear_min_effort"}  # on request only


@pytest.mark.slow
def test_the_speed_limit_binds_and_costs_effort(model, plans):
    """The 1.5 rad move in 0.6 s wants more than pi rad/s; the plan rides the limit instead."""
    task, effort, _ = plans
    assert np.abs(effort.qd).max() == pytest.approx(np.pi, rel=1e-8)
    free = make("nonlinear_min_effort", speed_limit=100.0).plan(task, model)
    assert np.abs(free.qd).max() > 1.05 * np.pi
    assert free.info["objective"] < effort.info["objective"]


@pytest.mark.slow
def test_the_effort_bound_is_below_the_weighted_plans_effort(plans):
    """Oracle: Q = 0 minimises effort alone over the same feasible set, so no weighted plan spends less."""
    _, effort, weighted = plans
    assert np.sum(effort.u_plan**2) <= np.sum(weighted.u_plan**2) * (1 + 1e-9)


def test_first_order_optimality_of_the_effort_bound(model, effort):
    """With no path constraint near its limit, the KKT condition is grad f = S_N^T lambda: the gradient lies in the
    row space of the terminal constraint's Jacobian (least-squares residual relative to the gradient)."""
    task, ref = effort
    assert ref.info["path_rows"] == 0
    n = task.n
    R = np.diag(1.0 / JointInfo.of(model).torque_limit ** 2)
    problem = Shooting(model, np.concatenate([task.q0, np.zeros(n)]), np.concatenate([task.qg, np.zeros(n)]),
                        np.zeros((2 * n, 2 * n)), R, task.steps, 1e-6)
    u = ref.u_plan.ravel()
    gradient = problem.gradient(u)
    S_N = problem.evaluate(u)[3][-1]
    multipliers, *_ = np.linalg.lstsq(S_N.T, gradient, rcond=None)
    assert np.linalg.norm(gradient - S_N.T @ multipliers) < 1e-4 * np.linalg.norm(gradient)


@pytest.mark.parametrize("name", [pytest.param("nonlinear_optimal", marks=pytest.mark.slow), "nonlinear_min_effort"])
def test_a_tiny_move_is_the_linear_planners_plan(model, name):
    """The linearisation is exact in the limit: at 1 mrad the plans agree to 0.2 %, at 0.3 rad they do not."""
    linear = make("optimal", alpha=0.0 if name == "nonlinear_min_effort" else 1.0)
    gaps = []
    for move in (1e-3, 0.3):
        task = short_task(model, move)
        mine, theirs = make(name).plan(task, model).u_plan, linear.plan(task, model).u_plan
        gaps.append(np.abs(mine - theirs).max() / np.abs(theirs).max())
    assert gaps[0] < 2e-3
    assert gaps[1] > 10 * gaps[0]


def test_an_unreachable_goal_names_the_binding_constraint(model):
    task = short_task(model, 1.0)
    with pytest.raises(InfeasibleError, match=r"^nonlinear_min_effort: no start to optimise from: optimal: x_N = 0 "
                                              r"cannot be reached within the torque bounds .* the binding bound is "
                                              r"joint 'shoulder_pan_joint'"):
        make("nonlinear_min_effort", torque_bound=0.5).plan(task, model)


@pytest.mark.parametrize(("options", "message"), [
    ({"alpha": 1.0}, r"^alpha, state_weight: nonlinear_min_effort has no state weight \(Q = 0\); use "
                     r"nonlinear_optimal for a weighted plan$"),
    ({"speed_limit": 0.0}, r"^speed_limit: expected a positive number, got 0.0$"),
    ({"max_iter": 0}, r"^max_iter: expected a whole number >= 1, got 0$"),
    ({"curvature_scale": -1.0}, r"^curvature_scale: expected a positive number, got -1.0$"),
    ({"torque_bound": -1.0}, r"^torque_bound: expected positive values, got -1.0$"),
    ({"solver": "newton"}, r"^solver: unknown value 'newton'; valid: auto, sqp, slsqp$"),
    ({"sqp_max_iter": 0}, r"^sqp_max_iter: expected a whole number >= 1, got 0$"),
    ({"keep": "best"}, r"^keep: unknown value 'best'; valid: first, lowest$"),
    ({"settings": {"retry_factor": 3.0}},
     r"^settings: expected a NonlinearSettings \(mjtraj.core.planners.nonlinear\), got \{'retry_factor': 3.0\}$"),
])
def test_bad_options_are_one_line_errors(options, message):
    with pytest.raises(InvalidInputError, match=message):
        make("nonlinear_min_effort", **options)


@pytest.mark.parametrize(("settings", "message"), [
    ({"retry_factor": 0.0}, r"^settings.retry_factor: expected a positive number, got 0.0$"),
    ({"max_rounds": 0}, r"^settings.max_rounds: expected a whole number >= 1, got 0$"),
    ({"slsqp_max_torques": 1.5}, r"^settings.slsqp_max_torques: expected a whole number >= 0, got 1.5$"),
    ({"range_margin": -1e-4}, r"^settings.range_margin: expected a number in \[0, inf\), got -0.0001$"),
    ({"sqp": {"stall": 1e-8}}, r"^settings.sqp: expected an SqpSettings \(mjtraj.core.planners.sqp\), got "
                               r"\{'stall': 1e-08\}$"),
])
def test_bad_settings_are_one_line_errors(settings, message):
    from mjtraj.core.planners.nonlinear import NonlinearSettings

    with pytest.raises(InvalidInputError, match=message):
        NonlinearSettings(**settings)


@pytest.mark.parametrize(("settings", "message"), [
    ({"curvature_scale": -1.0}, r"^settings.sqp.curvature_scale: expected a positive number, got -1.0$"),
    ({"shrink": 0.5}, r"^settings.sqp.shrink: expected a number in \[1, inf\), got 0.5$"),
    ({"armijo": 1.0}, r"^settings.sqp.armijo: expected a number in \(0, 1\), got 1.0$"),
    ({"min_step": 2.0}, r"^settings.sqp.min_step: expected a number in \(0, 1\], got 2.0$"),
    ({"stall": 0.0}, r"^settings.sqp.stall: expected a positive number, got 0.0$"),
    ({"second_order_after": -1}, r"^settings.sqp.second_order_after: expected a whole number >= 0, got -1$"),
    ({"slow": (8, 3)}, r"^settings.sqp.slow: expected \(after, run, contraction\), got \(8, 3\)$"),
    ({"slow": (8, 0, 0.7)}, r"^settings.sqp.slow\[1\]: expected a whole number >= 1, got 0$"),
    ({"augment": ()}, r"^settings.sqp.augment: expected at least one number in \(0, inf\), got \(\)$"),
    ({"damping": (0.1, 1.0)}, r"^settings.sqp.damping\[1\]: expected a number in \(1, inf\), got 1.0$"),
    ({"newton_reuse": 1.5}, r"^settings.sqp.newton_reuse: expected a whole number >= 0, got 1.5$"),
    ({"join_distance": 0.0}, r"^settings.sqp.join_distance: expected a positive number, got 0.0$"),
    ({"relaxed": (0.5, 1.0)}, r"^settings.sqp.relaxed\[1\]: expected a number in \(0, 1\), got 1.0$"),
    ({"daqp_tol": float("nan")}, r"^settings.sqp.daqp_tol: expected a positive number, got nan$"),
])
def test_bad_sqp_settings_are_one_line_errors(settings, message):
    from mjtraj.core.planners.sqp import SqpSettings

    with pytest.raises(InvalidInputError, match=message):
        SqpSettings(**settings)


def test_the_settings_reach_the_solvers_and_a_plan_records_those_changed(model):
    """`settings=` of `make` reaches the SQP: a looser stall test (`SqpSettings.stall` 1e-3) stops the same solve
    sooner, at the same minimum (oracle: the default solve, to 1e-9), and the plan's info names the change; a plan
    with the defaults records none. A wider `range_margin` narrows the problem's joint ranges by it. The defaults are
    the modules' own, and a list given for a tuple is kept as a tuple (the settings stay hashable and comparable)."""
    from mjtraj.core.planners import nonlinear, sqp
    from mjtraj.core.planners.nonlinear import NonlinearSettings
    from mjtraj.core.planners.sqp import SqpSettings

    assert make("nonlinear_optimal").settings == NonlinearSettings() == nonlinear.DEFAULT_SETTINGS
    assert NonlinearSettings().sqp == SqpSettings() == sqp.DEFAULT_SETTINGS
    assert NonlinearSettings().changes() == [] and SqpSettings(relaxed=[0.5, 0.25]) == SqpSettings()
    task = short_task(model, 0.3)
    default = make("nonlinear_optimal").plan(task, model)
    loose = make("nonlinear_optimal", settings=NonlinearSettings(sqp=SqpSettings(stall=1e-3))).plan(task, model)
    assert "settings" not in default.info and loose.info["settings"] == "sqp.stall=0.001"
    assert loose.info["iterations"] < default.info["iterations"]
    assert not np.array_equal(loose.u_plan, default.u_plan)
    assert loose.info["objective"] == pytest.approx(default.info["objective"], rel=1e-9)
    two = NonlinearSettings(sqp=SqpSettings(slow=(6, 3, 0.6)), range_margin=0.05)
    assert two.changes() == ["sqp.slow=(6, 3, 0.6)", "range_margin=0.05"]
    _, limits, _ = make("nonlinear_optimal", settings=two).problem(task, model)
    joints = JointInfo.of(model)
    np.testing.assert_array_equal(limits.q_high, np.maximum(joints.upper - 0.05, np.maximum(task.q0, task.qg)))
    np.testing.assert_array_equal(limits.q_low, np.minimum(joints.lower + 0.05, np.minimum(task.q0, task.qg)))


def test_the_change_of_variables_is_exact_and_starts_at_the_gauss_newton_hessian(model):
    """v = L^T u: round trip, derivative rows carried to v (a linear function's values agree), and L L^T equal to
    the scale times R + sum S^T Q S computed by plain loops."""
    task = short_task(model, 0.3)
    rng = np.random.default_rng(3)
    n, N = task.n, task.steps
    Q, R = np.diag(rng.uniform(0.5, 2.0, 2 * n)), np.diag(rng.uniform(0.5, 2.0, n))
    problem = Shooting(model, np.concatenate([task.q0, np.zeros(n)]), np.concatenate([task.qg, np.zeros(n)]), Q, R,
                        N, 1e-7)
    u = rng.normal(0.0, 1.0, N * n)
    metric = _Metric.at(problem, u, 7.0)
    S = problem.evaluate(u)[3]
    expected = np.kron(np.eye(N), R) + sum(S[k].T @ Q @ S[k] for k in range(1, N + 1))
    np.testing.assert_allclose(metric.L @ metric.L.T, 7.0 * expected, rtol=1e-10)
    np.testing.assert_allclose(metric.to_u(metric.to_v(u)), u, rtol=1e-10)
    g, w = rng.normal(size=(2, N * n))
    assert metric.pull(g[None])[0] @ metric.to_v(w) == pytest.approx(g @ w, rel=1e-10)


def test_a_failed_solve_is_retried_with_shorter_first_steps(model, monkeypatch):
    """The first optimisation fails (as SLSQP does when an iterate's rollout diverges): the plan comes from the retry
    at `NonlinearSettings.retry_factor` times the curvature scale (5 here, 30 by default) and says so; when it and
    the try from the tracked start fail too, the error carries the three reasons."""
    from mjtraj.core.planners import nonlinear

    task = short_task(model, 0.3)
    scales = []
    solve = nonlinear.NonlinearOptimal._solve

    def first_fails(self, problem, limits, rows, u, f_scale, t_scale, scale):
        scales.append(scale)
        if scale == self.curvature_scale:
            raise SolverError("the rollout of an iterate diverged (MuJoCo reset the simulation)")
        return solve(self, problem, limits, rows, u, f_scale, t_scale, scale)

    monkeypatch.setattr(nonlinear.NonlinearOptimal, "_solve", first_fails)
    settings = nonlinear.NonlinearSettings(retry_factor=5.0)
    plan = make("nonlinear_min_effort", solver="slsqp", curvature_scale=2.0, settings=settings).plan(task, model)
    assert plan.info["retried"] == 1 and scales[0] == 2.0 and set(scales[1:]) == {10.0}
    check_plan(model, task, plan)

    def both_fail(self, problem, limits, rows, u, f_scale, t_scale, scale):
        raise SolverError(f"failed at {scale:g}")

    monkeypatch.setattr(nonlinear.NonlinearOptimal, "_solve", both_fail)
    with pytest.raises(SolverError, match=r"^nonlinear_min_effort: failed at 60 \(also with curvature_scale 2: "
                                          r"nonlinear_min_effort: failed at 2\) \(from the tracked start: "
                                          r"nonlinear_min_effort: failed at 2\)$"):
        make("nonlinear_min_effort", solver="slsqp", curvature_scale=2.0).plan(task, model)


def test_lowest_keeps_the_least_of_the_starts_plans_and_first_the_first(model, monkeypatch):
    """keep='lowest' (nonlinear_min_effort's default) runs the SQP from both starts, in START_NAMES order, and keeps
    the plan of least objective; 'first' stops at the first start from which it converges. Oracle: each run's
    result, recorded by a wrapper, and its objective recomputed."""
    from mjtraj.core.planners import nonlinear

    task = short_task(model, 0.8)
    runs = []
    sqp = nonlinear.gauss_newton_sqp

    def recorded(problem, limits, u, **options):
        result = sqp(problem, limits, u, **options)
        runs.append((problem.objective(result.u), result))
        return result

    monkeypatch.setattr(nonlinear, "gauss_newton_sqp", recorded)
    plan = make("nonlinear_min_effort").plan(task, model)
    assert len(runs) == 2 and all(result.converged for _, result in runs)
    best = min(range(2), key=lambda i: runs[i][0])
    assert (plan.info["solver"], plan.info["sqp_converged"]) == ("sqp", 2)
    assert plan.info["start"] == nonlinear.START_NAMES[best]
    assert plan.info["objective"] == runs[best][0] and plan.info["iterations"] == runs[best][1].iterations
    np.testing.assert_array_equal(plan.u_plan.ravel(), runs[best][1].u)
    runs.clear()
    first = make("nonlinear_min_effort", keep="first").plan(task, model)
    assert len(runs) == 1 and (first.info["start"], first.info["sqp_converged"]) == ("linear", 1)
    np.testing.assert_array_equal(first.u_plan.ravel(), runs[0][1].u)
    check_plan(model, task, plan)


def test_a_start_heading_for_the_first_starts_plan_joins_it(model, monkeypatch):
    """keep='lowest' hands the first start's plan to the second start's solve, which stops once an iterate comes
    within `SqpSettings.join_distance` of it. Oracle: the same solve without `join`, run to its own convergence
    test, ends at that plan (the same objective to 1e-9, the torques within 1e-3 of the plan's norm: the convergence
    test is on the objective and the constraints, and leaves the torques a few 1e-6 N m apart along the minimum's
    flat directions), in more iterations."""
    from mjtraj.core.planners import nonlinear

    task = short_task(model, 0.8)
    runs = []
    sqp = nonlinear.gauss_newton_sqp

    def recorded(problem, limits, u, **options):
        result = sqp(problem, limits, u, **options)
        runs.append((problem, limits, u, options, result))
        return result

    monkeypatch.setattr(nonlinear, "gauss_newton_sqp", recorded)
    plan = make("nonlinear_min_effort").plan(task, model)
    (_, _, _, first_options, first), (problem, limits, u, options, second) = runs
    assert first_options["join"] is None and options["join"] is first.u
    assert second.joined and second.converged and second.u is first.u
    np.testing.assert_array_equal(plan.u_plan.ravel(), first.u)
    alone = sqp(problem, limits, u, **{**options, "join": None})
    assert alone.converged and not alone.joined and alone.iterations > second.iterations
    assert problem.objective(alone.u) == pytest.approx(problem.objective(first.u), rel=1e-9)
    assert np.linalg.norm(alone.u - first.u) <= 1e-3 * np.linalg.norm(first.u)


def test_a_diverging_rollout_is_an_error_not_a_reset_state(model, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo logs its warning to MUJOCO_LOG.TXT in the working directory
    task = short_task(model, 0.3)
    n = task.n

    def rollout(speed):
        x0 = np.concatenate([task.q0, np.full(n, speed)])
        problem = Shooting(model, x0, x0, np.eye(2 * n), np.eye(n), task.steps, 1e-7)
        return problem.rollout(np.zeros((task.steps, n)))

    with pytest.raises(SolverError, match=r"^the rollout of an iterate diverged \(MuJoCo reset the simulation\)$"):
        rollout(1e20)  # MuJoCo would reset it to the model's rest pose and go on
    assert np.all(np.isfinite(rollout(1.0)))  # a sane rollout goes through


def test_the_gauss_newton_hessian_is_its_sum_over_the_samples(model):
    """Shooting.gauss_newton (a backward recursion) equals R (block diagonal) + sum_k S_k^T Q S_k by plain loops, for
    a full symmetric Q."""
    task = short_task(model, 0.3)
    rng = np.random.default_rng(5)
    n, N = task.n, task.steps
    root = rng.normal(size=(2 * n, 2 * n))
    Q, R = root @ root.T, np.diag(rng.uniform(0.5, 2.0, n))
    problem = Shooting(model, np.concatenate([task.q0, np.zeros(n)]), np.concatenate([task.qg, np.zeros(n)]), Q, R,
                       N, 1e-7)
    u = rng.normal(0.0, 1.0, N * n)
    S = problem.evaluate(u)[3]
    expected = np.kron(np.eye(N), R) + sum(S[k].T @ Q @ S[k] for k in range(1, N + 1))
    np.testing.assert_allclose(problem.gauss_newton(u), expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())


def test_sensitivities_filled_again_at_another_point_are_that_points_own(model):
    """Shooting.evaluate fills one array S at every new point: at u, then v, then u again it holds each point's own
    sensitivities, bit for bit those of a fresh problem evaluated there first (the entries it never writes stay
    zero)."""
    task = short_task(model, 0.3)
    rng = np.random.default_rng(8)
    n, N = task.n, task.steps

    def problem():
        return Shooting(model, np.concatenate([task.q0, np.zeros(n)]), np.concatenate([task.qg, np.zeros(n)]),
                        np.zeros((2 * n, 2 * n)), np.eye(n), N, 1e-7)

    reused = problem()
    u, v = rng.normal(0.0, 2.0, (2, N * n))
    for point in (u, v, u):
        np.testing.assert_array_equal(reused.evaluate(point)[3], problem().evaluate(point)[3])


def test_the_rollout_is_mujocos_own_step_loop_bit_for_bit_with_a_joint_on_its_limit(model):
    """Shooting.rollout (mujoco.rollout) against `replay`, a plain mj_step loop from a fresh MjData, on a model whose
    joint 1 is driven into a narrow range's end (the limit's constraint solver at work), twice and after another
    rollout: the same states bit for bit."""
    limited = copy.deepcopy(model)
    limited.jnt_range[1] = (-0.2, 0.2)
    limited.jnt_limited[1] = True
    task = short_task(model, 0.1, q0=np.array([0.3, 0.0, 0.5]))
    n, N = task.n, task.steps
    problem = Shooting(limited, np.concatenate([task.q0, np.zeros(n)]), np.concatenate([task.qg, np.zeros(n)]),
                       np.zeros((2 * n, 2 * n)), np.eye(n), N, 1e-7)
    U = np.tile([0.0, 40.0, 0.0], (N, 1))
    expected = replay(limited, task, U)
    assert np.abs(expected[:, 1]).max() > 0.2  # the limit is engaged (a soft constraint)
    for torques in (U, -U, U):
        np.testing.assert_array_equal(problem.rollout(torques), replay(limited, task, torques))


def test_the_path_rows_jacobian_is_their_derivative(model):
    """PathLimits.jacobian against central differences of the rows along random directions (through the rollout)."""
    task = short_task(model, 0.3)
    rng = np.random.default_rng(6)
    n, N = task.n, task.steps
    joints = JointInfo.of(model)
    limits = PathLimits(joints.torque_limit, joints.lower, joints.upper, np.full(n, np.pi))
    problem = Shooting(model, np.concatenate([task.q0, np.zeros(n)]), np.concatenate([task.qg, np.zeros(n)]),
                       np.eye(2 * n), np.eye(n), N, 1e-7)
    u = rng.normal(0.0, 2.0, N * n)
    rows = np.sort(rng.choice(6 * N * n, 60, replace=False))
    J = limits.jacobian(problem.evaluate(u)[3], rows)

    def h(v):
        return limits.values(*problem.states(v))[rows]

    for direction in rng.normal(size=(3, N * n)):
        eps = 1e-5
        numeric = (h(u + eps * direction) - h(u - eps * direction)) / (2 * eps)
        np.testing.assert_allclose(J @ direction, numeric, rtol=1e-4, atol=1e-6 * np.abs(numeric).max())
    weights = rng.normal(size=rows.size)
    on_states = limits.on_states(rows, weights, N, n)  # the rows' weights on x_k: the same derivative through S
    state = rows < 4 * N * n
    S = problem.evaluate(u)[3]
    np.testing.assert_allclose(np.einsum("ka,kab->b", on_states, S), weights[state] @ J[state], rtol=1e-12,
                               atol=1e-12 * np.abs(J).max())


def test_plans_keep_the_range_margin_but_always_reach_the_goal(model):
    """The plan's path keeps `NonlinearSettings.range_margin` (1e-4 rad) inside each joint's range, except that the
    margin never excludes the start
    or the goal: with joint 0's upper end 5e-5 rad beyond the goal (inside the margin) the goal is still reached and
    the path never passes it; joint 0's range as a bound on the samples then is the goal itself."""
    margin = 1e-4  # the default
    task = short_task(model, 0.3)
    near = copy.deepcopy(model)
    near.jnt_range[0] = (task.q0[0] - 1.0, task.qg[0] + 5e-5)
    near.jnt_limited[0] = True
    plan = make("nonlinear_min_effort").plan(task, near)
    np.testing.assert_allclose(plan.q[-1], task.qg, atol=1e-8)
    assert plan.q[:, 0].max() <= task.qg[0] + 1e-8
    problem, limits, _ = make("nonlinear_min_effort").problem(task, near)
    assert limits.q_high[0] == task.qg[0] and limits.q_low[0] == near.jnt_range[0, 0] + margin
    joints = JointInfo.of(model)
    np.testing.assert_array_equal(limits.q_high[1:], joints.upper[1:] - margin)


def test_the_second_order_term_is_the_curvature_of_the_weighted_states(model):
    """Shooting.second_order(u, w) against v^T H v' by second central differences of sum_k w_k^T x_k over whole
    MuJoCo rollouts (the oracle involves no derivative of ours), along random direction pairs; None where the model's
    tree does not give the rollout's Jacobians."""
    task = short_task(model, 0.3)
    rng = np.random.default_rng(9)
    n, N = task.n, task.steps
    problem = Shooting(model, np.concatenate([task.q0, np.zeros(n)]), np.concatenate([task.qg, np.zeros(n)]),
                       np.zeros((2 * n, 2 * n)), np.eye(n), N, 1e-7)
    u = rng.normal(0.0, 3.0, N * n)
    w = rng.normal(size=(N + 1, 2 * n))
    H = problem.second_order(u, w)
    assert H is not None
    np.testing.assert_allclose(H, H.T, atol=1e-12 * np.abs(H).max())

    def weighted(v):
        return float(np.sum(w[1:] * problem.states(v)[1][1:]))

    h = 1e-3
    for a, b in rng.normal(size=(4, 2, N * n)):
        oracle = (weighted(u + h * (a + b)) - weighted(u + h * (a - b)) - weighted(u - h * (a - b))
                  + weighted(u - h * (a + b))) / (4 * h * h)
        assert a @ H @ b == pytest.approx(oracle, rel=1e-4, abs=1e-6 * np.abs(H).max())
    limited = copy.deepcopy(model)
    limited.jnt_range[1] = (-1.6, -1.5)  # a narrow range about the start: the rollout meets the limit's force
    limited.jnt_limited[1] = True
    pressed = Shooting(limited, problem.x0, problem.xg, problem.Q, problem.R, N, 1e-7)
    assert pressed.second_order(u, w) is None and pressed.jacobian_counts == {"analytic": 0, "differenced": 1}


@pytest.mark.parametrize("hessian", ["dense", "diagonal"])
def test_the_qp_of_an_sqp_step_is_osqps_solution(hessian):
    """The step's QP (DAQP on the Cholesky-transformed problem; the box as simple bounds where H is diagonal, given
    as its diagonal) against OSQP on a random QP with equalities, rows and bounds, several of them active."""
    import osqp
    import scipy.sparse as sparse

    from mjtraj.core.planners.sqp import _qp

    rng = np.random.default_rng(7)
    size = 30
    root = rng.normal(size=(size, size))
    H, g = root @ root.T + np.eye(size), rng.normal(size=size) * 10
    if hessian == "diagonal":
        H = rng.uniform(0.01, 100.0, size)  # given as its diagonal, as the effort bound's
    C, c = rng.normal(size=(3, size)), rng.normal(size=3)
    G, h = rng.normal(size=(8, size)), rng.uniform(0.0, 0.5, 8)
    low, high = -np.full(size, 0.3), np.full(size, 0.3)
    d, multipliers = _qp(H, g, C, c, G, h, low, high, soft=False)
    solver = osqp.OSQP()
    dense = np.diag(H) if H.ndim == 1 else H
    solver.setup(sparse.csc_matrix(dense), g, sparse.csc_matrix(np.vstack([C, G, np.eye(size)])),
                 np.concatenate([-c, -h, low]), np.concatenate([-c, np.full(8, np.inf), high]), eps_abs=1e-10,
                 eps_rel=1e-10, polishing=True, max_iter=100_000, verbose=False)
    theirs = solver.solve(raise_error=True).x
    assert np.sum(np.isclose(np.abs(d), 0.3)) >= 3  # the bounds bind
    np.testing.assert_allclose(d, theirs, atol=1e-7)
    np.testing.assert_allclose(C @ d, -c, atol=1e-10)
    assert np.all(G @ d >= -h - 1e-10) and multipliers.shape == (11,)


def test_the_bound_linearises_analytically_and_reaches_the_differenced_plans_optimum(model, effort, monkeypatch):
    """On the shipped arm every linearisation of this plan is Pinocchio's (mjtraj.core.planners.rigid_body); with
    MuJoCo's differences alone the plan reaches the same optimum, to their noise."""
    task, _ = effort
    mine = make("nonlinear_min_effort").plan(task, model)
    assert mine.info["analytic_jacobians"] > 0 and mine.info["differenced_jacobians"] == 0
    monkeypatch.setattr("mjtraj.core.planners.shooting.RigidBody.of", lambda model, plant_forces=False: None)
    theirs = make("nonlinear_min_effort").plan(task, model)
    assert theirs.info["analytic_jacobians"] == 0 and theirs.info["differenced_jacobians"] > 0
    assert mine.info["objective"] == pytest.approx(theirs.info["objective"], rel=1e-7)
    np.testing.assert_allclose(mine.u_plan, theirs.u_plan, atol=1e-5 * np.abs(theirs.u_plan).max())


def test_the_sqp_plan_is_slsqps_optimum(model, effort):
    """nonlinear_optimal plans with the Gauss-Newton SQP by default and reaches SLSQP's optimum (SLSQP alone as the
    oracle); the plan holds every constraint."""
    task, _ = effort
    mine = make("nonlinear_optimal").plan(task, model)
    theirs = make("nonlinear_optimal", solver="slsqp").plan(task, model)
    assert (mine.info["solver"], theirs.info["solver"]) == ("sqp", "slsqp")
    assert mine.info["objective"] == pytest.approx(theirs.info["objective"], rel=1e-7)
    np.testing.assert_allclose(mine.u_plan, theirs.u_plan, atol=1e-4 * np.abs(theirs.u_plan).max())
    check_plan(model, task, mine)


@pytest.mark.slow
def test_the_sqp_plan_along_the_speed_limit_is_slsqps_optimum(model, plans):
    """The same where the speed limit binds (path rows active): no worse than SLSQP's optimum."""
    task, _, mine = plans
    theirs = make("nonlinear_optimal", solver="slsqp").plan(task, model)
    assert mine.info["solver"] == "sqp"
    assert mine.info["objective"] <= theirs.info["objective"] * (1 + 1e-7)


@pytest.mark.slow
def test_the_effort_bound_is_slsqps_optimum_or_lower_on_the_paper_task_and_50_nominal_tasks(model):
    """The issue's bar for the bound's solver, with SLSQP alone as the oracle: on the paper task and nominal
    scenarios 0-49 of seed 0 the default plan's objective is within 1e-4 of SLSQP's or below it, and the plan holds
    every constraint."""
    from mjtraj.domain.families import draw_scenario
    from mjtraj.domain.scenario import load_scenario

    tasks = [load_scenario(None).task] + [draw_scenario("nominal", 0, i, model, 0.02).task for i in range(50)]
    solvers = []
    for task in tasks:
        mine = make("nonlinear_min_effort").plan(task, model)
        theirs = make("nonlinear_min_effort", solver="slsqp").plan(task, model)
        assert mine.info["objective"] <= theirs.info["objective"] * (1 + 1e-4), (task, mine.info, theirs.info)
        check_plan(model, task, mine)
        solvers.append(mine.info["solver"])
    assert solvers.count("sqp") >= 45  # the SQP plans nearly all of them: SLSQP is the fallback


def test_auto_turns_to_slsqp_when_the_sqp_does_not_converge(model, effort, monkeypatch):
    """'auto' plans with SLSQP where the SQP stops unconverged from both starts and from the feasible point the least
    violation's search restores; 'sqp' fails then in one line, and where SLSQP fails too, the error carries every
    reason."""
    from mjtraj.core.planners import nonlinear

    task, _ = effort
    plan = make("nonlinear_optimal", sqp_max_iter=1).plan(task, model)
    assert plan.info["solver"] == "slsqp"
    check_plan(model, task, plan)
    with pytest.raises(SolverError, match=r"^nonlinear_optimal: the Gauss-Newton SQP stopped from the linear start: no "
                                          r"convergence in 1 iterations; from the tracked start: no convergence in 1 "
                                          r"iterations; from the feasible point restored from the linear start's last "
                                          r"iterate: no convergence in 1 iterations$"):
        make("nonlinear_optimal", solver="sqp", sqp_max_iter=1).plan(task, model)

    def fails(self, problem, limits, u, scale):
        raise SolverError(f"{self.name}: SLSQP failed at {scale:g}")

    monkeypatch.setattr(nonlinear.NonlinearOptimal, "_optimise", fails)
    with pytest.raises(SolverError, match=r"^nonlinear_optimal: SLSQP failed at 900 \(also with curvature_scale 30: "
                                          r"nonlinear_optimal: SLSQP failed at 30\) \(from the tracked start: "
                                          r"nonlinear_optimal: SLSQP failed at 30\) \(before SLSQP, the Gauss-Newton "
                                          r"SQP stopped from the linear start: no convergence in 1 iterations; from "
                                          r"the tracked start: no convergence in 1 iterations; from the feasible point "
                                          r"restored from the linear start's last iterate: no convergence in 1 "
                                          r"iterations\)$"):
        make("nonlinear_optimal", sqp_max_iter=1).plan(task, model)


def stage_hessians(problem, X, U, costates, eps=1e-4):
    """W_k = d2/dz2 (lambda_{k+1}^T F(z_k)) at z_k = [x_k; u_k], shape (N, 3n, 3n), F one step of the model: second
    differences of the steps from z_k, z_k + eps e_i and z_k + eps (e_i + e_j) (i <= j), all in one batch."""
    from mujoco.batch import Batch

    N, n = U.shape
    m = 3 * n
    upper_i, upper_j = np.triu_indices(m)
    directions = np.concatenate([np.eye(m), np.eye(m)[upper_i] + np.eye(m)[upper_j]])
    points = (np.concatenate([X[:-1], U], axis=1)[:, None, :] + eps * directions[None]).reshape(-1, m)
    batch = Batch(problem.model, len(points), nthread=1)
    batch.reset(list(range(len(points))))
    qpos, qvel, ctrl = batch.bind("qpos"), batch.bind("qvel"), batch.bind("ctrl")
    qpos[:], qvel[:], ctrl[:] = points[:, :n], points[:, n:2 * n], points[:, 2 * n:]
    batch.step(None, 1)
    after = np.concatenate([qpos, qvel], axis=1).reshape(N, len(directions), 2 * n)
    value = np.einsum("kpi,ki->kp", after, costates[1:])
    base = np.einsum("ki,ki->k", X[1:], costates[1:])
    single = value[:, :m]
    W = np.empty((N, m, m))
    W[:, upper_i, upper_j] = W[:, upper_j, upper_i] = (
        (value[:, m:] - single[:, upper_i] - single[:, upper_j] + base[:, None]) / eps ** 2)
    return W


@pytest.mark.slow
def test_the_gauss_newton_sqp_from_the_linear_start_stops_at_another_local_minimum_of_the_paper_task(model):
    """Why nonlinear_min_effort keeps the lowest of its starts' plans: on the paper task the Gauss-Newton SQP from the
    linear start converges to a strict local minimum costing 61 % more than the one it reaches from the tracked
    start (SLSQP's). Second-order sufficiency at it: the KKT conditions hold with least-squares multipliers, every
    active constraint's multiplier has its sign, and the Lagrangian's Hessian is positive definite on their null
    space. The Hessian is the Gauss-Newton term plus sum_k M_k^T W_k M_k (M_k = dz_k/du, W_k the costate-weighted
    second derivative of one step, by second differences); the oracle for it is the Lagrangian's curvature along
    null-space directions by second differences of whole rollouts."""
    import scipy.linalg

    from mjtraj.core.planners.optimal import planner_weights
    from mjtraj.domain.scenario import load_scenario

    task = load_scenario(None).task
    linear = make("nonlinear_min_effort", keep="first").plan(task, model)
    lowest = make("nonlinear_min_effort").plan(task, model)
    slsqp = make("nonlinear_min_effort", solver="slsqp").plan(task, model)
    assert (linear.info["start"], lowest.info["start"], lowest.info["sqp_converged"]) == ("linear", "tracked", 2)
    assert lowest.info["objective"] == pytest.approx(slsqp.info["objective"], rel=1e-6)
    assert linear.info["objective"] > 1.5 * lowest.info["objective"]
    joints = JointInfo.of(model)
    n, N = task.n, task.steps
    Q, R = planner_weights(task, joints.torque_limit, None, None, 0.0, 0.5)
    problem = Shooting(model, np.concatenate([task.q0, np.zeros(n)]), np.concatenate([task.qg, np.zeros(n)]), Q, R,
                       N, 1e-7)
    limits = PathLimits(joints.torque_limit, joints.lower, joints.upper, np.full(n, np.pi))
    u = linear.u_plan.ravel()
    U, X, A, S = problem.evaluate(u)
    active = np.flatnonzero(limits.values(U, X) <= 1e-7 * limits.scale(N))
    assert active.size and np.all(active < 4 * N * n)  # speed limits, no torque on its bound
    jacobian = limits.jacobian(S, active)
    gradient = problem.gradient(u)
    solved, *_ = np.linalg.lstsq(np.vstack([S[-1], -jacobian]).T, -gradient, rcond=None)
    terminal, path = solved[:2 * n], solved[2 * n:]  # L = f + terminal^T (x_N - x_g) - path^T h
    assert np.linalg.norm(gradient + S[-1].T @ terminal - jacobian.T @ path) < 1e-5 * np.linalg.norm(gradient)
    assert np.all(path > 1e-3 * path.max())  # strictly complementary
    group, rest = np.divmod(active, N * n)
    k, joint = np.divmod(rest, n)
    direct = np.zeros((N + 1, 2 * n))  # dL/dx_k through x_k itself
    direct[N] = terminal
    np.add.at(direct, (k + 1, np.where(group < 2, joint, n + joint)), path * np.where(group % 2 == 0, 1.0, -1.0))
    costates = direct.copy()
    for step in range(N - 1, 0, -1):
        costates[step] += A[step].T @ costates[step + 1]
    W = stage_hessians(problem, X, U, costates)
    M = np.zeros((N, 3 * n, N * n))
    M[:, :2 * n] = S[:-1]
    M.reshape(N, 3 * n, N, n)[np.arange(N), 2 * n:, np.arange(N), :] = np.eye(n)
    H = problem.gauss_newton(u) + M.reshape(-1, N * n).T @ (W @ M).reshape(-1, N * n)
    H = 0.5 * (H + H.T)
    second_order = problem.second_order(u, direct)  # the SQP's own (differenced analytic Jacobians, stage by stage)
    np.testing.assert_allclose(problem.gauss_newton(u) + second_order, H, rtol=1e-3, atol=1e-4 * np.abs(H).max())
    Z = scipy.linalg.null_space(np.vstack([S[-1], jacobian]))
    curvature, vectors = np.linalg.eigh(Z.T @ H @ Z)

    def lagrangian(v):
        U_v, X_v = problem.states(v)
        return problem.objective(v) + terminal @ (X_v[-1] - problem.xg) - path @ limits.values(U_v, X_v)[active]

    rng = np.random.default_rng(5)
    for direction in [Z @ vectors[:, 0], Z @ vectors[:, -1], Z @ rng.normal(size=Z.shape[1])]:
        direction /= np.linalg.norm(direction)
        oracle = (lagrangian(u + 1e-3 * direction) - 2 * lagrangian(u) + lagrangian(u - 1e-3 * direction)) / 1e-6
        assert direction @ H @ direction == pytest.approx(oracle, rel=1e-3)
    assert curvature[0] > 0.3 * np.diag(R).min(), curvature[0]  # positive definite: a strict local minimum


def test_tracking_gains_reach_the_discrete_riccati_gain_over_a_long_horizon():
    """Oracle: scipy's solver of the discrete algebraic Riccati equation. Far from the horizon's end the
    finite-horizon gains of a time-invariant system are the infinite-horizon gain."""
    import scipy.linalg

    from mjtraj.core.planners.tracking import tracking_gains

    rng = np.random.default_rng(3)
    A = np.eye(4) + 0.05 * rng.normal(size=(4, 4))
    B = 0.1 * rng.normal(size=(4, 2))
    Q, R = np.diag(rng.uniform(1, 10, 4)), np.diag(rng.uniform(0.1, 1, 2))
    K = tracking_gains(np.repeat(A[None], 400, axis=0), np.repeat(B[None], 400, axis=0), Q, R)
    P = scipy.linalg.solve_discrete_are(A, B, Q, R)
    np.testing.assert_allclose(K[0], np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A), rtol=1e-7)  # scipy: 1e-8
    P_last = Q  # the last gain sees only x_N's weight
    np.testing.assert_allclose(K[-1], np.linalg.solve(R + B.T @ P_last @ B, B.T @ P_last @ A), rtol=1e-12)


def test_tracking_gains_are_the_riccati_recursion_on_a_time_varying_system():
    """Oracle: the recursion written with NumPy's solve and products, on a random time-varying system with a full
    (not diagonal) positive definite R, 6 states and 3 inputs as on the UR5."""
    from mjtraj.core.planners.tracking import tracking_gains

    rng = np.random.default_rng(8)
    N = 60
    A = np.eye(6) + 0.05 * rng.normal(size=(N, 6, 6))
    B = 0.05 * rng.normal(size=(N, 6, 3))
    root = rng.normal(size=(3, 3))
    Q, R = np.diag(rng.uniform(1, 100, 6)), root @ root.T + 0.1 * np.eye(3)
    oracle, P = np.empty((N, 3, 6)), Q
    for k in range(N - 1, -1, -1):
        oracle[k] = np.linalg.solve(R + B[k].T @ P @ B[k], B[k].T @ P @ A[k])
        P = Q + A[k].T @ P @ (A[k] - B[k] @ oracle[k])
    np.testing.assert_allclose(tracking_gains(A, B, Q, R), oracle, rtol=1e-9, atol=1e-12 * np.abs(oracle).max())


def test_the_tracked_torques_are_the_feedback_law_and_replay_its_motion(model):
    """Shooting.tracked: u_k = clip(U_k + K_k (X_ref_k - x_k)) on the model's own steps, recomputed here by an
    independent loop, bit for bit; the returned torques replayed open loop give that motion; K = 0 is clip(U)."""
    task = short_task(model, 0.3)
    n, N = task.n, task.steps
    x0 = np.concatenate([task.q0, np.zeros(n)])
    problem = Shooting(model, x0, x0, np.eye(2 * n), np.eye(n), N, 1e-7)
    rng = np.random.default_rng(0)
    U = rng.normal(scale=20.0, size=(N, n))
    X_ref = x0 + rng.normal(scale=0.05, size=(N + 1, 2 * n))
    K = rng.uniform(0.0, 200.0, size=(N, n, 2 * n))
    u_max = np.full(n, 30.0)
    mine = problem.tracked(U, X_ref, K, u_max)
    data = mujoco.MjData(model)
    data.qpos[:] = task.q0
    theirs = []
    for k in range(N):
        u = np.clip(U[k] + K[k] @ (X_ref[k] - np.concatenate([data.qpos, data.qvel])), -u_max, u_max)
        theirs.append(u)
        data.ctrl[:] = u
        mujoco.mj_step(model, data)
    np.testing.assert_array_equal(mine, np.array(theirs))
    assert np.abs(mine).max() == 30.0  # the bound binds somewhere
    np.testing.assert_array_equal(problem.rollout(mine)[-1], np.concatenate([data.qpos, data.qvel]))
    tracked = problem.tracked(U, X_ref, K, u_max)
    np.testing.assert_array_equal(problem.states(tracked.ravel())[1], problem.rollout(tracked))  # served, not rolled
    np.testing.assert_array_equal(problem.tracked(U, X_ref, np.zeros_like(K), u_max), np.clip(U, -u_max, u_max))


def test_the_projected_step_is_the_open_loop_step_to_first_order_and_stays_near_its_prediction(model):
    """sqp.projector on the paper task's bound from its linear start, along a smooth random direction d: at t = 0
    it is u itself, bit for bit (the rollout tracks its own states); its distance from u + t d shrinks as t^2 (the
    two agree to first order, so the line search's predicted decrease holds); at t = 1 its states stay far nearer
    the linearised prediction x + S d than the open-loop step's, which single shooting's rollout amplifies."""
    from mjtraj.core.planners.sqp import projector
    from mjtraj.domain.scenario import load_scenario

    task = load_scenario(None).task
    problem, limits, starts = make("nonlinear_min_effort").problem(task, model)
    u = starts.get("linear")
    N, n = problem.steps, problem.n
    d = np.cumsum(np.random.default_rng(0).normal(size=(N, n)), axis=0).ravel()
    d *= 0.1 * np.linalg.norm(u) / np.linalg.norm(d)
    project = projector(problem, limits, u, d)
    np.testing.assert_array_equal(project(0.0), u)
    gaps = [np.linalg.norm(project(t) - (u + t * d)) for t in (1e-2, 1e-3)]
    assert 80.0 < gaps[0] / gaps[1] < 120.0, gaps
    _, X, _, S = problem.evaluate(u)
    prediction = X + S @ d
    projected = project(1.0)
    assert np.abs(projected).max() <= limits.u_max.max()
    open_loop = np.abs(problem.rollout((u + d).reshape(N, n)) - prediction)
    tracked = np.abs(problem.rollout(projected.reshape(N, n)) - prediction)
    assert tracked.max() < open_loop.max() / 5.0, (tracked.max(), open_loop.max())
    assert tracked[-1].max() < open_loop[-1].max() / 10.0, (tracked[-1], open_loop[-1])


@pytest.fixture(scope="module")
def drifting(model):
    """Nominal scenario 605 of seed 0: the linear plan's open-loop torques drive joint 1 into its end on the
    nonlinear arm, where the rollout's sensitivities vanish."""
    from mjtraj.domain.families import draw_scenario

    return draw_scenario("nominal", 0, 605, model, 0.02).task


def optimal_problem(model, task):
    """`nonlinear_optimal`'s problem for `task` as it plans it (`NonlinearOptimal.problem`): (its Shooting problem,
    path limits, the linear start)."""
    problem, limits, starts = make("nonlinear_optimal").problem(task, model)
    return problem, limits, starts.get("linear")


def test_a_start_drifting_into_a_joints_end_is_planned_from_the_tracked_start(model, drifting):
    """From the linear start the Gauss-Newton SQP finds no step (the linearised terminal condition cannot be met);
    from the tracked start it converges, and the plan holds every constraint."""
    from mjtraj.core.planners.sqp import gauss_newton_sqp

    problem, limits, start = optimal_problem(model, drifting)
    joints = JointInfo.of(model)
    _, X = problem.states(start)
    assert X[:, 1].min() < joints.lower[1] + 1e-3  # into joint 1's lower end
    stuck = gauss_newton_sqp(problem, limits, start, max_iter=40)
    assert not stuck.converged and stuck.message == "the linearised constraints admit no step"
    plan = make("nonlinear_optimal").plan(drifting, model)
    assert (plan.info["solver"], plan.info["start"]) == ("sqp", "tracked")
    check_plan(model, drifting, plan)


def test_a_solve_allowed_exactly_the_steps_it_needs_converges(model, effort):
    """The iterate of the last allowed step is tested too: a solve capped at the number of steps in which it
    converges reports convergence, with the same iterate bit for bit; one step fewer does not."""
    from mjtraj.core.planners.sqp import gauss_newton_sqp

    problem, limits, start = optimal_problem(model, effort[0])

    def solve(max_iter):
        return gauss_newton_sqp(problem, limits, start, max_iter=max_iter)

    free = solve(100)
    assert free.converged and 2 <= free.iterations < 100
    capped, short = solve(free.iterations), solve(free.iterations - 1)
    assert capped.converged and capped.iterations == free.iterations
    np.testing.assert_array_equal(capped.u, free.u)
    assert not short.converged and short.message == f"no convergence in {free.iterations - 1} iterations"


def test_the_step_qp_closes_part_of_the_way_where_the_whole_way_is_infeasible(monkeypatch):
    """sqp._step_qp on two torques in the box [-1, 1] (H = I, g = 0, so d is the least-norm point): a terminal row
    d1 + d2 = -c the box cannot meet is asked half, then a quarter of the way; a violated path row (h < 0) is scaled
    with it, a row that holds (h >= 0) is not; where no share admits a step, the path rows go soft; where the
    terminal row itself cannot be met, there is no step and no soft solve is tried. Oracle: the least-norm
    solutions by hand."""
    from mjtraj.core.planners import sqp
    from mjtraj.core.planners.sqp import SqpSettings, _step_qp

    qp = sqp._qp_to

    assert SqpSettings().relaxed == (0.5, 0.25)
    H, g, low, high = np.eye(2), np.zeros(2), -np.ones(2), np.ones(2)
    C, none = np.array([[1.0, 1.0]]), (np.zeros((0, 2)), np.zeros(0))

    def step(c, G=none[0], h=none[1]):
        return _step_qp(H, g, C, np.array([c]), G, np.array(h, dtype=float), low, high)

    d, _, share, soft = step(1.0)
    assert (share, soft) == (1.0, False)
    np.testing.assert_allclose(d, [-0.5, -0.5], atol=1e-12)  # feasible: the whole way
    d, _, share, soft = step(3.0)
    assert (share, soft) == (0.5, False)
    np.testing.assert_allclose(d, [-0.75, -0.75], atol=1e-12)  # d1 + d2 = -1.5
    d, _, share, soft = step(5.0)
    assert (share, soft) == (0.25, False)
    np.testing.assert_allclose(d, [-0.625, -0.625], atol=1e-12)  # d1 + d2 = -1.25
    G = np.array([[1.0, 0.0], [-1.0, 0.0]])
    d, _, share, soft = step(0.0, G, [-3.0, 2.0])  # d1 >= 3 (violated), d1 <= 2: a quarter asks d1 >= 0.75
    assert (share, soft) == (0.25, False)
    np.testing.assert_allclose(d, [0.75, -0.75], atol=1e-9)
    d, _, share, soft = step(0.0, G, [-3.0, 0.5])  # d1 <= 0.5 holds at d = 0 and is not scaled: only soft rows
    assert (share, soft) == (1.0, True)
    assert d[0] + d[1] == pytest.approx(0.0, abs=1e-9)  # the terminal row stays hard
    solves = []
    monkeypatch.setattr(sqp, "_qp_to", lambda *args: solves.append(args[9]) or qp(*args))
    assert step(10.0, G, [-3.0, 0.5]) is None  # |d1 + d2| <= 2 in the box: not even a quarter of 10
    assert solves == [False, False, False, False]  # the terminal row alone fails: no soft solve


def test_a_torque_on_its_bound_stays_there_and_the_sqp_plans_where_slsqp_had_to(model):
    """Aggressive 39 of seed 1 (`nonlinear_optimal`): its plan saturates a torque at -60 N m from the first sample.
    An iterate rounded a few ulps past the bound made MuJoCo clamp that torque, so its column of the analytic
    Jacobian was zero: each QP then moved it 60 N m for free, every trial was refused, and SLSQP planned (0.5 s,
    objective 25.3219). Iterates now stay on the box: the SQP converges. Oracle: SLSQP alone, whose plan is no
    lower; the plan's torques never pass the bound."""
    from mjtraj.domain.families import draw_scenario
    from mjtraj.domain.scenario import load_scenario

    task = draw_scenario("aggressive", 1, 39, model, load_scenario(None).task.dt).task
    plan = make("nonlinear_optimal").plan(task, model)
    assert plan.info["solver"] == "sqp"
    assert np.abs(plan.u_plan).max() <= 60.0 and np.abs(plan.u_plan).max() == 60.0
    slsqp = make("nonlinear_optimal", solver="slsqp").plan(task, model)
    assert plan.info["objective"] <= slsqp.info["objective"] * (1.0 + 1e-9)
    check_plan(model, task, plan)


@pytest.mark.slow
def test_slow_gauss_newton_turns_to_newton_early_and_reaches_the_same_plan(model, monkeypatch):
    """Nominal 145 of seed 1 (`nonlinear_min_effort`, linear start): Gauss-Newton contracts by about 0.5 an
    iteration. With `SqpSettings.slow` the Hessian turns to the Lagrangian's once three slow iterations follow the
    8th, not after the 20th; the plan is the same minimum (oracle: the solve without the slow switch, to 1e-9), in
    fewer iterations."""
    from mjtraj.core.planners import sqp
    from mjtraj.domain.families import draw_scenario
    from mjtraj.domain.scenario import load_scenario

    task = draw_scenario("nominal", 1, 145, model, load_scenario(None).task.dt).task
    problem, limits, starts = make("nonlinear_min_effort").problem(task, model)
    iterations: list[int] = []  # one entry per iteration (its gradient), then the first Hessian's iteration
    first: list[int] = []
    gradient, hessian = problem.gradient, sqp._lagrangian_hessian

    def counted(problem, *args):
        first.append(len(iterations))
        return hessian(problem, *args)

    def solve(settings):
        iterations.clear()
        first.clear()
        result = sqp.gauss_newton_sqp(problem, limits, starts.get("linear"), max_iter=40, settings=settings)
        assert result.converged
        return result, first[0] - 1  # the iterations before the first Newton one

    monkeypatch.setattr(problem, "gradient", lambda u: iterations.append(0) or gradient(u))
    monkeypatch.setattr(sqp, "_lagrangian_hessian", counted)
    default = sqp.SqpSettings()
    early, gauss_newton = solve(default)
    assert default.slow[0] <= gauss_newton < default.second_order_after
    late, gauss_newton = solve(sqp.SqpSettings(slow=(10 ** 6, 3, 0.7)))
    assert gauss_newton == default.second_order_after
    assert early.iterations < late.iterations
    assert problem.objective(early.u) == pytest.approx(problem.objective(late.u), rel=1e-9)


@pytest.mark.slow
def test_slsqp_reaches_the_sqps_plan_from_the_tracked_start(model, drifting):
    """The oracle for the drifting task: SLSQP from the same start as the SQP's plan, the tracked one, on the same
    problem (`NonlinearOptimal.problem`), reaches its objective. (SLSQP alone, from the linear start, now converges,
    in 1,125 iterations, to a local minimum 71 % higher: the problem is not convex.)"""
    planner = make("nonlinear_optimal")
    mine = planner.plan(drifting, model)
    assert (mine.info["solver"], mine.info["start"]) == ("sqp", "tracked")
    problem, limits, starts = planner.problem(drifting, model)
    u, *_ = planner._optimise(problem, limits, starts.get("tracked"), planner.curvature_scale)
    assert problem.objective(u) == pytest.approx(mine.info["objective"], rel=1e-7)


def test_a_torque_on_its_upper_bound_has_its_effect_in_the_transition_jacobian(model):
    """MuJoCo clamps ctrl to its range, so a forward difference of a torque at +u_max sees no effect; the Jacobian
    differences it backwards. Oracle: the same model with the ctrl range opened, where nothing clamps, at the same
    point: B_k agrees to the differences' accuracy at +u_max, -u_max and inside."""
    task = short_task(model, 0.3)
    n, N = task.n, task.steps
    x0 = np.concatenate([task.q0, np.zeros(n)])
    high = model.actuator_ctrlrange[:, 1]
    U = np.zeros((N, n))
    U[::3] = high  # on the upper bound
    U[1::3] = -high  # on the lower one
    open_model = copy.copy(model)
    open_model.actuator_ctrlrange[:] = [-1e3, 1e3]
    mine, theirs = (Shooting(m, x0, x0, np.eye(2 * n), np.eye(n), N, 1e-7) for m in (model, open_model))
    X = mine.rollout(U)
    np.testing.assert_array_equal(X, theirs.rollout(U))  # the bound itself is not clamped
    _, B = mine.jacobians(X, U)
    _, B_open = theirs.jacobians(X, U)
    np.testing.assert_allclose(B, B_open, rtol=0, atol=1e-6 * np.abs(B_open).max())
    assert np.abs(B[0]).max() > 0.1 * np.abs(B_open[0]).max()  # not the forward difference's zero column


def test_the_transition_jacobian_is_one_fresh_simulation_per_difference_bit_for_bit(model):
    """Shooting.jacobians steps every perturbed point in one batch on every CPU, restores the batch's reset rows by a
    copy, and steps a copy of the model without collision detection (no geom of the arm can touch another). Oracle:
    a fresh MjData of the model itself per perturbed point, stepped once; equal bit for bit, on a motion that rides
    a joint's end (the constraint solver at work), at a second point too (nothing carried over)."""
    n, N = 3, 25
    x0 = np.array([0.0, -np.pi / 2, model.jnt_range[2, 0] + 0.05, 0.0, 0.0, -1.0])  # the elbow near its lower end
    problem = Shooting(model, x0, x0, np.eye(2 * n), np.eye(n), N, 1e-6)
    rng = np.random.default_rng(3)
    limited = 0
    for scale in (60.0, 10.0):
        U = np.clip(rng.normal(scale=scale, size=(N, n)), -60.0, 59.9)
        X = problem.rollout(U)
        A, B = problem.jacobians(X, U)
        data = mujoco.MjData(model)
        for k in range(N):
            limited += X[k, 2] < model.jnt_range[2, 0] + 1e-3
            for j in range(3 * n):
                mujoco.mj_resetData(model, data)
                point = np.concatenate([X[k], U[k]])
                point[j] += 1e-6
                data.qpos[:], data.qvel[:], data.ctrl[:] = point[:n], point[n:2 * n], point[2 * n:]
                mujoco.mj_step(model, data)
                column = (np.concatenate([data.qpos, data.qvel]) - X[k + 1]) / 1e-6
                np.testing.assert_array_equal(column, A[k][:, j] if j < 2 * n else B[k][:, j - 2 * n])
    assert limited > 0
    assert problem._stepped.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT  # the caller's model untouched


def test_a_model_whose_geoms_can_touch_keeps_its_collision_detection():
    """Where two geoms can collide, the shooting problem steps the model itself, contacts and all."""
    from mjtraj.core.planners.shooting import _collision_free

    model = mujoco.MjModel.from_xml_string("""
    <mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
      <body pos="0 0 0.2"><joint name="j" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.05"/></body></worldbody>
      <actuator><motor joint="j" ctrlrange="-1 1"/></actuator></mujoco>""")
    assert _collision_free(model) is model
    model.geom_conaffinity[:] = 0
    free = _collision_free(model)
    assert free is not model and free.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT


def test_above_the_torque_cap_auto_refuses_without_slsqp(model, monkeypatch):
    """Where the SQP does not converge on a plan of more than `NonlinearSettings.slsqp_max_torques` torques, 'auto'
    refuses with the reason and never runs SLSQP (on a 7-hinge arm one failed SLSQP solve took 200 s)."""
    from mjtraj.core.planners.nonlinear import NonlinearSettings
    from mjtraj.exceptions import SolverError

    planner = make("nonlinear_min_effort", settings=NonlinearSettings(slsqp_max_torques=299))
    monkeypatch.setattr(type(planner), "_sqp", lambda self, *a: (SimpleNamespace(u=a[2], iterations=40, rows=0),
                                                                 "no convergence in 40 iterations"))
    monkeypatch.setattr(type(planner), "_restored", lambda self, *a: [])
    monkeypatch.setattr(type(planner), "_slsqp", lambda self, *a: pytest.fail("SLSQP ran"))
    task = Task.create([0.0, -1.57, 0.0], [0.5, -1.0, 0.5], 2.0, 0.02)
    with pytest.raises(SolverError, match=r"SLSQP, the fallback, is not run on more than 299 torques \(N n = 300"):
        planner.plan(task, model)


def test_the_compiled_sensitivities_are_the_products_of_their_definition():
    """shooting._propagate against S_{k+1} = A_k S_k + B_k E_k (E_k selects u_k) as NumPy's products, on random
    transitions: the same to rounding left of each sample's block, and nothing written right of it (where x_k does
    not depend on the torques, and `Shooting.evaluate`'s array stays zero)."""
    from mjtraj.core.planners.shooting import _propagate

    rng = np.random.default_rng(5)
    N, n = 40, 3
    A = np.eye(2 * n) + 0.1 * rng.normal(size=(N, 2 * n, 2 * n))
    B = rng.normal(size=(N, 2 * n, n))
    S = np.full((N + 1, 2 * n, N * n), np.nan)
    _propagate(A, B, S)
    expected = np.zeros((N + 1, 2 * n, N * n))
    for k in range(N):
        expected[k + 1] = A[k] @ expected[k]
        expected[k + 1, :, k * n:(k + 1) * n] += B[k]
    for k in range(N + 1):
        np.testing.assert_allclose(S[k, :, :k * n], expected[k, :, :k * n], rtol=1e-12, atol=1e-12)
        assert np.all(np.isnan(S[k, :, k * n:]))


@pytest.mark.slow
def test_reusing_the_lagrangians_hessian_reaches_the_same_plan_with_fewer_hessians(model, monkeypatch):
    """Nominal 145 of seed 1 (`nonlinear_min_effort`, linear start): with `SqpSettings.newton_reuse` the SQP makes
    fewer Lagrangian Hessians than with a new one every Newton iteration, and reaches the same minimum (oracle: the
    solve without reuse, Newton's method proper, to 1e-9), every constraint met."""
    from mjtraj.core.planners import sqp
    from mjtraj.core.planners.nonlinear import NonlinearOptimal
    from mjtraj.domain.families import draw_scenario
    from mjtraj.domain.scenario import load_scenario

    task = draw_scenario("nominal", 1, 145, model, load_scenario(None).task.dt).task
    problem, limits, starts = make("nonlinear_min_effort").problem(task, model)
    made: list[int] = []
    hessian = sqp._lagrangian_hessian
    monkeypatch.setattr(sqp, "_lagrangian_hessian", lambda *args: made.append(1) or hessian(*args))

    def solve(reuse: int) -> tuple[sqp.SqpResult, int]:
        made.clear()
        result = sqp.gauss_newton_sqp(problem, limits, starts.get("linear"), max_iter=40,
                                      settings=sqp.SqpSettings(newton_reuse=reuse))
        assert result.converged and NonlinearOptimal._unmet(problem, limits, result.u) is None
        return result, len(made)

    reused, some = solve(sqp.SqpSettings().newton_reuse)
    newton, every = solve(0)
    assert 0 < some < every
    assert problem.objective(reused.u) == pytest.approx(problem.objective(newton.u), rel=1e-9)
