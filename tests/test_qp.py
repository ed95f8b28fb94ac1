"""The condensed QP: its prediction against simulation, a dense KKT solve, and OSQP's checked answers."""


from __future__ import annotations

import numpy as np
import pytest
from oracles import WEIGHTS, kkt_solve, unit_task

from mjtraj.core.linearize import discretize_zoh, linearize
from mjtraj.core.planners import make
from mjtraj.core.qp import build_qp, solve_qp


def test_condensed_prediction_matches_simulation(model, rng):
    A, B = linearize(model, [0.3, -1.0, 0.8])
    Ad, Bd = discretize_zoh(A, B, 0.02)
    x0 = rng.normal(size=6)
    qp = build_qp(Ad, Bd, x0, 30, np.eye(6), np.eye(3), -np.ones(3), np.ones(3))
    U = rng.normal(size=90)
    x, states = x0, [x0]
    for u in U.reshape(30, 3):
        x = Ad @ x + Bd @ u
        states.append(x)
    np.testing.assert_allclose(qp.predict(U), np.array(states), atol=1e-12)
    # the objective written as sums (paper eq. 19), independent of the condensed H, f
    direct = 0.5 * sum(s @ s for s in states) + 0.5 * U @ U
    assert qp.objective(U) == pytest.approx(direct, rel=1e-10)


def test_solve_qp_checks_its_answer(model, task):
    qp, _ = make("optimal").build(task, model)
    solution = solve_qp(qp)
    assert solution.is_optimal() and solution.polished


def test_solver_failure_reports_status(model, task):
    planner = make("optimal", solver="osqp", osqp_settings={"max_iter": 3, "polishing": False})
    from mjtraj.exceptions import SolverError

    with pytest.raises(SolverError, match=r"^OSQP did not solve the QP: status 'maximum iterations reached' after 3 "
                                          r"iterations$"):
        planner.plan(task, model)


def test_optimal_equals_dense_kkt_when_bounds_inactive(model):
    task = unit_task(model, n_move=0.3)
    planner = make("optimal", torque_bound=1e4, **WEIGHTS)
    qp, _ = planner.build(task, model)
    ref = planner.plan(task, model)
    U_kkt = kkt_solve(qp)
    assert np.max(np.abs(U_kkt)) < 1e4
    np.testing.assert_allclose(ref.u_plan.ravel(), U_kkt, atol=1e-6)
    assert ref.info["terminal_residual"] <= 1e-8

