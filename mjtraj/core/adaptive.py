"""Adaptive computed torque (Slotine and Li, 1987): computed torque on the nominal model plus an online estimate of
what the nominal model leaves out, a payload at the flange, viscous damping and dry friction per joint.

With e = q_ref - q, the reference velocity qd_r = qd_ref + lam e, its rate qdd_r = qdd_ref + lam ed and the sliding
variable sigma = qd_r - qd = ed + lam e, the law is

    tau = D(q) qdd_r + C(q, qd) qd_r + G(q) - G_c(q) - P(qd) + D(q) k sigma + Y theta_hat,
    theta_hat' = Gamma Y^T sigma, projected onto [0, theta_max],

on the nominal model (D, C the Christoffel Coriolis matrix, G - G_c the gravity the plant does not compensate, P
its passive forces), with theta = [payload kg, damping_i N m s/rad, friction_i N m] and its regressor (n, 1 + 2n)

    Y = [ D_1(q) qdd_r + C_1(q, qd) qd_r + G_1(q) | diag(qd) | diag(tanh(qd / FRICTION_SPEED)) ],

where the index 1 marks the terms of a 1 kg point mass at the flange (`with_point_mass` minus the nominal model).
C(q, a) b is symmetric in a and b for the Christoffel C, so C(q, qd) qd_r = (c(qd + qd_r) - c(qd - qd_r)) / 4 with
c(v) = MuJoCo's qfrc_bias at (q, v): MuJoCo's own recursive Newton-Euler, no hand-written dynamics. Then D - 2C is
skew and V = sigma^T D sigma / 2 + theta_err^T Gamma^-1 theta_err / 2 does not grow (the Lyapunov argument of
Slotine and Li): tracking converges and, under persistent excitation, so does the estimate. The link inertia errors
of the mismatch family are not in the regressor; projection keeps the estimate bounded under them.

With theta_hat = 0 and lam = k = w the law is computed torque with kp = w^2, kd = 2 w (CT_RULE) but for the
Coriolis term's qd_r: both put the error dynamics' double pole at -w.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.core.controller import ControlOutput, overridden
from mjtraj.core.dynamics import DynamicsProbe
from mjtraj.core.model import JointInfo
from mjtraj.core.payload import with_point_mass

FRICTION_SPEED = 0.02
"""rad/s: the dry-friction regressor tanh(qd / FRICTION_SPEED) is a smooth sign (95 % at 0.04 rad/s)."""
ADAPTATION_RATE = 0.0155
"""gamma, 1/(N m rad): Gamma = gamma diag(theta_max^2). Chosen on the mismatch family's training stream, never on
evaluation scenarios: `mjtraj tune --gains --config paper_adaptive.toml --family mismatch --scenarios 50 --seed 0
--budget 32` printed adaptation_rate = 0.0155 (docs/control.md)."""
BOUND_RULE = ("the estimate is projected onto [0, theta_max]: a payload up to the arm's moving mass (an arm rarely "
              "carries more than itself), viscous damping up to 0.1 s/rad x the joint's torque limit, dry friction up "
              "to 0.2 x the torque limit; Gamma = gamma diag(theta_max^2), so every parameter adapts at the same rate "
              "in units of its bound")
GAIN_RULE = ("lam = k = w = 2 pi/(20 dt), computed torque's natural frequency (CT_RULE): the error dynamics' double "
             "pole at -w")


def parameter_bounds(model: mujoco.MjModel) -> NDArray[np.float64]:
    """BOUND_RULE's theta_max of `model`, shape (1 + 2n,): payload kg, damping N m s/rad, friction N m."""
    limit = JointInfo.of(model).torque_limit
    moving = float(np.sum(model.body_mass[1:]))
    return np.concatenate([[moving], 0.1 * limit, 0.2 * limit])


@dataclass
class AdaptiveComputedTorque:
    """The module's law for `nsim` simulations of `model` (the nominal one) at control period `dt` (s).

    Its per-simulation state is the estimate theta_hat, shape (nsim, 1 + 2n), starting at 0 (the nominal model);
    the loop keeps it (`state_size`, `initial_state`) and passes it with the measured q, qd.
    """

    model: mujoco.MjModel
    dt: float
    nsim: int
    rate: float = ADAPTATION_RATE
    name: ClassVar[str] = "adaptive_computed_torque"
    needs_dynamics: ClassVar[bool] = False
    bounds: NDArray[np.float64] = field(init=False)
    """theta_max, shape (1 + 2n,)."""
    _gain: NDArray[np.float64] = field(init=False, repr=False)
    _nominal: DynamicsProbe = field(init=False, repr=False)
    _loaded: DynamicsProbe = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.w = 2.0 * np.pi / (20.0 * self.dt)
        self.bounds = parameter_bounds(self.model)
        self._gain = self.rate * self.bounds**2
        self._nominal = DynamicsProbe(self.model, size=3 * self.nsim)
        self._loaded = DynamicsProbe(with_point_mass(self.model, 1.0), size=3 * self.nsim)

    @property
    def state_size(self) -> int:
        """1 + 2n: payload, damping per joint, friction per joint."""
        return 1 + 2 * self.model.nv

    def initial_state(self, rows: int) -> NDArray[np.float64]:
        """theta_hat = 0 for `rows` simulations, shape (rows, 1 + 2n)."""
        return np.zeros((rows, self.state_size))

    def regressor(self, q: NDArray[np.float64], qd: NDArray[np.float64], qd_r: NDArray[np.float64],
                  qdd_r: NDArray[np.float64]
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The nominal model's torque D qdd_r + C(q, qd) qd_r + G - G_c - P(qd) (B, n), N m, its D(q) (B, n, n) and
        the regressor Y (B, n, 1 + 2n); arguments (B, n)."""
        B, n = q.shape
        q3 = np.concatenate([q, q, q])
        v3 = np.concatenate([qd + qd_r, qd - qd_r, np.zeros_like(qd)])
        D0, bias0, passive0, gravcomp0 = self._nominal.terms(q3, v3)
        D1, bias1, _, _ = self._loaded.terms(q3, v3)
        plus, minus, rest = slice(0, B), slice(B, 2 * B), slice(2 * B, 3 * B)
        D0, D1 = D0[plus], D1[plus]
        nominal = (np.einsum("bij,bj->bi", D0, qdd_r) + (bias0[plus] - bias0[minus]) / 4.0
                   + bias0[rest] - gravcomp0[rest] - (passive0[plus] + passive0[minus]) / 2.0)
        extra = bias1 - bias0
        payload = (np.einsum("bij,bj->bi", D1 - D0, qdd_r) + (extra[plus] - extra[minus]) / 4.0 + extra[rest])
        Y = np.zeros((B, n, self.state_size))
        Y[:, :, 0] = payload
        joints = np.arange(n)
        Y[:, joints, 1 + joints] = qd
        Y[:, joints, 1 + n + joints] = np.tanh(qd / FRICTION_SPEED)
        return nominal, D0, Y

    def __call__(self, e: NDArray[np.float64], ed: NDArray[np.float64], integral: NDArray[np.float64],
                 tau_ff: NDArray[np.float64], qdd_ref: NDArray[np.float64] | None,
                 dynamics: tuple[NDArray[np.float64], NDArray[np.float64]] | None, limit: NDArray[np.float64],
                 dt: float, *, residual: NDArray[np.float64] | None = None,
                 override: NDArray[np.float64] | None = None, state: NDArray[np.float64] | None = None,
                 q: NDArray[np.float64] | None = None, qd: NDArray[np.float64] | None = None) -> ControlOutput:
        """One period: the command (B, n), N m, and the updated estimate in `ControlOutput.state`."""
        assert state is not None
        if override is not None:
            return overridden(override, limit, integral)._replace(state=state)
        assert qdd_ref is not None and q is not None and qd is not None
        w = self.w
        sigma = ed + w * e
        qd_r = qd + sigma
        qdd_r = qdd_ref + w * ed
        nominal, D, Y = self.regressor(q, qd, qd_r, qdd_r)
        fb = np.einsum("bij,bj->bi", D, w * ed + w * sigma)
        command = nominal + np.einsum("bij,bj->bi", D, w * sigma) + np.einsum("bip,bp->bi", Y, state)
        if residual is not None:
            command = command + residual
        dtau = np.minimum(np.maximum(command, -limit), limit)
        return ControlOutput(command - fb, fb, dtau, dtau != command, integral, self.adapted(state, Y, sigma, dt))

    def adapted(self, state: NDArray[np.float64], Y: NDArray[np.float64], sigma: NDArray[np.float64], dt: float
                ) -> NDArray[np.float64]:
        """One period of the adaptation law: theta_hat + dt Gamma Y^T sigma, projected onto [0, theta_max]; state
        (B, 1 + 2n), Y (B, n, 1 + 2n), sigma (B, n)."""
        estimate = state + dt * self._gain * np.einsum("bip,bi->bp", Y, sigma)
        return np.minimum(np.maximum(estimate, 0.0), self.bounds)  # type: ignore[no-any-return]
