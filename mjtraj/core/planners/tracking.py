"""Time-varying LQR feedback about a state trajectory, for the nonlinear planners: the tracked start
(`mjtraj.core.planners.nonlinear`) and the SQP's projected line search (`mjtraj.core.planners.sqp`) both roll the
model out under u_k = U_k + K_k (X_ref_k - x_k) (`Shooting.tracked`), so that the motion stays near X_ref where the
open-loop torques U alone would drift away from it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

TRACKING_ERROR = (0.01, 0.1)
"""The feedback is LQR with Bryson's weights for these largest tracking errors (rad, rad/s) and the torque bound
(`bryson_gains`). For the projected line search, errors of (0.001, 0.01) and (0.1, 1) were run beside these on
the validation tasks of `mjtraj.core.planners.nonlinear.SQP_MAX_ITER`: objectives equal to 1e-10 on the first 180
for both, and on all 480 for (0.1, 1), in a mean time 4 % lower. Two runs of the same code on the 180 differed by
3 %, so the tracked start's errors serve both."""


def tracking_gains(Ad: NDArray[np.float64], Bd: NDArray[np.float64], Q: NDArray[np.float64], R: NDArray[np.float64]
                   ) -> NDArray[np.float64]:
    """Finite-horizon LQR gains K_k (N, n, 2n) of x_{k+1} = Ad_k x_k + Bd_k u_k (Ad (N, 2n, 2n), Bd (N, 2n, n)) for
    sum_{k=1..N} x_k^T Q x_k + sum_{k=0..N-1} u_k^T R u_k, u_k = -K_k x_k: the backward Riccati recursion from P_N = Q.
    """
    steps, nx, nu = Bd.shape
    K = np.empty((steps, nu, nx))
    P = Q
    for k in range(steps - 1, -1, -1):
        BP = Bd[k].T @ P
        K[k] = np.linalg.solve(R + BP @ Bd[k], BP @ Ad[k])
        P = Q + Ad[k].T @ P @ (Ad[k] - Bd[k] @ K[k])
        P = 0.5 * (P + P.T)
    return K


def bryson_gains(Ad: NDArray[np.float64], Bd: NDArray[np.float64], u_max: NDArray[np.float64]) -> NDArray[np.float64]:
    """`tracking_gains` (N, n, 2n) with Bryson's weights: Q = diag(TRACKING_ERROR's position error^-2 (n times), its
    speed error^-2 (n times)), R = diag(u_max^-2), u_max (n,) N m."""
    n = Bd.shape[2]
    position, speed = TRACKING_ERROR
    Q = np.diag(np.concatenate([np.full(n, position ** -2.0), np.full(n, speed ** -2.0)]))
    return tracking_gains(Ad, Bd, Q, np.diag(np.asarray(u_max, dtype=np.float64) ** -2.0))
