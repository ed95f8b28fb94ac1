"""One period of `mpc`'s Kalman filter (`mjtraj.core.estimator`) for one simulation, compiled: the fast path of
`mjtraj.core.mpc.PredictiveFilter`, which a deployed policy runs every period beside its network.

The equations are the filter's (its module docstring): the correction by the measurement in Joseph form, then the
one-step prediction under the linearisation's torque and the covariance's propagation. NumPy's calls on these 9 x 9
matrices cost about 0.25 ms a period at batch 1, as much as the policy's inference; compiled they cost microseconds.
The NumPy path stays the reference (it is `mpc`'s own): a test holds this one's estimate to `mpc`'s within 1e-9.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.core.planners.numba_cache import njit


def filter_periods(state: NDArray[np.float64], measured: NDArray[np.float64], X0: NDArray[np.float64],
                   X1: NDArray[np.float64], A: NDArray[np.float64], B: NDArray[np.float64], c: NDArray[np.float64],
                   V: NDArray[np.float64], initial: NDArray[np.float64], process: NDArray[np.float64]
                   ) -> NDArray[np.float64]:
    """The filter's state (B, 1 + 5n + (3n)^2: `ModelPredictive.state_size`'s layout without parameters) after one
    period of each simulation, from its state before, the measurement [q; qd] (B, 2n), the linearisation at the
    period (its states X0 and X1 (B, 2n) at k and k + 1, A (B, 2n, 2n), B (B, 2n, n), c (B, 2n)), V's diagonal
    (B, 2n), the covariance before any measurement (B, 3n, 3n: used where the state holds no prediction yet) and W's
    diagonal (3n,). The prediction is the model's under the linearisation's own torque (what `PredictiveFilter`
    commands)."""
    out = np.empty_like(state)
    _periods(np.ascontiguousarray(state), np.ascontiguousarray(measured), np.ascontiguousarray(X0),
             np.ascontiguousarray(X1), np.ascontiguousarray(A), np.ascontiguousarray(B), np.ascontiguousarray(c),
             np.ascontiguousarray(V), np.ascontiguousarray(initial), np.ascontiguousarray(process), out)
    return out


@njit
def _periods(state: Any, measured: Any, X0: Any, X1: Any, A: Any, B: Any, c: Any, V: Any, initial: Any,
             process: Any, out: Any) -> None:  # pragma: no cover (compiled)
    """`filter_periods`, row by row; fills out."""
    rows, n2 = measured.shape
    n = n2 // 2
    m = 3 * n
    for b in range(rows):
        expected = state[b, 1:1 + n2]
        fresh = np.any(np.isnan(expected))
        z = np.empty(m)
        if fresh:
            z[:n2] = measured[b]
            z[n2:] = 0.0
            P = initial[b].copy()
        else:
            z[:n2] = expected
            z[n2:] = state[b, 1 + 4 * n:1 + 5 * n]
            P = state[b, 1 + 5 * n:].reshape(m, m).copy()
        S = P[:n2, :n2].copy()
        for i in range(n2):
            S[i, i] += V[b, i]
        K = np.linalg.solve(S, np.ascontiguousarray(P[:n2, :])).T.copy()  # P H^T S^-1, (m, 2n)
        innovation = measured[b] - z[:n2]
        z = z + K @ innovation
        I_KH = np.eye(m)
        I_KH[:, :n2] -= K
        KV = K * V[b]
        P = I_KH @ P @ I_KH.T + KV @ K.T
        x, d = z[:n2], z[n2:]
        predicted = X1[b] + A[b] @ (x - X0[b]) + c[b] + B[b] @ d
        F = np.eye(m)
        F[:n2, :n2] = A[b]
        F[:n2, n2:] = B[b]
        P = F @ P @ F.T
        for i in range(m):
            P[i, i] += process[i]
        out[b, 0] = state[b, 0] + 1.0
        out[b, 1:1 + n2] = predicted
        out[b, 1 + n2:1 + 2 * n2] = 0.0
        out[b, 1 + 4 * n:1 + 5 * n] = d
        out[b, 1 + 5 * n:] = P.ravel()
