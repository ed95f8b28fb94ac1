"""A planned joint-space reference trajectory, sampled on the control grid."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.exceptions import InvalidInputError


@dataclass(frozen=True)
class Reference:
    """Reference samples at t_k = k dt, k = 0..N.

    Attributes:
      planner: name of the planner that made it.
      t: sample times; shape (N+1,), s, strictly increasing.
      q, qd, qdd: positions (rad), velocities (rad/s), accelerations (rad/s^2); shape (N+1, n) each.
      u_plan: the planner's own corrective torque per period, shape (N, n), N m; None for kinematic planners.
      info: solver facts (status, residuals, solve time, ...), JSON-serialisable.
    """

    planner: str
    t: NDArray[np.float64]
    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    qdd: NDArray[np.float64]
    u_plan: NDArray[np.float64] | None = None
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = np.array(self.t, dtype=np.float64)
        if t.ndim != 1 or t.size < 2 or not (t[1:] > t[:-1]).all():
            raise InvalidInputError(f"t: expected at least two strictly increasing times, got shape {t.shape}")
        arrays = {"t": t}
        for name in ("q", "qd", "qdd"):
            a = np.array(getattr(self, name), dtype=np.float64)
            if a.ndim != 2 or a.shape[0] != t.size:
                raise InvalidInputError(f"{name}: expected shape ({t.size}, n), got {a.shape}")
            arrays[name] = a
        n = arrays["q"].shape[1]
        if arrays["qd"].shape[1] != n or arrays["qdd"].shape[1] != n:
            raise InvalidInputError(f"qd, qdd: expected {n} columns like q, got "
                                    f"{arrays['qd'].shape[1]} and {arrays['qdd'].shape[1]}")
        if self.u_plan is not None:
            u = np.array(self.u_plan, dtype=np.float64)
            if u.shape != (t.size - 1, n):
                raise InvalidInputError(f"u_plan: expected shape ({t.size - 1}, {n}), got {u.shape}")
            arrays["u_plan"] = u
        for name, a in arrays.items():  # own copies (np.array copies), read-only
            if not np.isfinite(a).all():
                raise InvalidInputError(f"{name}: expected finite values in the {self.planner} reference")
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    @property
    def steps(self) -> int:
        """N, the number of control periods."""
        return self.t.size - 1

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.q.shape[1]

    @property
    def dt(self) -> float:
        """Control period, s."""
        return float(self.t[1] - self.t[0])
