"""The paper's QP solved exactly by fixed-endpoint Riccati recursions, batched over problems.

min 1/2 sum_{k=1..N} x_k^T Q x_k + 1/2 sum_{k=0..N-1} u_k^T R u_k  s.t.  x_{k+1} = Ad x_k + Bd u_k,  x_N = 0,
|u_k| <= u_max. Box constraints are handled by a primal-dual active-set iteration: inputs in the active set
are fixed at their bound and the rest solved by the recursion; the set changes until the KKT conditions hold
(free inputs inside the box, fixed inputs pushed against their bound by the cost). A convex QP whose KKT
conditions hold is solved: the result is the exact optimum, not an approximation. Problems whose set does not
settle within `max_iter` are reported, for an iterative solver (OSQP) to take over.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class BoxLQRSolution:
    """Solutions of P problems: U (P, N, nu), X (P, N+1, nx); `solved` (P,) marks those whose KKT conditions
    hold; `iterations` (P,) counts active-set iterations; `active` (P, N, nu) is -1/0/+1 for lower/free/upper."""

    U: NDArray[np.float64]
    X: NDArray[np.float64]
    solved: NDArray[np.bool_]
    iterations: NDArray[np.int64]
    active: NDArray[np.int8]


def fixed_input_lqr(Ad: NDArray[np.float64], Bd: NDArray[np.float64], Q: NDArray[np.float64],
                    R: NDArray[np.float64], x0: NDArray[np.float64], fixed: NDArray[np.float64],
                    value: NDArray[np.float64]
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The QP without bounds but with inputs fixed where `fixed` is 1 (u_k,i = value_k,i), for P problems.

    Writing u_k = M_k v_k + c_k (M_k selects the free inputs, c_k holds the fixed values), the cost-to-go with a
    multiplier nu on x_N = 0 is V_k(x) = 1/2 x^T P x + x^T (S nu + p) + 1/2 nu^T W nu + nu^T q, with P_N = 0,
    S_N = I, W_N = 0, p_N = 0, q_N = 0. Backwards, with B~ = B M, G = M R M + B~^T P B~ + (I - M),
    r = B~^T (P B c + p) + M R c: v = -K x - L nu - h, [K, L, h] = G^-1 [B~^T P A, B~^T S, r];
    P <- Q + A^T P (A - B~ K); S <- (A - B~ K)^T S; W <- W - (B~^T S)^T L; p <- A^T (P B c + p) - K^T r;
    q <- q + S^T B c - L^T r. Then nu = -W_0^-1 (S_0^T x0 + q_0) gives x_N = 0.

    Args:
      Ad (P, nx, nx), Bd (P, nx, nu), Q (P, nx, nx), R (P, nu, nu), x0 (P, nx);
      fixed: (P, N, nu), 1 for a fixed input and 0 for a free one; value: (P, N, nu), the fixed values.

    Returns:
      U (P, N, nu); X (P, N+1, nx); and the cost gradient dJ/du_k = R u_k + B^T lambda_{k+1} (P, N, nu),
      lambda_{k+1} = dV_{k+1}/dx the costate: zero on free inputs, the bound's multiplier (sign aside) on fixed.
      A problem whose x_N = 0 is not reachable with its free inputs (W_0 singular) gets NaN throughout.
    """
    n_p, nx, nu = Bd.shape
    steps = fixed.shape[1]
    At = Ad.transpose(0, 2, 1)
    eye = np.eye(nu)
    P = np.zeros((n_p, nx, nx))
    S = np.broadcast_to(np.eye(nx), (n_p, nx, nx)).copy()
    W = np.zeros((n_p, nx, nx))
    p = np.zeros((n_p, nx, 1))
    q = np.zeros((n_p, nx, 1))
    gains = np.empty((steps, n_p, nu, 2 * nx + 1))
    costate = np.empty((steps + 1, n_p, nx, nx + nx + 1))  # [P, S, p] of V_k for k = 1..N
    costate[steps] = np.concatenate([P, S, p], axis=2)
    for k in range(steps - 1, -1, -1):
        free = 1.0 - fixed[:, k]
        Bf = Bd * free[:, None, :]
        Bft = Bf.transpose(0, 2, 1)
        c = (value[:, k] * fixed[:, k])[:, :, None]
        Mr = R * free[:, :, None] * free[:, None, :]
        G = Mr + Bft @ P @ Bf + eye * fixed[:, k][:, None, :]
        BfS = Bft @ S
        Pc_p = P @ (Bd @ c) + p
        r = Bft @ Pc_p + (R @ c) * free[:, :, None]
        gains[k] = np.linalg.solve(G, np.concatenate([Bft @ P @ Ad, BfS, r], axis=2))
        K, L, h = gains[k][:, :, :nx], gains[k][:, :, nx:2 * nx], gains[k][:, :, 2 * nx:]
        closed = Ad - Bf @ K
        q = q + S.transpose(0, 2, 1) @ (Bd @ c) - L.transpose(0, 2, 1) @ r
        W = W - BfS.transpose(0, 2, 1) @ L
        p = At @ Pc_p - K.transpose(0, 2, 1) @ r
        S = closed.transpose(0, 2, 1) @ S
        P = Q + At @ P @ closed
        P = 0.5 * (P + P.transpose(0, 2, 1))
        costate[k] = np.concatenate([P, S, p], axis=2)
    rhs = S.transpose(0, 2, 1) @ x0[:, :, None] + q
    reachable = np.linalg.cond(W) < 1e14
    nu_ = np.full_like(rhs, np.nan)
    nu_[reachable] = -np.linalg.solve(W[reachable], rhs[reachable])
    X = np.empty((n_p, steps + 1, nx))
    U = np.empty((n_p, steps, nu))
    grad = np.empty((n_p, steps, nu))
    X[:, 0] = x0
    for k in range(steps):
        x = X[:, k, :, None]
        K, L, h = gains[k][:, :, :nx], gains[k][:, :, nx:2 * nx], gains[k][:, :, 2 * nx:]
        v = -K @ x - L @ nu_ - h
        U[:, k] = np.where(fixed[:, k] > 0, value[:, k], v[:, :, 0])
        X[:, k + 1] = (Ad @ x + Bd @ U[:, k, :, None])[:, :, 0]
        Pn, Sn, pn = costate[k + 1][:, :, :nx], costate[k + 1][:, :, nx:2 * nx], costate[k + 1][:, :, 2 * nx:]
        lam = Pn @ X[:, k + 1, :, None] + Sn @ nu_ + pn
        grad[:, k] = (R @ U[:, k, :, None] + Bd.transpose(0, 2, 1) @ lam)[:, :, 0]
    return U, X, grad


def box_lqr(Ad: NDArray[np.float64], Bd: NDArray[np.float64], Q: NDArray[np.float64], R: NDArray[np.float64],
            x0: NDArray[np.float64], steps: int, u_max: NDArray[np.float64], *, max_iter: int = 30,
            tol: float = 1e-9) -> BoxLQRSolution:
    """The bounded QP for P problems by primal-dual active sets over `fixed_input_lqr`.

    Start from the unbounded optimum; each iteration fixes at its bound every free input that lies outside the
    box, and frees every fixed input whose cost gradient no longer pushes it against the bound; a problem is
    solved when nothing changes (the KKT conditions hold to `tol`, relative to the bound and to the largest
    gradient). Shapes as in `fixed_input_lqr`; u_max: (P, nu), N m.
    """
    n_p, nx, nu = Bd.shape
    active = np.zeros((n_p, steps, nu), dtype=np.int8)
    U = np.zeros((n_p, steps, nu))
    X = np.zeros((n_p, steps + 1, nx))
    solved = np.zeros(n_p, dtype=bool)
    iterations = np.zeros(n_p, dtype=np.int64)
    bound = u_max[:, None, :]
    todo = np.arange(n_p)
    for _ in range(max_iter + 1):
        if todo.size == 0:
            break
        a = active[todo]
        fixed = (a != 0).astype(np.float64)
        Ut, Xt, grad = fixed_input_lqr(Ad[todo], Bd[todo], Q[todo], R[todo], x0[todo], fixed, a * bound[todo])
        U[todo], X[todo] = Ut, Xt
        iterations[todo] += 1
        b = bound[todo]
        g_tol = tol * np.maximum(1.0, np.abs(grad).max(axis=(1, 2)))[:, None, None]
        above = (a == 0) & (Ut > b * (1 + tol))
        below = (a == 0) & (Ut < -b * (1 + tol))
        release = ((a == 1) & (grad > g_tol)) | ((a == -1) & (grad < -g_tol))
        changed = (above | below | release).any(axis=(1, 2))
        # the free inputs cannot reach x_N = 0 (W_0 singular: NaN), or every input sits on a bound and the end state
        # is missed: left to OSQP, which solves or proves the problem infeasible
        scale = np.maximum(1.0, np.abs(x0[todo]).max(axis=1))
        missed = np.abs(Xt[:, -1]).max(axis=1) > 1e-6 * scale
        failed = ~np.isfinite(Ut).all(axis=(1, 2)) | ~np.isfinite(grad).all(axis=(1, 2)) | missed
        changed &= ~failed
        new = np.where(above, 1, np.where(below, -1, np.where(release, 0, a))).astype(np.int8)
        active[todo] = new
        solved[todo[~changed & ~failed]] = True
        todo = todo[changed]
    U = np.clip(U, -bound, bound)  # a free input within tol of its bound is put on it
    return BoxLQRSolution(U=U, X=X, solved=solved, iterations=iterations, active=active)
