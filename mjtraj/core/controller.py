"""The control laws with saturation, each written once and batched over a leading axis: the paper's feedforward + PID
(`control_law`, `PID`) and computed torque (`ComputedTorque`), behind the `Controller` protocol the loop calls."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple, Protocol

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
    state: NDArray[np.float64] | None = None
    """A stateful law's state after this step, (B, state_size) (the adaptive law's estimate), else None."""


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
        return overridden(override, limit, integral + e * dt)
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


def overridden(override: NDArray[np.float64], limit: NDArray[np.float64], integral: NDArray[np.float64]
               ) -> ControlOutput:
    """The output when `override` (B, n), N m, replaces the whole command: saturated, nothing else reported."""
    zero = np.zeros_like(override)
    dtau = np.minimum(np.maximum(override, -limit), limit)
    return ControlOutput(zero, zero, dtau, dtau != override, integral)


class Controller(Protocol):
    """A control law the one closed loop calls once per control period for a batch of B simulations.

    Arrays are (B, n): the measured tracking error e = q_ref - q (rad) and its rate ed (rad/s), the integral
    I_{k-1} (rad s), the planned feedforward tau_ff (N m), the reference acceleration qdd_ref (rad/s^2), and, when
    `needs_dynamics`, the nominal model's D(q) (B, n, n) and h(q, qd) = C(q, qd) qd - passive forces (B, n) at the
    measured state (else None). `limit` is the saturation (B, n), N m. `residual` is added before saturation,
    `override` replaces the command (the env's modes).

    A stateful law (one with a `state_size` attribute > 0 and `initial_state(rows)`) is also given its state
    `state` (B, state_size) and the measured q, qd (B, n) as keywords, and returns its next state in
    `ControlOutput.state`; the loop keeps the state per simulation and resets it when a simulation restarts.
    """

    @property
    def name(self) -> str:
        """How scenario files, the CLI and result rows name the law."""

    @property
    def needs_dynamics(self) -> bool:
        """Whether the law reads D(q) and h(q, qd) at the measured state."""

    def __call__(self, e: NDArray[np.float64], ed: NDArray[np.float64], integral: NDArray[np.float64],
                 tau_ff: NDArray[np.float64], qdd_ref: NDArray[np.float64] | None,
                 dynamics: tuple[NDArray[np.float64], NDArray[np.float64]] | None, limit: NDArray[np.float64],
                 dt: float, *, residual: NDArray[np.float64] | None = None,
                 override: NDArray[np.float64] | None = None) -> ControlOutput: ...


@dataclass(frozen=True)
class PID:
    """The paper's law: planned feedforward + PID (`control_law`), gains of shape (B, n) (PIDGains.tiled)."""

    gains: PIDGains
    anti_windup: str = "none"
    name: ClassVar[str] = "pid"
    needs_dynamics: ClassVar[bool] = False

    def __call__(self, e: NDArray[np.float64], ed: NDArray[np.float64], integral: NDArray[np.float64],
                 tau_ff: NDArray[np.float64], qdd_ref: NDArray[np.float64] | None,
                 dynamics: tuple[NDArray[np.float64], NDArray[np.float64]] | None, limit: NDArray[np.float64],
                 dt: float, *, residual: NDArray[np.float64] | None = None,
                 override: NDArray[np.float64] | None = None) -> ControlOutput:
        return control_law(e, ed, integral, tau_ff, self.gains, limit, dt, anti_windup=self.anti_windup,
                           residual=residual, override=override)


CT_RULE = ("the error dynamics e'' + kd e' + kp e = 0 of every joint get the PID rule's natural frequency "
           "w = 2 pi/(20 dt) with damping ratio 1: kp = w^2, kd = 2 w")


@dataclass(frozen=True)
class ComputedTorque:
    """Computed torque on the nominal model: dtau = clip(D(q) (qdd_ref + kp e + kd ed) + h(q, qd), +-limit), with q,
    qd the measured state (gravity is compensated natively, as for PID). Reported split: tau_ff = D qdd_ref + h,
    tau_fb = D (kp e + kd ed). No integral (it stays I_{-1} = 0).

    Attributes:
      kp: 1/s^2, kd: 1/s, shape (n,) or (B, n): the error dynamics' gains (see CT_RULE and `for_period`).
    """

    kp: NDArray[np.float64]
    kd: NDArray[np.float64]
    name: ClassVar[str] = "computed_torque"
    needs_dynamics: ClassVar[bool] = True

    @classmethod
    def for_period(cls, dt: float, n: int) -> ComputedTorque:
        """The gains of CT_RULE for control period dt (s) on n joints."""
        w = 2.0 * np.pi / (20.0 * dt)
        return cls(frozen(np.full(n, w * w)), frozen(np.full(n, 2.0 * w)))

    def __call__(self, e: NDArray[np.float64], ed: NDArray[np.float64], integral: NDArray[np.float64],
                 tau_ff: NDArray[np.float64], qdd_ref: NDArray[np.float64] | None,
                 dynamics: tuple[NDArray[np.float64], NDArray[np.float64]] | None, limit: NDArray[np.float64],
                 dt: float, *, residual: NDArray[np.float64] | None = None,
                 override: NDArray[np.float64] | None = None) -> ControlOutput:
        if override is not None:
            return overridden(override, limit, integral)
        assert qdd_ref is not None and dynamics is not None
        D, h = dynamics
        ff = np.einsum("bij,bj->bi", D, qdd_ref) + h
        fb = np.einsum("bij,bj->bi", D, self.kp * e + self.kd * ed)
        command = ff + fb if residual is None else ff + fb + residual
        dtau = np.minimum(np.maximum(command, -limit), limit)
        return ControlOutput(ff, fb, dtau, dtau != command, integral)
