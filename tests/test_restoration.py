"""The least violation of the nonlinear planners' constraints (`mjtraj.core.planners.restoration`), and what the
planners do with it where their SQP stops short: a local infeasibility reported, or a plan from a restored point."""

from __future__ import annotations

import numpy as np
import pytest
from oracles import short_task

from mjtraj.core.planners import make
from mjtraj.core.planners.restoration import least_violation, residual
from mjtraj.exceptions import InfeasibleError, SolverError


@pytest.fixture(scope="module")
def impossible(model):
    """Joints 0 and 2 move 0.2 rad in 0.3 s from rest to rest under a speed limit of 0.5 rad/s: a mean speed of
    0.67 rad/s, 1.33 times the largest allowed. No plan exists."""
    task = short_task(model, 0.2, duration=0.3)
    return task, make("nonlinear_min_effort", speed_limit=0.5)


@pytest.mark.slow
def test_an_impossible_move_is_reported_locally_infeasible(model, impossible):
    """The SQP stops short from both starts, and the least violation is positive from both: InfeasibleError, local,
    naming a joint that misses its goal."""
    task, planner = impossible
    with pytest.raises(InfeasibleError, match=r"^nonlinear_min_effort: no plan near where the SQP stopped \(locally "
                                              r"infeasible\): the least violation of the constraints is positive from "
                                              r"the linear start's last iterate \(joint [02] misses its goal by .*; "
                                              r"from the tracked start's last iterate \(joint [02] misses its goal by "
                                              r".*not a proof that no plan exists$"):
        planner.plan(task, model)


def test_the_least_violation_is_a_stationary_point_of_the_violation(model, impossible):
    """Oracle: finite differences. From the search's end, 1/2 |r|^2 grows (to first order, not at all falls) along
    every direction that stays in the torque box; the search reports convergence and a positive violation."""
    task, planner = impossible
    problem, limits, starts = planner.problem(task, model)
    least = least_violation(problem, limits, starts.get("linear"))
    assert least.converged and not least.feasible and least.optimality < 1e-5
    np.testing.assert_array_equal(least.residual, residual(problem, limits, least.u))
    u, u_max = least.u, np.tile(limits.u_max, problem.steps)
    assert np.abs(u).max() <= limits.u_max.max()
    value = 0.5 * float(np.sum(least.residual ** 2))
    rng = np.random.default_rng(1)
    for _ in range(10):
        v = rng.normal(size=u.shape)
        v[(u >= u_max - 1e-12) & (v > 0)] *= -1.0  # into the box where u sits on its bound
        v[(u <= -u_max + 1e-12) & (v < 0)] *= -1.0
        v /= np.linalg.norm(v)
        for eps in (1e-3, 1e-4):
            moved = 0.5 * float(np.sum(residual(problem, limits, u + eps * v) ** 2))
            assert moved - value > -1e-8 * eps * value, (eps, moved - value)


def test_where_the_sqp_stops_short_it_plans_again_from_a_restored_feasible_point(model, monkeypatch):
    """The SQP made to stop after one iteration from both starts: the least violation's search finds a feasible
    point, and the SQP from it reaches the plan of an unhindered solve."""
    from mjtraj.core.planners import nonlinear

    task = short_task(model, 0.3)
    free = make("nonlinear_min_effort").plan(task, model)
    real, calls = nonlinear.gauss_newton_sqp, []

    def hindered(*args, **kwargs):
        calls.append(kwargs.get("join") is not None)
        if len(calls) <= 2:
            kwargs["max_iter"] = 1
        return real(*args, **kwargs)

    monkeypatch.setattr(nonlinear, "gauss_newton_sqp", hindered)
    plan = make("nonlinear_min_effort").plan(task, model)
    assert len(calls) == 3 and plan.info["start"] == "restored" and plan.info["solver"] == "sqp"
    assert plan.info["objective"] == pytest.approx(free.info["objective"], rel=1e-8)
    np.testing.assert_allclose(plan.u_plan, free.u_plan, atol=1e-5 * np.abs(free.u_plan).max())


def test_a_search_that_does_not_converge_leaves_the_verdict_to_slsqp(model, impossible, monkeypatch):
    """MAX_EVALUATIONS cut to 3: no verdict from the search, so 'sqp' fails with every reason (and 'auto' would turn
    to SLSQP)."""
    from mjtraj.core.planners import restoration

    monkeypatch.setattr(restoration, "MAX_EVALUATIONS", 3)
    task, _ = impossible
    with pytest.raises(SolverError, match=r"^nonlinear_min_effort: the Gauss-Newton SQP stopped from the linear "
                                          r"start: .*; from the tracked start: .*; the least violation's search from "
                                          r"the linear start's last iterate did not converge in \d rollouts$"):
        make("nonlinear_min_effort", speed_limit=0.5, solver="sqp").plan(task, model)


@pytest.mark.slow
def test_a_large_problem_searches_without_the_dense_svd_and_within_its_cap(model, impossible, monkeypatch):
    """LARGE_TORQUES cut to 0, so the UR5's impossible move takes the path of a 6- or 7-hinge arm: scipy's 'lsmr'
    subproblems approach the dense search's stationary point (the same positive violation, the projected gradient
    small) within MAX_EVALUATIONS_LARGE rollouts, which bound the search."""
    import scipy.optimize

    from mjtraj.core.planners import restoration

    task, planner = impossible
    problem, limits, starts = planner.problem(task, model)
    dense = least_violation(problem, limits, starts.get("linear"))
    monkeypatch.setattr(restoration, "LARGE_TORQUES", 0)
    seen = []
    real = scipy.optimize.least_squares
    monkeypatch.setattr(scipy.optimize, "least_squares", lambda *a, **k: seen.append(k) or real(*a, **k))
    large = least_violation(problem, limits, starts.get("linear"))
    assert seen[-1]["tr_solver"] == "lsmr" and seen[-1]["max_nfev"] == restoration.MAX_EVALUATIONS_LARGE
    assert not large.feasible and large.optimality < 1e-4 and large.evaluations <= restoration.MAX_EVALUATIONS_LARGE
    assert 0.5 * np.sum(large.residual ** 2) == pytest.approx(0.5 * np.sum(dense.residual ** 2), rel=1e-3)
    monkeypatch.setattr(restoration, "MAX_EVALUATIONS_LARGE", 3)
    capped = least_violation(problem, limits, starts.get("linear"))
    assert not capped.converged and capped.evaluations <= 4
