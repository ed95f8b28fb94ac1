"""The score of an execution, J_exec, and the rule that sets its weights: defined here and nowhere else.

J_exec = sum_k (x_k^T Q_exec x_k + dtau_k^T R_exec dtau_k) over the control periods k = 0..N-1, x_k = [e_k; ed_k],
with diagonal weights. The weights belong to the scenario, never to a planner: retuning a planner's own weights
does not change how it is scored. The default rule is Bryson's, applied to each task.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.checks import frozen, vector
from mjtraj.core.task import Task
from mjtraj.exceptions import InvalidInputError

JOINT_SPEED_LIMIT = np.pi
"""UR5 joint speed limit, rad/s (180 deg/s on every joint): the velocity scale of Bryson's rule."""


def bryson_weights(task: Task, torque_limit: npt.ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Bryson's rule: each weight is 1 / (largest acceptable value)^2 of its variable.

    Scales: position deviation max_i |dq_i| (the move itself; 1 rad if there is no move), velocity the joint speed
    limit pi rad/s, torque the corrective saturation `torque_limit` (N m, shape (n,)). Returns diag(Q), shape (2n,),
    and diag(R), shape (n,).
    """
    move = float(np.max(np.abs(task.displacement))) or 1.0
    n = task.n
    q_diag = np.concatenate([np.full(n, 1.0 / move**2), np.full(n, 1.0 / JOINT_SPEED_LIMIT**2)])
    return q_diag, 1.0 / np.asarray(torque_limit, dtype=np.float64) ** 2


@dataclass(frozen=True)
class Scoring:
    """How executions are scored: Bryson's rule on each task (both weights None), or fixed diagonal weights.

    Attributes:
      Q_exec: diag(Q_exec), shape (2n,), >= 0; None for Bryson's rule.
      R_exec: diag(R_exec), shape (n,), >= 0; None for Bryson's rule.
    """

    Q_exec: NDArray[np.float64] | None = None
    R_exec: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        if (self.Q_exec is None) != (self.R_exec is None):
            raise InvalidInputError("Q_exec, R_exec: give both fixed weights, or neither for Bryson's rule")
        for name in ("Q_exec", "R_exec"):
            value = getattr(self, name)
            if value is not None:
                array = frozen(np.array(value, dtype=np.float64))
                if array.ndim != 1 or not np.all(np.isfinite(array)) or np.any(array < 0):
                    raise InvalidInputError(f"{name}: expected finite weights >= 0 (a diagonal), got "
                                            f"{np.asarray(value).tolist()}")
                object.__setattr__(self, name, array)

    @classmethod
    def fixed(cls, Q_exec: npt.ArrayLike, R_exec: npt.ArrayLike, n: int) -> Scoring:
        """Fixed diagonal weights for an arm of n joints: Q_exec (2n,), R_exec (n,)."""
        return cls(vector("Q_exec", Q_exec, 2 * n), vector("R_exec", R_exec, n))

    @property
    def rule(self) -> str:
        """'bryson' or 'fixed'."""
        return "bryson" if self.Q_exec is None else "fixed"

    def weights(self, task: Task, torque_limit: npt.ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """diag(Q_exec) (2n,) and diag(R_exec) (n,) that score an execution of `task`."""
        if self.Q_exec is None or self.R_exec is None:
            return bryson_weights(task, torque_limit)
        if self.Q_exec.size != 2 * task.n or self.R_exec.size != task.n:
            raise InvalidInputError(f"Q_exec, R_exec: expected {2 * task.n} and {task.n} weights for a task of "
                                    f"{task.n} joints, got {self.Q_exec.size} and {self.R_exec.size}")
        return self.Q_exec, self.R_exec

    def as_dict(self) -> dict[str, object]:
        """As the scenario file's [cost] section."""
        if self.Q_exec is None or self.R_exec is None:
            return {"rule": "bryson"}
        return {"Q_exec": self.Q_exec.tolist(), "R_exec": self.R_exec.tolist()}


def step_cost(e: NDArray[np.float64], ed: NDArray[np.float64], dtau: NDArray[np.float64],
              q_diag: NDArray[np.float64], r_diag: NDArray[np.float64]
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The two terms of one period's cost, x^T Q_exec x and dtau^T R_exec dtau, for arrays (..., n) with diagonal
    weights (..., 2n) and (..., n); shapes (...,) each. (The env's reward is minus their sum.)"""
    x = np.concatenate([e, ed], axis=-1)
    return (x * x * q_diag).sum(axis=-1), (dtau * dtau * r_diag).sum(axis=-1)


def executed_cost(e: NDArray[np.float64], ed: NDArray[np.float64], dtau: NDArray[np.float64],
                  q_diag: npt.ArrayLike, r_diag: npt.ArrayLike) -> NDArray[np.float64]:
    """J_exec of B executions: e, ed, dtau of shape (B, N, n); diagonal weights (2n,) and (n,) shared by all, or
    (B, 2n) and (B, n), one pair each. Returns shape (B,)."""
    q = np.asarray(q_diag, dtype=np.float64)
    r = np.asarray(r_diag, dtype=np.float64)
    x = np.concatenate([e, ed], axis=-1)
    return (np.sum(np.square(x) * q[..., None, :], axis=(-2, -1))
            + np.sum(np.square(dtau) * r[..., None, :], axis=(-2, -1)))
