"""The exact active-set solver on the banded KKT system, against quadprog and OSQP on the paper's QP."""


from __future__ import annotations

import numpy as np
import quadprog  # a test dependency (extra 'test'): a missing one fails, never skips

from mjtraj.core import lqr
from mjtraj.core.linearize import discretize_zoh, linearize
from mjtraj.core.lqr import box_lqr
from mjtraj.core.planners import make
from mjtraj.core.qp import build_qp
from mjtraj.core.task import random_task


def _problems(model, rng, count, steps):
    """Random linearisations, weights and starts of the arm: Ad, Bd, Q, R, x0 with a leading axis of `count`."""
    Ad, Bd = [], []
    for _ in range(count):
        A, B = linearize(model, rng.uniform([-3, -2.5, -2.5], [3, -0.5, 2.5]))
        a, b = discretize_zoh(A, B, 0.02)
        Ad.append(a)
        Bd.append(b)
    Q = np.array([np.diag(rng.uniform(0, 10, 6)) for _ in range(count)])
    R = np.array([np.diag(rng.uniform(1e-4, 1e-2, 3)) for _ in range(count)])
    x0 = np.concatenate([rng.uniform(-1.5, 1.5, (count, 3)), rng.uniform(-0.5, 0.5, (count, 3))], axis=1)
    return np.array(Ad), np.array(Bd), Q, R, x0


def _quadprog(Ad, Bd, Q, R, x0, steps, bound):
    """The condensed QP (`build_qp`) solved by quadprog's dense active set: the torques, (N, nu)."""
    qp = build_qp(Ad, Bd, x0, steps, Q, R, -bound, bound)
    H, f, A, b_eq, lb, ub = (np.array(a, dtype=np.float64) for a in (qp.H, qp.f, qp.A_eq, qp.b_eq, qp.lb, qp.ub))
    n = H.shape[0]
    C = np.hstack([A.T, np.eye(n), -np.eye(n)])
    return quadprog.solve_qp(H, -f, C, np.concatenate([b_eq, lb, -ub]), A.shape[0])[0].reshape(steps, -1)


def test_banded_kkt_active_set_equals_quadprog(model, rng):
    """Bounds from loose to tight: no input on a bound (one solve), a few (the Schur complement on the first
    factorisation) and many (a new factorisation) all give quadprog's torques, and x_N = 0. A problem the active
    set leaves unsolved goes to OSQP in the planner (`test_active_set_equals_osqp_through_the_planner`)."""
    steps = 40
    Ad, Bd, Q, R, x0 = _problems(model, rng, 6, steps)
    free = box_lqr(Ad, Bd, Q, R, x0, steps, np.full((6, 3), 1e9))
    peak = np.abs(free.U).max(axis=1)
    counts = []
    for fraction in (2.0, 0.97, 0.9, 0.6, 0.35):
        bound = fraction * peak
        solution = box_lqr(Ad, Bd, Q, R, x0, steps, bound)
        for p in range(6):
            if not solution.solved[p]:  # an active set whose free inputs cannot reach x_N = 0: left to OSQP
                continue
            expected = _quadprog(Ad[p], Bd[p], Q[p], R[p], x0[p], steps, bound[p])
            scale = np.abs(expected).max()
            np.testing.assert_allclose(solution.U[p], expected, atol=1e-8 * scale)
            assert np.abs(solution.X[p, -1]).max() < 1e-9
            np.testing.assert_array_equal(solution.active[p] != 0, np.abs(solution.U[p]) >= bound[p])
            counts.append(int(np.sum(solution.active[p] != 0)))
    counts_seen = np.array(counts)
    assert counts_seen.size >= 27  # of 30
    assert np.any(counts_seen == 0)
    assert np.any((counts_seen >= 1) & (counts_seen <= lqr.SCHUR_MAX))
    assert np.any(counts_seen > lqr.SCHUR_MAX)


def test_one_problem_alone_equals_in_a_batch(model, rng):
    steps = 30
    Ad, Bd, Q, R, x0 = _problems(model, rng, 4, steps)
    bound = np.full((4, 3), 15.0)
    together = box_lqr(Ad, Bd, Q, R, x0, steps, bound)
    for p in range(4):
        alone = box_lqr(Ad[p:p + 1], Bd[p:p + 1], Q[p:p + 1], R[p:p + 1], x0[p:p + 1], steps, bound[p:p + 1])
        np.testing.assert_array_equal(alone.U[0], together.U[p])
        np.testing.assert_array_equal(alone.X[0], together.X[p])


def test_unreachable_end_is_not_solved(model, rng):
    """With bounds too small to reach x_N = 0 the solver reports the problem unsolved (for OSQP to prove it)."""
    steps = 10
    Ad, Bd, Q, R, x0 = _problems(model, rng, 2, steps)
    solution = box_lqr(Ad, Bd, Q, R, x0, steps, np.full((2, 3), 1e-3))
    assert not solution.solved.any()


def test_active_set_equals_osqp_through_the_planner(model, rng):
    """The planner's exact solver and OSQP agree on random tasks, with and without active torque bounds."""
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
        assert ref.info["solver"] == "kkt-active-set"
        active += ref.info["active_bounds"] > 0
        np.testing.assert_allclose(ref.u_plan, expected.u_plan, atol=1e-6)
        assert ref.info["objective"] <= expected.info["objective"] * (1 + 1e-9)
        assert ref.info["terminal_residual"] < 1e-9
    assert active >= 2  # the bounds bind in some of them
