"""What one closed-loop execution recorded, per scenario and step."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Rollout:
    """Records of B scenarios over N control periods; per-step arrays of shape (B, N, n), read-only.

    q, qd are measured at the start of period k (before control); e = q_ref - q, ed = qd_ref - qd;
    tau_ff, tau_fb, dtau (N m) are the feedforward, PID and applied (saturated) corrective torques;
    saturated marks the joints whose command exceeded the limit. q_final, qd_final (B, n) are the state after
    period N-1; e_final = q_ref,N - q_final. A scenario that diverged (non-finite state, or |e| above the
    bound) is frozen at `diverged_step` (-1 if it did not) and its later records are NaN.
    """

    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    e: NDArray[np.float64]
    ed: NDArray[np.float64]
    tau_ff: NDArray[np.float64]
    tau_fb: NDArray[np.float64]
    dtau: NDArray[np.float64]
    saturated: NDArray[np.bool_]
    q_final: NDArray[np.float64]
    qd_final: NDArray[np.float64]
    e_final: NDArray[np.float64]
    diverged_step: NDArray[np.int64]
    dt: float

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if isinstance(value, np.ndarray):
                value.setflags(write=False)

    @property
    def diverged(self) -> NDArray[np.bool_]:
        """Shape (B,)."""
        return self.diverged_step >= 0

    def scenario(self, b: int) -> Rollout:
        """The records of scenario b alone, as a batch of one."""
        pick = slice(b, b + 1)
        fields: dict[str, Any] = {name: getattr(self, name)[pick] if name != "dt" else self.dt
                                  for name in self.__dataclass_fields__}
        return Rollout(**fields)
