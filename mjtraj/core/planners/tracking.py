"""Time-varying LQR feedback about a state trajectory, for the nonlinear planners: the tracked start
(`mjtraj.core.planners.nonlinear`) and the SQP's projected line search (`mjtraj.core.planners.sqp`) both roll the
model out under u_k = U_k + K_k (X_ref_k - x_k) (`Shooting.tracked`), so that the motion stays near X_ref where the
open-loop torques U alone would drift away from it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.core.planners.numba_cache import njit

TRACKING_ERROR = (0.01, 0.1)
"""The feedback is LQR with Bryson's weights for these largest tracking errors (rad, rad/s) and the torque bound
(`bryson_gains`). For the projected line search, errors of (0.001, 0.01) and (0.1, 1) were run beside these on
the nonlinear planners' validation tasks (docs/design.md, "The nonlinear planners' settings"): objectives equal to
1e-10 on the first 180 for both, and on all 480 for (0.1, 1), in a mean time 4 % lower. Two runs of the same code
on the 180 differed by 3 %, so the tracked start's errors serve both."""


def tracking_gains(Ad: NDArray[np.float64], Bd: NDArray[np.float64], Q: NDArray[np.float64], R: NDArray[np.float64]
                   ) -> NDArray[np.float64]:
    """Finite-horizon LQR gains K_k (N, n, 2n) of x_{k+1} = Ad_k x_k + Bd_k u_k (Ad (N, 2n, 2n), Bd (N, 2n, n)) for
    sum_{k=1..N} x_k^T Q x_k + sum_{k=0..N-1} u_k^T R u_k, u_k = -K_k x_k: the backward Riccati recursion from P_N = Q,
    K_k = (R + B^T P B)^-1 B^T P A (by Cholesky: R is positive definite), P <- Q + A^T P (A - B K), symmetrised.
    Compiled (`_riccati`): the projected line search computes one set of gains per iteration, and NumPy's calls on
    these 6 x 6 matrices took 1.4 ms of them at N = 100 (0.08 ms compiled)."""
    steps, nx, nu = Bd.shape
    K = np.empty((steps, nu, nx))
    _riccati(np.ascontiguousarray(Ad, dtype=np.float64), np.ascontiguousarray(Bd, dtype=np.float64),
             np.ascontiguousarray(Q, dtype=np.float64), np.ascontiguousarray(R, dtype=np.float64), K)
    return K


@njit
def _riccati(Ad: Any, Bd: Any, Q: Any, R: Any, K: Any) -> None:  # pragma: no cover (compiled)
    """`tracking_gains`' recursion, written out for small matrices; fills K (N, nu, nx)."""
    steps, nx, nu = Bd.shape
    P = Q.copy()
    BP = np.empty((nu, nx))
    L = np.empty((nu, nu))
    rhs = np.empty((nu, nx))
    closed = np.empty((nx, nx))
    PA = np.empty((nx, nx))
    for k in range(steps - 1, -1, -1):
        A, B = Ad[k], Bd[k]
        for i in range(nu):  # BP = B^T P
            for j in range(nx):
                acc = 0.0
                for m in range(nx):
                    acc += B[m, i] * P[m, j]
                BP[i, j] = acc
        for i in range(nu):  # L L^T = R + BP B, rhs = BP A
            for j in range(nu):
                acc = R[i, j]
                for m in range(nx):
                    acc += BP[i, m] * B[m, j]
                L[i, j] = acc
            for j in range(nx):
                acc = 0.0
                for m in range(nx):
                    acc += BP[i, m] * A[m, j]
                rhs[i, j] = acc
        for j in range(nu):  # Cholesky, lower triangle in place
            acc = L[j, j]
            for m in range(j):
                acc -= L[j, m] * L[j, m]
            L[j, j] = np.sqrt(acc)
            for i in range(j + 1, nu):
                acc = L[i, j]
                for m in range(j):
                    acc -= L[i, m] * L[j, m]
                L[i, j] = acc / L[j, j]
        for c in range(nx):  # K[:, c] = L^-T L^-1 rhs[:, c]
            for i in range(nu):
                acc = rhs[i, c]
                for m in range(i):
                    acc -= L[i, m] * K[k, m, c]
                K[k, i, c] = acc / L[i, i]
            for i in range(nu - 1, -1, -1):
                acc = K[k, i, c]
                for m in range(i + 1, nu):
                    acc -= L[m, i] * K[k, m, c]
                K[k, i, c] = acc / L[i, i]
        for i in range(nx):  # closed = A - B K, PA = P closed
            for j in range(nx):
                acc = A[i, j]
                for m in range(nu):
                    acc -= B[i, m] * K[k, m, j]
                closed[i, j] = acc
        for i in range(nx):
            for j in range(nx):
                acc = 0.0
                for m in range(nx):
                    acc += P[i, m] * closed[m, j]
                PA[i, j] = acc
        for i in range(nx):  # P = Q + A^T PA, symmetrised
            for j in range(i, nx):
                upper = Q[i, j]
                lower = Q[j, i]
                for m in range(nx):
                    upper += A[m, i] * PA[m, j]
                    lower += A[m, j] * PA[m, i]
                P[i, j] = P[j, i] = 0.5 * (upper + lower)


def bryson_gains(Ad: NDArray[np.float64], Bd: NDArray[np.float64], u_max: NDArray[np.float64]) -> NDArray[np.float64]:
    """`tracking_gains` (N, n, 2n) with Bryson's weights: Q = diag(TRACKING_ERROR's position error^-2 (n times), its
    speed error^-2 (n times)), R = diag(u_max^-2), u_max (n,) N m."""
    n = Bd.shape[2]
    position, speed = TRACKING_ERROR
    Q = np.diag(np.concatenate([np.full(n, position ** -2.0), np.full(n, speed ** -2.0)]))
    return tracking_gains(Ad, Bd, Q, np.diag(np.asarray(u_max, dtype=np.float64) ** -2.0))
