"""Execution metrics (docs/design.md, "Metrics"): pure functions over arrays of shape (..., N, n); J_exec comes
from `mjtraj.core.scoring`."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.core.rollout import Rollout
from mjtraj.core.scoring import executed_cost
from mjtraj.exceptions import InvalidInputError

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

    @classmethod
    def nan(cls) -> Metrics:
        """The metrics of an execution that did not complete: NaN everywhere."""
        return cls(**{name: float("nan") for name in METRIC_NAMES})


def _diagonal(name: str, weight: npt.ArrayLike) -> NDArray[np.float64]:
    """A diagonal weight as given ((m,) or (B, m)), or the diagonal of a diagonal matrix (m, m)."""
    w = np.asarray(weight, dtype=np.float64)
    if w.ndim == 2 and w.shape[0] == w.shape[1] and w.shape[0] > 1 and np.array_equal(w, np.diag(np.diag(w))):
        return np.diag(w).copy()
    if w.ndim not in (1, 2):
        raise InvalidInputError(f"{name}: expected a diagonal weight, shape (m,) or one per execution (B, m), got "
                                f"shape {w.shape}")
    return w


def metrics_arrays(rollout: Rollout, Q_exec: npt.ArrayLike, R_exec: npt.ArrayLike) -> dict[str, NDArray[np.float64]]:
    """Every metric for every execution of `rollout`: name -> shape (B,).

    Q_exec and R_exec are the diagonals of J_exec's weights (`mjtraj.core.scoring`), shapes (2n,) and (n,) shared
    by every execution or (B, 2n) and (B, n), one pair each (a diagonal matrix is also accepted).
    """
    e, dtau = rollout.e, rollout.dtau
    cost = executed_cost(e, rollout.ed, dtau, _diagonal("Q_exec", Q_exec), _diagonal("R_exec", R_exec))
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
