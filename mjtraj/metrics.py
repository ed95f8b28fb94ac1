"""Execution metrics of DESIGN §5: pure functions over arrays of shape (..., N, n)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.rollout import Rollout

METRIC_NAMES = ("rms_err", "rms_dtau", "int_dtau", "cost", "rms_fb", "peak_dtau", "saturated_frac", "max_err",
                "terminal_err")
METRIC_UNITS = {"rms_err": "rad", "rms_dtau": "N m", "int_dtau": "N m s", "cost": "-", "rms_fb": "N m",
                "peak_dtau": "N m", "saturated_frac": "-", "max_err": "rad", "terminal_err": "rad"}


def rms(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """sqrt(1/(N n) sum_k sum_i x_ki^2) over the last two axes."""
    return np.sqrt(np.mean(np.square(x), axis=(-2, -1)))


def integral_abs(x: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    """sum_k sum_i |x_ki| dt over the last two axes (the paper's J_dtau, rectangle rule on the ZOH torque)."""
    return np.sum(np.abs(x), axis=(-2, -1)) * dt


def quadratic_cost(e: NDArray[np.float64], ed: NDArray[np.float64], dtau: NDArray[np.float64],
                   Q_exec: NDArray[np.float64], R_exec: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per-step x_k^T Q_exec x_k + dtau_k^T R_exec dtau_k with x_k = [e_k; ed_k]; shape (..., N)."""
    x = np.concatenate([e, ed], axis=-1)
    return np.einsum("...i,ij,...j->...", x, Q_exec, x) + np.einsum("...i,ij,...j->...", dtau, R_exec, dtau)


def executed_cost(e: NDArray[np.float64], ed: NDArray[np.float64], dtau: NDArray[np.float64],
                  Q_exec: NDArray[np.float64], R_exec: NDArray[np.float64]) -> NDArray[np.float64]:
    """J_exec = sum_k (x_k^T Q_exec x_k + dtau_k^T R_exec dtau_k) over k = 0..N-1."""
    return np.sum(quadratic_cost(e, ed, dtau, Q_exec, R_exec), axis=-1)


def reduction(planner: npt.ArrayLike, optimal: npt.ArrayLike) -> NDArray[np.float64]:
    """The paper's reduction column, 100 (M_planner - M_optimal) / M_planner, in %."""
    m = np.asarray(planner, dtype=np.float64)
    return 100.0 * (m - np.asarray(optimal, dtype=np.float64)) / m


@dataclass(frozen=True)
class Metrics:
    """Metrics of one execution; see METRIC_UNITS. NaN everywhere for a diverged execution."""

    rms_err: float
    rms_dtau: float
    int_dtau: float
    cost: float
    rms_fb: float
    peak_dtau: float
    saturated_frac: float
    max_err: float
    terminal_err: float

    def as_dict(self) -> dict[str, float]:
        """Field name -> value."""
        return asdict(self)


def _matrix(weight: npt.ArrayLike) -> NDArray[np.float64]:
    w = np.asarray(weight, dtype=np.float64)
    return np.diag(w) if w.ndim == 1 else w


def metrics_arrays(rollout: Rollout, Q_exec: npt.ArrayLike, R_exec: npt.ArrayLike, *, per_scenario: bool = False
                   ) -> dict[str, NDArray[np.float64]]:
    """Every metric for every scenario of `rollout`: name -> shape (B,).

    Q_exec (2n, 2n) and R_exec (n, n) may also be given as their diagonals, shapes (2n,) and (n,); with
    `per_scenario`, they are diagonals of shapes (B, 2n) and (B, n), one per scenario.
    """
    e, dtau = rollout.e, rollout.dtau
    if per_scenario:
        q_diag, r_diag = np.asarray(Q_exec, dtype=np.float64), np.asarray(R_exec, dtype=np.float64)
        x = np.concatenate([e, rollout.ed], axis=-1)
        cost = np.sum(np.square(x) * q_diag[:, None, :], axis=(-2, -1)) + \
            np.sum(np.square(dtau) * r_diag[:, None, :], axis=(-2, -1))
    else:
        cost = executed_cost(e, rollout.ed, dtau, _matrix(Q_exec), _matrix(R_exec))
    return {
        "rms_err": rms(e),
        "rms_dtau": rms(dtau),
        "int_dtau": integral_abs(dtau, rollout.dt),
        "cost": cost,
        "rms_fb": rms(rollout.tau_fb),
        "peak_dtau": np.max(np.abs(dtau), axis=(-2, -1)),
        "saturated_frac": np.mean(rollout.saturated, axis=(-2, -1)).astype(np.float64),
        "max_err": np.max(np.abs(e), axis=(-2, -1)),
        "terminal_err": np.linalg.norm(rollout.e_final, axis=-1),
    }


def metrics(rollout: Rollout, Q_exec: npt.ArrayLike, R_exec: npt.ArrayLike) -> list[Metrics]:
    """One Metrics per scenario of `rollout` (NaN for a diverged one)."""
    arrays = metrics_arrays(rollout, Q_exec, R_exec)
    out = []
    for b in range(rollout.diverged_step.size):
        values = {name: float("nan") if rollout.diverged[b] else float(arrays[name][b]) for name in METRIC_NAMES}
        out.append(Metrics(**values))
    return out
