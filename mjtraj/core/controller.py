"""The feedforward + PID control law with saturation: written once, batched over a leading axis."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.checks import frozen, vector

ANTI_WINDUP = ("none", "clamp")


@dataclass(frozen=True)
class PIDGains:
    """Diagonal PID gains; shape (n,) each. kp in N m/rad, ki in N m/(rad s), kd in N m s/rad."""

    kp: NDArray[np.float64]
    ki: NDArray[np.float64]
    kd: NDArray[np.float64]

    @classmethod
    def create(cls, kp: npt.ArrayLike, ki: npt.ArrayLike, kd: npt.ArrayLike, n: int) -> PIDGains:
        """Validate (finite, >= 0, length n) and freeze."""
        arrays = {name: vector(name, value, n) for name, value in (("kp", kp), ("ki", ki), ("kd", kd))}
        for name, a in arrays.items():
            if np.any(a < 0):
                from mjtraj.exceptions import InvalidInputError
                raise InvalidInputError(f"{name}: expected non-negative gains, got {a.tolist()}")
        return cls(**{name: frozen(a) for name, a in arrays.items()})

    def tiled(self, rows: int) -> PIDGains:
        """The same gains repeated for `rows` simulations, shape (rows, n) each: arithmetic with (rows, n)
        arrays then runs without broadcasting (the single-scenario loop is dominated by such overheads)."""
        return PIDGains(*(frozen(np.tile(a, (rows, 1))) for a in (self.kp, self.ki, self.kd)))


class ControlOutput(NamedTuple):
    """One control step for a batch; arrays of shape (B, n). (A NamedTuple: it is built every control period.)"""

    tau_ff: NDArray[np.float64]
    """Feedforward part, N m."""
    tau_fb: NDArray[np.float64]
    """PID part, N m."""
    dtau: NDArray[np.float64]
    """Applied corrective torque after saturation, N m."""
    saturated: NDArray[np.bool_]
    """Whether the command exceeded the limit on that joint."""
    integral: NDArray[np.float64]
    """Error integral I_k after this step, rad s."""


def control_law(e: NDArray[np.float64], ed: NDArray[np.float64], integral: NDArray[np.float64],
                tau_ff: NDArray[np.float64], gains: PIDGains, limit: NDArray[np.float64], dt: float, *,
                anti_windup: str = "none", residual: NDArray[np.float64] | None = None,
                override: NDArray[np.float64] | None = None) -> ControlOutput:
    """The corrective torque (docs/design.md, "Controller") for a batch; arrays (B, n) except `limit` (n,).

    I_k = I_{k-1} + e_k dt;  tau_fb = Kp e + Ki I_k + Kd ed;  dtau = clip(tau_ff + tau_fb [+ residual], +-limit).
    The arguments are validated where they are configured (LoopConfig), not here in the loop.
    With anti_windup 'clamp' the integral is frozen (I_k = I_{k-1}) on the joints whose command saturates.
    `override` replaces the whole command (the env's torque mode): feedforward and PID are then reported as 0.

    Args:
      e, ed: tracking error q_ref - q (rad) and its rate (rad/s). integral: I_{k-1}, rad s.
      tau_ff: feedforward, N m. limit: saturation per joint, N m, shape (n,) or (B, n). dt: control period, s.
      gains: arrays of shape (n,) or (B, n) (see PIDGains.tiled).
      residual: extra torque added before saturation (the env's residual mode), N m.
    """
    if override is not None:
        zero = np.zeros_like(override)
        dtau = np.minimum(np.maximum(override, -limit), limit)
        return ControlOutput(zero, zero, dtau, dtau != override, integral + e * dt)
    new_integral = integral + e * dt
    tau_fb = gains.kp * e + gains.ki * new_integral + gains.kd * ed
    command = tau_ff + tau_fb if residual is None else tau_ff + tau_fb + residual
    dtau = np.minimum(np.maximum(command, -limit), limit)
    saturated = dtau != command
    if anti_windup == "clamp" and saturated.any():
        new_integral = np.where(saturated, integral, new_integral)
        tau_fb = gains.kp * e + gains.ki * new_integral + gains.kd * ed
        command = tau_ff + tau_fb if residual is None else tau_ff + tau_fb + residual
        dtau = np.minimum(np.maximum(command, -limit), limit)
    return ControlOutput(tau_ff, tau_fb, dtau, saturated, new_integral)
