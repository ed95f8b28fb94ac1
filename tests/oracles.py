"""Oracles and tasks shared by the planner, QP and nonlinear planner tests."""

from __future__ import annotations

import numpy as np

from mjtraj.core.task import Task

SHORT_Q0 = np.array([0.0, -np.pi / 2, 0.0])
SHORT_DIRECTION = np.array([1.0, 0.5, -1.0])
"""`short_task`'s default start and its direction of motion."""

WEIGHTS = {"state_weight": (1.0, 1.0, 1.0, 0.1, 0.1, 0.1), "input_weight": (1 / 3600,) * 3}
"""Fixed optimal-planner weights (Bryson's for a 1 rad move)."""


def unit_task(model, n_move=1.0):
    """From (0, -1.5, 0.5) rad, every joint by n_move rad, in 2 s at 0.02 s."""
    q0 = np.array([0.0, -1.5, 0.5])
    return Task.create(q0, q0 + n_move, 2.0, 0.02, model=model)


def short_task(model, move, duration=0.5, q0=SHORT_Q0):
    """A move of `move` rad along SHORT_DIRECTION in `duration` s (N = 25 at dt = 0.02: the nonlinear planners plan
    it in seconds, not minutes)."""
    return Task.create(q0, q0 + move * SHORT_DIRECTION, duration, 0.02, model=model)


def kkt_solve(qp):
    """Dense KKT solve of the equality-constrained QP (bounds dropped): the independent solve."""
    n, m = qp.H.shape[0], qp.A_eq.shape[0]
    K = np.block([[qp.H, qp.A_eq.T], [qp.A_eq, np.zeros((m, m))]])
    return np.linalg.solve(K, np.concatenate([-qp.f, qp.b_eq]))[:n]


def same_outcome(a, b) -> bool:
    """Outcomes equal bit for bit, NaN metrics (not measured) included."""
    return (a.status, a.reason, sorted(a.metrics)) == (b.status, b.reason, sorted(b.metrics)) and all(
        np.array_equal(a.metrics[k], b.metrics[k], equal_nan=True) for k in a.metrics)
