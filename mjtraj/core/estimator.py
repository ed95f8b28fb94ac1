"""The predictive laws' state estimate under measurement noise: a Kalman filter on an input-disturbance model.

The law's model of one control period, linearised where it plans (`mjtraj.core.mpc`), is augmented by an unknown
torque d (n,) that the plant receives beside the command and that drifts as a random walk, and optionally by
parameters theta (p,) whose torque Y_k theta the plant also receives (Y_k (n, p), the regressor at period k: a
payload at the flange, viscous damping and dry friction per joint, `mjtraj.core.mpc`):

    x_{k+1} = A_k x_k + B_k (u_k + d_k + Y_k theta_k) + c_k + w_x,   d_{k+1} = d_k + w_d,   theta_{k+1} = theta_k + w_t,
    y_k = x_k + v_k,

with x = [q; qd] (2n), the measurement y of the whole state, and independent Gaussian noises: w_x of standard
deviations `KalmanSettings.state_noise` (what the linear model mispredicts besides d), w_d of `torque_noise` N m per
period (how fast the torque the model leaves out changes as the arm moves), w_t of `parameter_drift` times each
parameter's bound, v of the sensor's sigma rad on q and sqrt(2) sigma / dt rad/s on qd (the benchmark's noise
model: a finite-difference velocity, `mjtraj.domain.families`). The sensor's sigma is assumed per simulation from
the one the loop declares (`KalmanSettings.assumed`). The filter (Kalman 1960; the augmented model of
offset-free MPC, Pannocchia and Rawlings 2003) propagates the covariance P of z = [x; d; theta] with
F_k = [[A_k, B_k, B_k Y_k], [0, I, 0], [0, 0, I]] and corrects the law's own prediction by

    K = P H^T (H P H^T + V)^-1,   z += K (y - x_pred),   P = (I - K H) P (I - K H)^T + K V K^T   (H = [I 0]),

the Joseph form, which keeps P symmetric and positive definite in floating point; theta is then projected onto its
bounds [0, theta_max]. Batched over simulations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.checks import positive
from mjtraj.exceptions import InvalidInputError


@dataclass(frozen=True)
class KalmanSettings:
    """The noise model the filter is designed for (module docstring). Defaults: the rule in docs/floor.md,
    "Protocol v2" (chosen on the validation stream, never on evaluation scenarios)."""

    sensor: float = 1e-3
    """rad: the least position-sensor standard deviation the filter assumes, also where the loop declares exact
    measurements (the noisy family's 1 mrad: a margin for what the linear model mispredicts)."""
    sensor_margin: float = 1.0
    """The filter assumes this multiple of the sensor's standard deviation the loop declares, at least `sensor`
    (`assumed`); `adaptive_mpc`'s is 2 (`mjtraj.core.mpc.ADAPTIVE_SETTINGS`)."""
    state_noise: tuple[float, float] = (1e-4, 5e-3)
    """(rad, rad/s): standard deviations per period of what the linear model mispredicts on q and on qd besides the
    torques."""
    torque_noise: float = 0.5
    """N m per period: the standard deviation of the torque disturbance's random walk."""
    initial_torque: float = 10.0
    """N m: the standard deviation of the torque disturbance before the first measurement (it starts at 0)."""
    parameter_drift: float = 6e-4
    """Per period, as a fraction of each parameter's bound: the standard deviation of the parameters' random walk."""
    initial_parameter: float = 0.05
    """As a fraction of each parameter's bound: its standard deviation before the first measurement (it starts at 0).
    At 0.15 the noisy first periods moved the parameters far enough that the estimate of a torque disturbance ran away
    on 2 of 1000 noisy validation draws (the arm fell); among 0.03, 0.05, 0.1 and 0.15, 0.05 left the most noisy
    draws at rest (962, 976, 971, 965 of 1000) and none diverged (docs/floor.md, "Protocol v2")."""

    def __post_init__(self) -> None:
        for name in ("sensor", "sensor_margin", "torque_noise", "initial_torque", "parameter_drift",
                     "initial_parameter"):
            positive(name, getattr(self, name))
        noise = self.state_noise
        if not (isinstance(noise, tuple) and len(noise) == 2 and all(np.isfinite(v) and v > 0 for v in noise)):
            raise InvalidInputError(f"state_noise: expected two standard deviations > 0 (rad, rad/s), got {noise!r}")

    def assumed(self, declared: npt.ArrayLike) -> NDArray[np.float64]:
        """rad: the position sensor's standard deviation the filter assumes where the loop declares `declared` (rad,
        any shape; 0 for exact measurements): max(sensor, sensor_margin declared)."""
        return np.maximum(self.sensor, self.sensor_margin * np.asarray(declared, dtype=np.float64))


class DisturbanceKalman:
    """The module's filter for n joints at control period dt (s) and parameters of `bounds` (p,) (none by default):
    covariances (B, size, size) in, out."""

    def __init__(self, n: int, dt: float, settings: KalmanSettings | None = None, *,
                 bounds: npt.ArrayLike = ()) -> None:
        self.n, self.dt = n, float(dt)
        self.settings = s = settings or KalmanSettings()
        self.bounds = np.asarray(bounds, dtype=np.float64).reshape(-1)
        """theta_max (p,): each parameter is kept in [0, theta_max]."""
        self.measurement = self.variances(np.zeros(1))[0]
        """V's diagonal (2n,) where the loop declares exact measurements: rad^2 and (rad/s)^2."""
        self.process = np.concatenate([np.full(n, s.state_noise[0] ** 2), np.full(n, s.state_noise[1] ** 2),
                                       np.full(n, s.torque_noise**2), (s.parameter_drift * self.bounds) ** 2])
        """W's diagonal (size,)."""

    @property
    def parameters(self) -> int:
        """p, the parameters estimated beside the torque disturbance."""
        return self.bounds.size

    @property
    def size(self) -> int:
        """3n + p: the filtered state z = [x; d; theta]."""
        return 3 * self.n + self.parameters

    def variances(self, declared: NDArray[np.float64]) -> NDArray[np.float64]:
        """V's diagonal (B, 2n), rad^2 and (rad/s)^2, of simulations whose loop declares sensors of `declared` (B,)
        rad: the assumed sigma's square on q, 2 (sigma / dt)^2 on qd."""
        sigma = self.settings.assumed(declared)[:, None]
        return np.concatenate([np.repeat(sigma**2, self.n, axis=1), np.repeat(2.0 * (sigma / self.dt) ** 2, self.n,
                                                                               axis=1)], axis=1)

    def initial(self, rows: int, declared: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """The covariance (rows, size, size) before the first measurement: the sensor's on x (`variances` of the
        declared sensors (rows,), rad; None: exact measurements), `initial_torque`^2 on d, (`initial_parameter`
        theta_max)^2 on theta."""
        s = self.settings
        V = self.variances(np.zeros(rows) if declared is None else declared)
        rest = np.concatenate([np.full(self.n, s.initial_torque**2), (s.initial_parameter * self.bounds) ** 2])
        diagonal = np.concatenate([V, np.broadcast_to(rest, (rows, rest.size))], axis=1)
        out = np.zeros((rows, self.size, self.size))
        out[:, np.arange(self.size), np.arange(self.size)] = diagonal
        return out

    def correct(self, predicted: NDArray[np.float64], disturbance: NDArray[np.float64],
                covariance: NDArray[np.float64], measured: NDArray[np.float64],
                declared: NDArray[np.float64] | None = None
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The estimate after measuring y: the predicted state (B, 2n), [d; theta] (B, n + p) and P (B, size, size)
        before, the measurement (B, 2n), the sensors the loop declares (B,), rad (None: exact measurements); returns
        x (B, 2n), [d; theta] (theta within its bounds) and P."""
        m = 2 * self.n
        V = self.variances(np.zeros(len(predicted)) if declared is None else declared)  # (B, 2n)
        S = covariance[:, :m, :m] + V[:, :, None] * np.eye(m)  # (B, 2n, 2n)
        K = np.linalg.solve(S, covariance[:, :m, :]).transpose(0, 2, 1)  # P H^T S^-1, (B, size, 2n): S, P symmetric
        z = np.concatenate([predicted, disturbance], axis=1) + np.einsum("bij,bj->bi", K, measured - predicted)
        I_KH = np.broadcast_to(np.eye(self.size), covariance.shape).copy()
        I_KH[:, :, :m] -= K
        P = I_KH @ covariance @ I_KH.transpose(0, 2, 1) + (K * V[:, None, :]) @ K.transpose(0, 2, 1)
        if self.parameters:
            z[:, m + self.n:] = np.clip(z[:, m + self.n:], 0.0, self.bounds)
        return z[:, :m], z[:, m:], P

    def predict(self, covariance: NDArray[np.float64], A: NDArray[np.float64], B: NDArray[np.float64],
                regressor: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """P of the next period: F P F^T + W with A (B, 2n, 2n), B (B, 2n, n) of the period the law commanded and
        the parameters' regressor Y (B, n, p) there (None without parameters)."""
        rows, m, n = A.shape[0], 2 * self.n, self.n
        F = np.broadcast_to(np.eye(self.size), (rows, self.size, self.size)).copy()
        F[:, :m, :m], F[:, :m, m:m + n] = A, B
        if self.parameters:
            assert regressor is not None
            F[:, :m, m + n:] = B @ regressor
        P = F @ covariance @ F.transpose(0, 2, 1)
        P[:, np.arange(self.size), np.arange(self.size)] += self.process
        return P
