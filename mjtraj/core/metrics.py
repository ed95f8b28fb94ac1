"""Execution metrics (docs/design.md, "Metrics"): pure functions over arrays of shape (..., N, n); J_exec comes
from `mjtraj.core.scoring`."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.core.dynamics import DynamicsProbe
from mjtraj.core.rollout import Rollout
from mjtraj.core.scoring import executed_cost
from mjtraj.exceptions import InvalidInputError

METRIC_NAMES = ("rms_err", "rms_dtau", "int_dtau", "cost", "rms_fb", "peak_dtau", "saturated_frac", "max_err",
                "terminal_err", "rms_dtau_norm", "rms_tau_total")
METRIC_UNITS = {"rms_err": "rad", "rms_dtau": "N m", "int_dtau": "N m s", "cost": "-", "rms_fb": "N m",
                "peak_dtau": "N m", "saturated_frac": "-", "max_err": "rad", "terminal_err": "rad",
                "rms_dtau_norm": "N m", "rms_tau_total": "N m"}
"""rms_dtau is over every joint and step; rms_dtau_norm is the RMS over steps of the torque vector's norm,
sqrt(1/N sum_k |dtau_k|^2) = sqrt(n) rms_dtau; rms_tau_total is rms_dtau's definition applied to the total torque
G(q_k) + dtau_k (gravity compensation included, G of the nominal model at the measured pose). rms_tau_total costs a
G(q) per recorded pose: compare and frontier measure it; sweeps and the env leave it NaN."""


GOAL_TOLERANCE = 0.2
"""The goal rule, on every family: an execution whose terminal error |q_ref,N - q_N| exceeds this fraction of its
task's largest joint displacement missed its goal (a failure, whatever its J_exec: an optimiser of J_exec, which does
not score x_N, would otherwise stop short). On the UR5's 2 x 7,000 nominal executions of seeds 0 and 1 (every
planner and variant) the largest fraction is 0.073."""


def missed_goal(terminal_err: npt.ArrayLike, displacement: npt.ArrayLike) -> NDArray[np.bool_]:
    """Whether executions with terminal error `terminal_err` (rad) missed a goal `displacement` away (the task's
    largest joint displacement, rad): GOAL_TOLERANCE. False for NaN (a diverged execution fails on its own)."""
    return np.asarray(terminal_err) > GOAL_TOLERANCE * np.asarray(displacement)  # type: ignore[no-any-return]


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
    rms_dtau_norm: float
    rms_tau_total: float

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


def metrics_arrays(rollout: Rollout, Q_exec: npt.ArrayLike, R_exec: npt.ArrayLike, *,
                   gravity: NDArray[np.float64] | None = None) -> dict[str, NDArray[np.float64]]:
    """Every metric for every execution of `rollout`: name -> shape (B,).

    Q_exec and R_exec are the diagonals of J_exec's weights (`mjtraj.core.scoring`), shapes (2n,) and (n,) shared
    by every execution or (B, 2n) and (B, n), one pair each (a diagonal matrix is also accepted). `gravity` is
    G(q_k) at the recorded poses, shape (B, N, n), N m (`gravity_along`); without it rms_tau_total is NaN.
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
        "rms_dtau_norm": np.sqrt(np.mean(np.sum(np.square(dtau), axis=-1), axis=-1)),
        "rms_tau_total": rms(gravity + dtau) if gravity is not None else np.full(e.shape[0], np.nan),
    }


def gravity_along(model: mujoco.MjModel, rollout: Rollout) -> NDArray[np.float64]:
    """G(q_k) of `model` at every recorded pose of `rollout`, shape (B, N, n), N m (NaN where nothing was
    recorded)."""
    q = rollout.q.reshape(-1, rollout.q.shape[-1])
    seen = np.all(np.isfinite(q), axis=1)
    out = np.full(q.shape, np.nan)
    if seen.any():
        out[seen] = DynamicsProbe(model, size=int(seen.sum())).gravity(q[seen])
    return out.reshape(rollout.q.shape)


def metrics(rollout: Rollout, Q_exec: npt.ArrayLike, R_exec: npt.ArrayLike, *,
            model: mujoco.MjModel | None = None) -> list[Metrics]:
    """One Metrics per scenario of `rollout` (NaN for a diverged one); with the nominal `model`, rms_tau_total too."""
    arrays = metrics_arrays(rollout, Q_exec, R_exec, gravity=None if model is None else gravity_along(model, rollout))
    out = []
    for b in range(rollout.diverged_step.size):
        values = {name: float("nan") if rollout.diverged[b] else float(arrays[name][b]) for name in METRIC_NAMES}
        out.append(Metrics(**values))
    return out
