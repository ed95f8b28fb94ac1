"""Model-predictive tracking (`mpc`) and its adaptive variant (`adaptive_mpc`): control laws like the others, that plan
the saturation ahead on the nominal model with the reference's preview (docs/floor.md, "Model-predictive control").

Each control period, from the state x_k and for each simulation, a receding-horizon QP in the corrective torques
u_k..u_{k+H-1} (H periods of `PredictiveSettings.horizon_seconds`) is solved and u_k applied:

    min  sum_{j=1..H} (x_{k+j} - x_ref,k+j)^T Q (x_{k+j} - x_ref,k+j) [scored]  +  sum_j u^T R u
    s.t. x_{j+1} = A_j x_j + B_j (u_j + w_j) + c_j + d   (the nominal model linearised where it plans)
         |u| <= limit,   and the terminal rows where the horizon reaches the reference's end N

with the score's own weights by Bryson's rule on the reference's move (Q = diag(1/move^2, 1/pi^2), R = 1/limit^2), so
that the law minimises the score it is judged by. The model is linearised when the loop starts a reference (`track`):
at each sample (x_ref,j, tau_ff,j), the feedforward clipped into the saturation, the analytic RK4 step of the
model's hinge tree (`mjtraj.core.planners.rigid_body`) gives A_j, B_j and the defect c_j = F(x_ref,j, tau_ff,j) -
x_ref,j+1 (central differences of MuJoCo's step where the tree does not hold the model). The QP (H n variables) is
condensed and solved by DAQP (`mjtraj.core.planners.sqp._qp`), the terminal rows soft, at most `qp_iteration_cap`
iterations; a solve that reaches the cap, fails or overflows applies the last plan shifted by one period where this
period has one, else the torques the model was linearised at.

The two protocols (docs/design.md) differ in what the law knows and how the episode ends:

- Protocol v1 (the motion alone, J_exec and the goal rule): the horizon stops at N, x_N is not scored (J_exec's sum
  ends at N-1), the terminal rows hold q_N within `goal_aim` of the goal rule's box, and the prediction is made
  offset-free by a state disturbance d_k = d_{k-1} + L (y_k - x_pred,k) (`observer_gain` L) of the measurement y.
  After its first period the model is linearised along the last solve's prediction, shifted by one period (the
  real-time iteration).
- Protocol v2 (the settle window: episodes that end at rest at the goal, J_settle): the horizon runs a whole H past
  every period, through the window and past the episode's end with the goal held and scored; the terminal rows hold
  the window's last `rest_hold` states within the at-rest rule (`goal_aim` of the settling band and of the speed
  limit, widening to `aim_last` over the last `aim_ramp` periods); the model is linearised along the reference; and
  the law plans from a Kalman filter's estimate (`mjtraj.core.estimator`): the state, a torque disturbance w_j = d
  (the same on every step) and, for `adaptive_mpc`, the adaptive law's parameters (a payload at the flange, viscous
  damping and dry friction per joint), whose torque along the reference enters every predicted step. A residual
  added to the command enters the prediction, so that the filter does not take it for a disturbance.

`adaptive_mpc` in protocol v1 plans on the adaptive law's online estimate (`mjtraj.core.adaptive`): it adds the
estimated torque Y theta_hat (held over the horizon, inside the saturation) and updates theta_hat by the adaptive
law's own rule, except in a period whose command saturates; the disturbance estimate carries the rest. In protocol
v2 the filter estimates the same parameters instead (the gradient rule, with raw measurements, does not survive
measurement noise).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, NamedTuple, cast

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import positive_int
from mjtraj.core.adaptive import ADAPTATION_RATE, AdaptiveComputedTorque, parameter_bounds
from mjtraj.core.controller import ControlOutput, overridden
from mjtraj.core.estimator import DisturbanceKalman, KalmanSettings
from mjtraj.core.metrics import GOAL_TOLERANCE
from mjtraj.core.model import JointInfo
from mjtraj.core.scoring import JOINT_SPEED_LIMIT
from mjtraj.core.settle import SETTLE_BAND, SETTLE_SPEED
from mjtraj.exceptions import SolverError
from mjtraj.threads import one_blas_thread


@dataclass(frozen=True)
class PredictiveSettings:
    """The predictive laws' tunables, each with its rule (the measurements behind them: docs/floor.md,
    "Model-predictive control" and "Protocol v2"; every choice made on validation draws, seed 0, never on the
    held-out scenarios)."""

    horizon_seconds: float = 1.0
    """s of preview: the horizon is round(horizon_seconds / dt) periods (50 at the UR5's 20 ms). Chosen with the
    observer gain on the mismatch family's validation draws 0-29 (adaptive_mpc's mean J_exec over the adaptive
    law's) among 0.5 s and 1 s x gains 0.3, 0.6 and 1: 0.5 s gave 0.916, 0.910, 0.906; 1 s 0.892, 0.870, 0.862."""
    observer_gain: float = 1.0
    """Protocol v1: L of the disturbance estimate d_k = d_{k-1} + L (y_k - x_pred,k) (an integrator of the
    prediction error)."""
    real_time_iteration: bool = True
    """Protocol v1: linearise along the last solve's prediction, shifted by one period (True), or along the
    reference (False). On aggressive motions the arm lags the reference far, and linearised there the plan of seven
    held-out scenarios cost 3 to 29 times their floor."""
    settle_real_time_iteration: bool = False
    """Protocol v2's real_time_iteration. Rule: kept only where validation shows it helps, by the most episodes at
    rest at the goal, then the least mean J_settle, over 100 validation draws of each family (the noisy one
    included). Along the last prediction mpc comes to rest on 76 and 73 of the mismatch and noisy draws, along the
    reference on 90 and 87 (adaptive_mpc: 89, 83 against 100, 96); the other families: 100 either way."""
    qp_iteration_cap: int = 50
    """DAQP's iteration cap per solve (deterministic, unlike a time cap, so a run's numbers stay the same): 5 times
    the most any solve took over 60 validation episodes (20 per family, with the settle window: 2, 6 and 10 at most,
    the median 1). It applies in both protocols; the published v1 rows reproduce with it."""
    goal_aim: float = 0.5
    """The terminal rows aim at this fraction of the rule's per-joint box (v1: the goal rule's, v2: the settling
    band and the speed limit), a margin for the model's error."""
    aim_ramp: int = 10
    """Protocol v2: the periods before the window's end over which the aim widens from goal_aim to aim_last (a plan
    held to half the band one period from the end pushes a joint that is inside the band: on validation draws with
    noise this moved the noisy family's successes from 89 to 95 of 100 for adaptive_mpc; 5 and 25 periods did the
    same)."""
    aim_last: float = 0.9
    """Protocol v2: the aim at the last period (the whole rule, 1, left episodes ending at 0.05 rad/s exactly:
    aggressive successes 96 of 100 against 100)."""
    rest_hold: int = 5
    """Protocol v2: the terminal rows hold this many of the window's last states, each within the at-rest aim (at
    most the window's periods, 25 at 20 ms: a state before the window would be held at the goal too). Held
    at the last state alone (1) the plan reached the box at that state only, the state before it outside (a late
    correction whose speed the noisy family's filter mispredicts: the held-out noisy failures ended at 0.05 to 0.15
    rad/s). Rule: settle_real_time_iteration's, with the filter's initial_parameter (chosen together, before
    `adaptive_mpc`'s sensor of 2 mrad); for `adaptive_mpc` on 300 validation draws of the noise-free families and 1000
    noisy ones, 1876 episodes at rest against 1874 with 1 (docs/floor.md, "Protocol v2"); `mpc` on 100 of each, 384
    against 377."""
    past_end: bool = True
    """Protocol v2: plan a whole horizon from every period, past the episode's end with the goal held and scored
    (True), or stop the horizon at the episode's end (False; a horizon of one period at the end is a dead-beat plan
    whose gains amplify the measurement noise: mpc's noisy successes 23 of 30 validation draws against 27)."""
    filter_friction_speed: float = 0.1
    """rad/s: the filter's dry-friction regressor is tanh(qd / filter_friction_speed) at the estimated velocity
    (the adaptive law's 0.02 is below the noisy family's velocity noise, 0.07 rad/s, and made the estimate of a
    stuck joint's friction wind up until it broke away). Among 0.02, 0.05, 0.1 and 0.2: adaptive_mpc at rest on 97,
    99, 100, 99 mismatch and 95, 94, 96, 94 noisy validation draws of 100."""
    guess_reach: tuple[float, float] = (np.pi / 2, 4 * np.pi)
    """Protocol v1: a predicted motion farther than this from the reference (rad) or faster (rad/s) anywhere is not
    linearised along: the reference's linearisation stands instead (a prediction that an estimate of a payload that
    is not there drove away, on aggressive motions)."""
    payload_inertia: bool = True
    """Protocol v2, `adaptive_mpc`: the filter's payload estimate m also weighs in the plan's response to torque,
    B_j D_j (D_j + m D1_j)^-1 in place of B_j (D_j the nominal mass matrix along the reference, D1_j a 1 kg point
    mass's at the flange), besides its torque along the reference; False: the nominal response, the payload's
    inertia then left to the filter's torque disturbance, which lags each correction (heavy payloads ended their
    windows still swinging). Rule: settle_real_time_iteration's; 100 validation draws per family could not tell the
    two apart (394 and 395 of 400 at rest), 300 did: 1189 against 1186 of 1200 at rest, the least mean J_settle on
    mismatched plants with and without noise (docs/floor.md, "Protocol v2")."""
    payload_confidence: float = 0.0
    """Protocol v2, with `payload_inertia`: the payload counted is the filter's estimate less this many of its
    standard deviations (at least 0). One and two left fewer episodes at rest on 100 validation draws (391 and 392 of
    400 against 394)."""
    kalman: KalmanSettings = field(default_factory=KalmanSettings)
    """Protocol v2's filter (`mjtraj.core.estimator`)."""

    def __post_init__(self) -> None:
        positive_int("rest_hold", self.rest_hold)


DEFAULT_SETTINGS = PredictiveSettings()
"""`mpc`'s settings."""

ADAPTIVE_SETTINGS = PredictiveSettings(kalman=KalmanSettings(sensor_margin=2.0))
"""`adaptive_mpc`'s settings: `mpc`'s, but its filter assumes a sensor twice as noisy as the loop declares, at least
1 mrad (the noisy family's 2 mrad, exact measurements' 1: the margin absorbs what the parameters' torque along the
reference mispredicts under noise). Rule: the settings' own, on 300 validation draws of each noise-free family and
1000 noisy ones: at rest on 1885 with this rule, 1883 with 2 mrad everywhere, 1882 with 1.5, 1876 with 1 and, on the
noisy draws, 973 of 1000 with 3 (987, 985, 978); a fixed 2 mrad also cost 1.7 % mean J_settle on the mismatched
plants without noise. `mpc`, which estimates no parameters, came to rest on fewer draws with 2 mrad (371 of 400
against 384), so it keeps 1 (docs/floor.md, "Protocol v2")."""


def linearised_steps(model: mujoco.MjModel, X: NDArray[np.float64], U: NDArray[np.float64], *, tree: Any = False
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """One control period of `model` from each state X (M, 2n) under U (M, n): (next (M, 2n), A (M, 2n, 2n),
    B (M, 2n, n)); analytic where the model's hinge tree holds it (`tree`: `RigidBody.of(model)` made once by the
    caller, None where it does not hold; False: made here), else central differences of MuJoCo's step."""
    if tree is False:
        from mjtraj.core.planners.rigid_body import RigidBody

        tree = RigidBody.of(model)
    n = model.nv
    if tree is not None:
        after, jacobian = tree.step(X, U)
        return after, jacobian[:, :, :2 * n], jacobian[:, :, 2 * n:]
    data = mujoco.MjData(model)
    M = X.shape[0]
    after = np.empty((M, 2 * n))
    jacobian = np.empty((M, 2 * n, 3 * n))
    eps = 1e-6

    def step(z: NDArray[np.float64]) -> NDArray[np.float64]:
        mujoco.mj_resetData(model, data)
        data.qpos[:], data.qvel[:], data.ctrl[:] = z[:n], z[n:2 * n], z[2 * n:]
        mujoco.mj_step(model, data)
        return np.concatenate([data.qpos, data.qvel])

    for m in range(M):
        z = np.concatenate([X[m], U[m]])
        after[m] = step(z)
        for i in range(3 * n):
            dz = np.zeros(3 * n)
            dz[i] = eps
            jacobian[m, :, i] = (step(z + dz) - step(z - dz)) / (2 * eps)
    return after, jacobian[:, :, :2 * n], jacobian[:, :, 2 * n:]


class Solved(NamedTuple):
    """One simulation's solve at one period (`ModelPredictive.solve`)."""

    torque: NDArray[np.float64]
    """(n,) N m: the command, before any residual and the saturation."""
    predicted: NDArray[np.float64]
    """(2n,): the state the model predicts after it."""
    A: NDArray[np.float64]
    """(2n, 2n): the model's first step, linearised where the solve planned."""
    B: NDArray[np.float64]
    """(2n, n)."""
    regressor: NDArray[np.float64] | None = None
    """(n, p): the filter's parameters' regressor of this period (`estimates_parameters`), else None."""


@dataclass
class ModelPredictive:
    """The module's law for `nsim` simulations of the nominal `model` at control period `dt` (s).

    Its per-simulation state is the period counter (the loop keeps and resets it); `track` takes each simulation's
    reference when the loop (re)starts it.
    """

    model: mujoco.MjModel
    dt: float
    nsim: int
    horizon: int = 0
    """Periods of preview; 0: round(settings.horizon_seconds / dt)."""
    settings: PredictiveSettings = DEFAULT_SETTINGS
    name: ClassVar[str] = "mpc"
    needs_dynamics: ClassVar[bool] = False
    estimates_parameters: ClassVar[bool] = False
    """Whether protocol v2's filter also estimates the adaptive law's parameters (a payload at the flange, viscous
    damping and dry friction per joint, `mjtraj.core.adaptive`) beside the torque disturbance."""
    _plan: dict[str, NDArray[np.float64]] = field(default_factory=dict, repr=False)
    _response: tuple[NDArray[np.intp], NDArray[np.float64]] | None = field(default=None, repr=False)
    """The last period's protocol-v2 simulations and their input matrices B (R, 2n, n): `applied_state`."""

    def __post_init__(self) -> None:
        self.n = self.model.nv
        if self.horizon <= 0:
            self.horizon = max(1, round(self.settings.horizon_seconds / self.dt))
        self.limit = JointInfo.of(self.model).torque_limit
        bounds = parameter_bounds(self.model) if self.estimates_parameters else ()
        self.filter = DisturbanceKalman(self.n, self.dt, self.settings.kalman, bounds=bounds)

    @property
    def state_size(self) -> int:
        """1 + 4n + (m - 2n) + m^2: the period counter k, the state the model predicted for now (NaN at the start),
        the disturbance estimate d (2n) of protocol v1's episodes, and protocol v2's filter of m = `filter.size`
        states: its torque disturbance (n) and parameters (with `estimates_parameters`), and its covariance (m^2,
        row-major; `mjtraj.core.estimator`)."""
        return 1 + 2 * self.n + self.filter.size + self.filter.size**2

    def initial_state(self, rows: int) -> NDArray[np.float64]:
        """k = 0 and no prediction for `rows` simulations, shape (rows, state_size)."""
        out = np.zeros((rows, self.state_size))
        out[:, 1:1 + 2 * self.n] = np.nan
        start = 1 + 2 * self.n + self.filter.size
        out[:, start:start + self.filter.size**2] = self.filter.initial(rows).reshape(rows, -1)
        return out

    def track(self, rows: NDArray[np.intp] | slice, q_ref: NDArray[np.float64], qd_ref: NDArray[np.float64],
              tau_ff: NDArray[np.float64], *, windows: NDArray[np.intp] | None = None,
              sensors: NDArray[np.float64] | None = None) -> None:
        """Linearise the model along the references of simulations `rows`: q_ref, qd_ref (N+1, R, n), the
        feedforward tau_ff (N, R, n). Past N the reference holds its last pose at rest, with zero torque. `windows`
        (R,): the periods of a settle window that ends each reference (protocol v2; None or 0: none), whose at-rest
        rule then is the terminal constraint. `sensors` (R,): the standard deviation of the position noise the loop
        declares for each simulation, rad (None: exact measurements), which protocol v2's filter is designed for
        (`KalmanSettings.assumed`)."""
        N, R, n = tau_ff.shape
        H = self.horizon
        x_ref = np.concatenate([q_ref, qd_ref], axis=2).transpose(1, 0, 2)  # (R, N+1, 2n)
        hold = np.concatenate([q_ref[-1], np.zeros_like(qd_ref[-1])], axis=1)  # (R, 2n)
        x_ext = np.concatenate([x_ref, np.repeat(hold[:, None], H, axis=1)], axis=1)  # (R, N+H+1, 2n)
        # linearised at the feedforward within the saturation: MuJoCo clamps a control to its range, so beyond it the
        # step's Jacobian in that torque is zero
        inside = np.clip(tau_ff, -self.limit, self.limit)
        u_ext = np.concatenate([inside.transpose(1, 0, 2), np.zeros((R, H, n))], axis=1)  # (R, N+H, n)
        with one_blas_thread():
            after, A, B = linearised_steps(self.model, x_ext[:, :-1].reshape(-1, 2 * n), u_ext.reshape(-1, n),
                                           tree=self._tree)
        fields = {"x": x_ext, "u": u_ext, "A": A.reshape(R, N + H, 2 * n, 2 * n),
                  "B": B.reshape(R, N + H, 2 * n, n),
                  "c": after.reshape(R, N + H, 2 * n) - x_ext[:, 1:],
                  "steps": np.full(R, N, dtype=np.float64),
                  "move": np.max(np.abs(q_ref[-1] - q_ref[0]), axis=1),
                  "window": np.zeros(R) if windows is None else np.asarray(windows, dtype=np.float64),
                  "sensor": np.zeros(R) if sensors is None else np.asarray(sensors, dtype=np.float64),
                  "guess_x": np.zeros((R, H + 1, 2 * n)), "guess_u": np.zeros((R, H, n)),
                  "guess_k": np.full(R, -1.0), "regressor": self._regressors(x_ext),
                  **self._inertias(x_ext)}
        if not self._plan or (self._plan["x"].shape[1] != N + H + 1):
            self._plan = {k: np.zeros((self.nsim, *v.shape[1:])) for k, v in fields.items()}
        for name, value in fields.items():
            self._plan[name][rows] = value

    @cached_property
    def _tree(self) -> Any:
        """The model's hinge tree (`RigidBody.of`), None where it does not hold the model; made once."""
        from mjtraj.core.planners.rigid_body import RigidBody

        return RigidBody.of(self.model)

    def _regressors(self, x_ext: NDArray[np.float64]) -> NDArray[np.float64]:
        """(R, N+H, n, p): the torque per unit of each parameter that the plant receives along each step of the
        references x_ext (R, N+H+1, 2n): minus the adaptive law's regressor there (what it takes to follow the step,
        the accelerations the velocities' differences); p = 0 for a law without parameters."""
        R, steps, n = x_ext.shape[0], x_ext.shape[1] - 1, self.n
        if not self.estimates_parameters:
            return np.zeros((R, steps, n, 0))
        q, qd = x_ext[:, :-1, :n].reshape(-1, n), x_ext[:, :-1, n:].reshape(-1, n)
        qdd = (np.diff(x_ext[:, :, n:], axis=1) / self.dt).reshape(-1, n)
        _, _, Y = self._regressor_probe.regressor(q, qd, qd, qdd)
        return -Y.reshape(R, steps, n, -1)  # type: ignore[no-any-return]

    def _inertias(self, x_ext: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Along each step of the references x_ext (R, N+H+1, 2n): the nominal mass matrix "inertia" and a 1 kg
        payload's "payload_inertia" at the flange (R, N+H, n, n), kg m^2, where `payload_inertia` applies; else
        empty (R, N+H, 0, 0)."""
        R, steps, n = x_ext.shape[0], x_ext.shape[1] - 1, self.n
        if not (self.estimates_parameters and self.settings.payload_inertia):
            return {"inertia": np.zeros((R, steps, 0, 0)), "payload_inertia": np.zeros((R, steps, 0, 0))}
        q = x_ext[:, :-1, :n].reshape(-1, n)
        rest = np.zeros_like(q)
        probe = self._regressor_probe
        _, D, Y = probe.regressor(q, rest, rest, rest)
        columns = [probe.regressor(q, rest, rest, np.broadcast_to(np.eye(n)[j], q.shape))[2][:, :, 0] - Y[:, :, 0]
                   for j in range(n)]  # a 1 kg payload's torque per unit acceleration of joint j, less its gravity
        return {"inertia": D.reshape(R, steps, n, n),
                "payload_inertia": np.stack(columns, axis=2).reshape(R, steps, n, n)}

    def _loaded_response(self, b: int, k: int, H: int, B: NDArray[np.float64], payload: float
                         ) -> NDArray[np.float64]:
        """B (H, 2n, n) of simulation b's horizon from period k, the torque's response under a payload of `payload`
        kg at the flange: B_j D_j (D_j + payload D1_j)^-1 (`PredictiveSettings.payload_inertia`): the nominal
        model's response to D_j (D_j + payload D1_j)^-1 u is the loaded arm's to u."""
        D = self._plan["inertia"][b, k:k + H]
        loaded = D + payload * self._plan["payload_inertia"][b, k:k + H]
        return B @ np.linalg.solve(loaded, D).transpose(0, 2, 1)  # type: ignore[no-any-return]  # D, loaded symmetric

    @cached_property
    def _regressor_probe(self) -> AdaptiveComputedTorque:
        """The adaptive law, for its regressor; made once."""
        return AdaptiveComputedTorque(self.model, self.dt, 1)

    def _regressor_now(self, b: int, k: int, qd: NDArray[np.float64]) -> NDArray[np.float64]:
        """(n, p): simulation b's regressor at period k, the payload's along the reference, damping's and
        friction's at the estimated velocity qd (n,)."""
        n = self.n
        Y = self._plan["regressor"][b, k].copy()
        joints = np.arange(n)
        Y[joints, 1 + joints] = -qd
        Y[joints, 1 + n + joints] = -np.tanh(qd / self.settings.filter_friction_speed)
        return Y  # type: ignore[no-any-return]

    def _linearisation(self, b: int, k: int, H: int
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                                  NDArray[np.float64]]:
        """Where simulation b's model is linearised for the horizon of period k: the states (H+1, 2n) and model
        torques (H, n) and the step's A (H, 2n, 2n), B (H, 2n, n), c (H, 2n) there. The last solve's prediction,
        shifted by one period (real-time iteration), where it is this period's; else the reference's (`track`)."""
        p = self._plan
        s = self.settings
        realtime = s.settle_real_time_iteration if p["window"][b] > 0 else s.real_time_iteration
        if int(p["guess_k"][b]) != k or not realtime:
            return (p["x"][b, k:k + H + 1], p["u"][b, k:k + H], p["A"][b, k:k + H], p["B"][b, k:k + H],
                    p["c"][b, k:k + H])
        X, W = p["guess_x"][b, :H + 1], p["guess_u"][b, :H]
        n = self.n
        near = (np.all(np.abs(X[:, :n] - p["x"][b, k:k + H + 1, :n]) <= s.guess_reach[0])
                and np.all(np.abs(X[:, n:]) <= s.guess_reach[1]))
        if near:
            after, A, B = linearised_steps(self.model, X[:-1], W, tree=self._tree)
            if np.all(np.isfinite(after)) and np.all(np.isfinite(A)) and np.all(np.isfinite(B)):
                return X, W, A, B, after - X[1:]
        p["guess_k"][b] = -1  # a wild prediction: the reference's linearisation instead
        return self._linearisation(b, k, H)

    def solve(self, b: int, k: int, x: NDArray[np.float64], shift: NDArray[np.float64] | None = None,
              disturbance: NDArray[np.float64] | None = None, torque: NDArray[np.float64] | None = None,
              payload: float = 0.0) -> Solved:
        """The torque (n,), N m, that simulation b applies at period k from the (estimated) state x (2n,); `shift`
        is a torque (n,) the plant also receives, held over the horizon (the adaptive estimate's), inside the limit;
        `disturbance` (2n,) is added to every predicted step (protocol v1's offset-free estimate); `torque` is
        protocol v2's filtered [d (; m)] (`mjtraj.core.estimator`): the torque disturbance d (n,) and, with the
        payload, its torque m Y_j along the reference, added to every predicted step's torque; `payload` (kg) the
        payload whose inertia the response to torque counts (`PredictiveSettings.payload_inertia`). Also returns the
        state (2n,) the model predicts after the command and the first step's A and B."""
        from mjtraj.core.planners.sqp import _qp

        p = self._plan
        n, N = self.n, int(p["steps"][b])
        settle = p["window"][b] > 0
        # in protocol v2's episodes the horizon runs past the episode's end, the goal held and scored (a whole horizon
        # to the last period: no deadbeat plan at the end, where a short horizon's gains amplify the noise)
        s = self.settings
        past_end = bool(settle and s.past_end)
        H = self.horizon if past_end else min(self.horizon, max(N - k, 1))
        X, W, A, B, c = self._linearisation(b, k, H)
        if payload > 0:
            B = self._loaded_response(b, k, H, B, payload)
        inputs, regressor = None, None
        if torque is not None:  # the filter's torque on every predicted step, (H, n)
            inputs = np.broadcast_to(torque[:n], (H, n))
            if self.estimates_parameters:  # the parameters' along the reference, at the estimate for this period's
                Y = p["regressor"][b, k:k + H].copy()
                Y[0] = regressor = self._regressor_now(b, k, x[n:])
                inputs = inputs + Y @ torque[n:]
        x_ref = p["x"][b, k:k + H + 1]
        move = float(p["move"][b]) or 1.0
        q_w = np.concatenate([np.full(n, 1.0 / move**2), np.full(n, 1.0 / JOINT_SPEED_LIMIT**2)])
        r_w = 1.0 / self.limit**2
        held = np.zeros(n) if shift is None else shift
        # condensed prediction of the deviations d_j = x_{k+j} - X_j from the linearisation's states: d = F d_0 + G v +
        # e, v the torque change from W
        F = np.empty((H + 1, 2 * n, 2 * n))
        G = np.zeros((H + 1, 2 * n, H * n))
        e = np.zeros((H + 1, 2 * n))
        F[0] = np.eye(2 * n)
        for j in range(H):
            F[j + 1] = A[j] @ F[j]
            G[j + 1] = A[j] @ G[j]
            G[j + 1, :, j * n:(j + 1) * n] = B[j]
            e[j + 1] = A[j] @ e[j] + c[j] + (0.0 if disturbance is None else disturbance)
            if inputs is not None:
                e[j + 1] += B[j] @ inputs[j]
        deviation = np.einsum("jab,b->ja", F, x - X[0]) + e  # (H+1, 2n): from X, with v = 0
        free = X - x_ref + deviation  # (H+1, 2n): the tracking errors with v = 0
        # x_N and beyond are not scored (J_exec's sum ends at N-1), but past a settle window's end (past_end)
        scored = (np.arange(1, H + 1) + k < N) | past_end
        weights = np.where(scored[:, None], q_w, 0.0)  # (H, 2n)
        Gs = G[1:] * np.sqrt(weights)[:, :, None]
        rs = free[1:] * np.sqrt(weights)
        total = W + held  # the torque with v = 0, (H, n)
        hessian = Gs.reshape(-1, H * n).T @ Gs.reshape(-1, H * n)
        hessian[np.diag_indices(H * n)] += np.tile(r_w, H)
        gradient = Gs.reshape(-1, H * n).T @ rs.ravel() + (total * r_w).ravel()
        high = (self.limit - total).ravel()
        low = (-self.limit - total).ravel()
        rows_g, rows_h = np.zeros((0, H * n)), np.zeros(0)
        if k + H >= N:  # the horizon reaches the end: the goal rule's box at x_N, or the at-rest rule's
            end = N - k
            if settle:  # a settle window: every joint within the band and below the speed limit
                # the margin for the model's error narrows as the end comes nearer: the full rule at the last period
                aim = s.aim_last - (s.aim_last - s.goal_aim) * min(1.0, (end - 1) / max(s.aim_ramp - 1, 1))
                box = np.concatenate([np.full(n, aim * SETTLE_BAND * move), np.full(n, aim * SETTLE_SPEED)])
                held_states = np.arange(max(end - s.rest_hold + 1, 1), end + 1)  # the window's last rest_hold states
                Gq, at = G[held_states].reshape(-1, H * n), free[held_states].ravel()
                box = np.tile(box, held_states.size)
            else:
                box = np.full(n, s.goal_aim * GOAL_TOLERANCE * move / np.sqrt(n))
                Gq, at = G[end, :n], free[end, :n]
            rows_g = np.vstack([-Gq, Gq])
            rows_h = np.concatenate([box - at, box + at])
        try:
            solved = _qp(hessian, gradient, np.zeros((0, H * n)), np.zeros(0), rows_g, rows_h, low, high, True,
                         iter_limit=s.qp_iteration_cap)
        except SolverError:  # a Hessian made of a prediction that overflowed
            solved = None
        v = solved[0] if solved is not None and np.all(np.isfinite(solved[0])) else self._fallback(b, k, H, W)
        states = X + deviation + np.einsum("jab,b->ja", G, v)  # (H+1, 2n): the predicted motion
        self._keep(b, k, H, states, W + v.reshape(H, n))
        return Solved(total[0] + v[:n], states[1], A[0], B[0], regressor)

    def _fallback(self, b: int, k: int, H: int, W: NDArray[np.float64]) -> NDArray[np.float64]:
        """The torque change (H n,) from the linearisation's torques W (H, n) that a failed or capped solve applies:
        to the last plan shifted by one period where this period has one (`_keep`), else none (W itself)."""
        p = self._plan
        if int(p["guess_k"][b]) != k:
            return np.zeros(H * self.n)
        return (p["guess_u"][b, :H] - W).ravel()  # type: ignore[no-any-return]

    def _keep(self, b: int, k: int, H: int, states: NDArray[np.float64], inputs: NDArray[np.float64]) -> None:
        """Keep simulation b's predicted motion (H+1, 2n) and model torques (H, n) from period k, shifted to start at
        k + 1 and extended by the reference, as the next period's linearisation (real-time iteration)."""
        p = self._plan
        p["guess_x"][b, :H] = states[1:]
        p["guess_x"][b, H] = p["x"][b, k + H + 1]
        p["guess_u"][b, :H - 1] = np.clip(inputs[1:], -self.limit, self.limit)
        p["guess_u"][b, H - 1] = p["u"][b, k + H]
        p["guess_k"][b] = k + 1

    def __call__(self, e: NDArray[np.float64], ed: NDArray[np.float64], integral: NDArray[np.float64],
                 tau_ff: NDArray[np.float64], qdd_ref: NDArray[np.float64] | None,
                 dynamics: tuple[NDArray[np.float64], NDArray[np.float64]] | None, limit: NDArray[np.float64],
                 dt: float, *, residual: NDArray[np.float64] | None = None,
                 override: NDArray[np.float64] | None = None, state: NDArray[np.float64] | None = None,
                 q: NDArray[np.float64] | None = None, qd: NDArray[np.float64] | None = None) -> ControlOutput:
        """One period for the batch: the command (B, n), N m; the counter advances in `ControlOutput.state`."""
        assert state is not None and q is not None and qd is not None
        if override is not None:
            self._response = None
            return overridden(override, limit, integral)._replace(state=self._skipped(state))
        estimate = self._estimate(state, np.concatenate([q, qd], axis=1))
        return self._output(self._solve_all(estimate, None), estimate, tau_ff, limit, integral, residual)

    def _estimate(self, state: NDArray[np.float64], measured: NDArray[np.float64]) -> Estimate:
        """What the law knows at this period after measuring [q; qd] (B, 2n): in protocol v1's episodes the
        measurement itself and d + L (y - x_pred) (L `settings.observer_gain`), in protocol v2's the filter's
        estimate."""
        n, m = self.n, self.filter.size
        counter, expected = state[:, :1], state[:, 1:1 + 2 * n]
        disturbance, torque = state[:, 1 + 2 * n:1 + 4 * n], state[:, 1 + 4 * n:1 + 2 * n + m]
        covariance = state[:, 1 + 2 * n + m:1 + 2 * n + m + m * m].reshape(-1, m, m)
        window = self._plan["window"] > 0
        gain = self.settings.observer_gain
        out = Estimate(counter, measured.copy(), disturbance + gain * np.nan_to_num(measured - expected),
                       np.zeros_like(torque), covariance.copy(), window)
        if window.any():
            rows = np.flatnonzero(window)
            fresh: NDArray[np.bool_] = np.asarray(np.isnan(expected[rows]).any(axis=1))  # the first period, or one
            # after a period the law did not command
            prior = np.where(fresh[:, None], measured[rows], expected[rows])
            declared = self._plan["sensor"][rows]
            P = np.where(fresh[:, None, None], self.filter.initial(rows.size, declared), covariance[rows])
            x, z, P = self.filter.correct(prior, np.where(fresh[:, None], 0.0, torque[rows]), P, measured[rows],
                                          declared)
            out.state[rows], out.torque[rows], out.covariance[rows] = x, z, P
            out.disturbance[rows] = 0.0
        return out

    def applied_state(self, state: NDArray[np.float64], commanded: NDArray[np.float64],
                      applied: NDArray[np.float64]) -> NDArray[np.float64]:
        """The state (B, state_size) after the period this law last answered, had it commanded `applied` (B, n),
        N m, instead of its command `commanded` (B, n): a teacher shadowing a loop that applied another
        command (`ClosedLoop.teach`). In protocol v2's episodes the prediction moves by B (applied - commanded), as
        the law's own loop counts a residual or the saturation, so that its filter does not take the other
        command for a disturbance; protocol v1's episodes keep their state (their prediction counts neither)."""
        if self._response is None:
            return state
        rows, B = self._response
        other = applied[rows] - commanded[rows]
        moved = np.flatnonzero(np.any(other != 0, axis=1))  # elsewhere exact, even where B is not finite
        out = state.copy()
        out[rows[moved], 1:1 + 2 * self.n] += np.einsum("bij,bj->bi", B[moved], other[moved])
        return out

    def _skipped(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """The state after a period the law did not command (the env's torque mode): no prediction to compare."""
        out = state.copy()
        out[:, 0] += 1
        out[:, 1:1 + 2 * self.n] = np.nan
        return out

    def _solve_all(self, estimate: Estimate, shift: NDArray[np.float64] | None) -> list[Solved]:
        """Every simulation's solve from its estimate."""
        payloads = self._counted_payloads(estimate)
        with one_blas_thread():
            ks = self._periods(estimate.counter)
            return [self.solve(b, int(ks[b]), estimate.state[b],
                               None if shift is None else shift[b], estimate.disturbance[b],
                               estimate.torque[b] if estimate.filtered[b] else None, payloads[b])
                    for b in range(estimate.state.shape[0])]

    def _periods(self, counter: NDArray[np.float64]) -> NDArray[np.intp]:
        """(B,): each simulation's period k from the counters (B, 1), at most its reference's last (a loop's teacher
        is asked again after its simulation ended, before the vector env restarts it: its answer is unused, but must
        not read past the plan)."""
        return np.minimum(counter[:, 0].astype(np.intp), self._plan["steps"].astype(np.intp) - 1)

    @staticmethod
    def _saturated(planned: NDArray[np.float64], residual: NDArray[np.float64] | None, limit: NDArray[np.float64]
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The command (B, n), N m (the plan's torque, a residual added), and what the plant receives: it within
        the saturation `limit`."""
        command = planned if residual is None else planned + residual
        return command, np.minimum(np.maximum(command, -limit), limit)

    def _counted_payloads(self, estimate: Estimate) -> NDArray[np.float64]:
        """(B,) kg: the payload whose inertia each simulation's plan counts (`PredictiveSettings.payload_inertia`):
        in protocol v2's episodes of a law that estimates it, the filter's estimate less `payload_confidence` of its
        standard deviations, at least 0; else 0."""
        s, n = self.settings, self.n
        if not (self.estimates_parameters and s.payload_inertia):
            return np.zeros(estimate.state.shape[0])
        spread = np.sqrt(np.maximum(estimate.covariance[:, 3 * n, 3 * n], 0.0))
        return np.where(estimate.filtered, np.maximum(estimate.torque[:, n] - s.payload_confidence * spread, 0.0), 0.0)

    def _output(self, solved: list[Solved], estimate: Estimate, tau_ff: NDArray[np.float64],
                limit: NDArray[np.float64], integral: NDArray[np.float64], residual: NDArray[np.float64] | None,
                extra: NDArray[np.float64] | None = None) -> ControlOutput:
        """The saturated command (a residual added first) and the law's next state (`extra` appended: a subclass's);
        reported split: tau_ff the loop's feedforward, tau_fb the rest of the MPC's command. In protocol v2's
        episodes the prediction counts what the plant receives beyond the plan (a residual, the saturation), so
        that the filter does not take it for a disturbance, and the filter's covariance moves on."""
        planned = np.stack([s.torque for s in solved])
        predicted = np.stack([s.predicted for s in solved])
        command, dtau = self._saturated(planned, residual, limit)
        covariance = estimate.covariance
        rows = np.flatnonzero(estimate.filtered)
        self._response = None
        if rows.size:
            A = np.stack([solved[b].A for b in rows])
            B = np.stack([solved[b].B for b in rows])
            self._response = (rows, B)
            predicted[rows] += np.einsum("bij,bj->bi", B, dtau[rows] - planned[rows])
            Y = (np.stack([cast(NDArray[np.float64], solved[b].regressor) for b in rows])
                 if self.estimates_parameters else None)
            covariance = covariance.copy()
            covariance[rows] = self.filter.predict(covariance[rows], A, B, Y)
        parts = [estimate.counter + 1, predicted, estimate.disturbance, estimate.torque,
                 covariance.reshape(covariance.shape[0], -1)]
        state = np.concatenate(parts if extra is None else [*parts, extra], axis=1)
        return ControlOutput(tau_ff, command - tau_ff, dtau, dtau != command, integral, state)


class Estimate(NamedTuple):
    """What a predictive law knows at one period for the batch (`ModelPredictive._estimate`)."""

    counter: NDArray[np.float64]
    """(B, 1): the period k."""
    state: NDArray[np.float64]
    """(B, 2n): the state it plans from (protocol v1: the measurement; v2: the filter's estimate)."""
    disturbance: NDArray[np.float64]
    """(B, 2n): protocol v1's state disturbance (0 in v2's episodes)."""
    torque: NDArray[np.float64]
    """(B, m - 2n): protocol v2's filtered torque disturbance (N m) and payload (kg; 0 in v1's episodes)."""
    covariance: NDArray[np.float64]
    """(B, m, m): protocol v2's covariance, after the measurement."""
    filtered: NDArray[np.bool_]
    """(B,): the episode is protocol v2's (a settle window ends its reference)."""


@dataclass
class AdaptiveModelPredictive(ModelPredictive):
    """`mpc` planning on the adaptive law's estimate: state [`mpc`'s (k, the predicted state, the disturbance),
    theta_hat]."""

    settings: PredictiveSettings = ADAPTIVE_SETTINGS
    rate: float = ADAPTATION_RATE
    name: ClassVar[str] = "adaptive_mpc"
    estimates_parameters: ClassVar[bool] = True

    def __post_init__(self) -> None:
        super().__post_init__()
        self._adaptive = AdaptiveComputedTorque(self.model, self.dt, self.nsim, self.rate)

    @property
    def state_size(self) -> int:
        """`mpc`'s state, then the adaptive law's estimate (1 + 2n: payload kg, damping, friction per joint)."""
        return super().state_size + self._adaptive.state_size

    def __call__(self, e: NDArray[np.float64], ed: NDArray[np.float64], integral: NDArray[np.float64],
                 tau_ff: NDArray[np.float64], qdd_ref: NDArray[np.float64] | None,
                 dynamics: tuple[NDArray[np.float64], NDArray[np.float64]] | None, limit: NDArray[np.float64],
                 dt: float, *, residual: NDArray[np.float64] | None = None,
                 override: NDArray[np.float64] | None = None, state: NDArray[np.float64] | None = None,
                 q: NDArray[np.float64] | None = None, qd: NDArray[np.float64] | None = None) -> ControlOutput:
        assert state is not None and q is not None and qd is not None and qdd_ref is not None
        own = super().state_size
        theta = state[:, own:]
        if override is not None:
            self._response = None
            return overridden(override, limit, integral)._replace(state=self._skipped(state))
        estimate = self._estimate(state[:, :own], np.concatenate([q, qd], axis=1))
        # protocol v2's episodes: the parameters are the filter's (estimates_parameters); the adaptive law's rule
        # runs in protocol v1's alone
        v1 = ~estimate.filtered
        adapted, shift = theta.copy(), np.zeros_like(q)
        if v1.any():
            w = self._adaptive.w
            sigma = ed[v1] + w * e[v1]
            _, _, Y = self._adaptive.regressor(q[v1], qd[v1], qd[v1] + sigma, qdd_ref[v1] + w * ed[v1])
            adapted[v1] = self._adaptive.adapted(theta[v1], Y, sigma, dt)
            shift[v1] = np.einsum("bip,bp->bi", Y, adapted[v1])
        out = self._output(self._solve_all(estimate, shift), estimate, tau_ff, limit, integral, residual, adapted)
        # no adaptation while the command saturates (the error then says nothing about the plant's parameters: on
        # aggressive motions of the nominal plant the payload estimate ran to its 17 kg bound in six periods)
        frozen = out.saturated.any(axis=1) | ~v1
        out.state[frozen, own:] = theta[frozen]  # type: ignore[index]
        return out


FILTER = "mpc_filter"
"""The name of `PredictiveFilter` among a loop's shadows (`mjtraj.core.laws.ESTIMATORS`)."""


def disturbance_of(state: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """(B, n) N m: protocol v2's filtered torque disturbance d in the states (B, state_size) of `mpc` or
    `mpc_filter` (`ModelPredictive.state_size`'s layout) of n joints."""
    return state[:, 1 + 4 * n:1 + 5 * n]


@dataclass
class PredictiveFilter(ModelPredictive):
    """`mpc`'s state estimate without its plan: in protocol v2's episodes the Kalman filter `mpc` plans from
    (`mjtraj.core.estimator`: the state and a torque disturbance d, N m), run on the same linearisation along the
    reference, at the cost of one filter step a period instead of a QP. It commands the linearisation's torque (the
    feedforward within the saturation) and is meant to shadow a loop (`ClosedLoop(teachers=("mpc_filter",))`), where
    its prediction counts the command the loop applied (`applied_state`) as `mpc`'s does: its estimate is then the
    one `mpc` would plan from at the same states (tested against `mpc` shadowing the same loop). A policy observes it
    (the env's `observe_disturbance`); protocol v1's episodes keep mpc's state-disturbance integrator."""

    name: ClassVar[str] = FILTER

    def __call__(self, e: NDArray[np.float64], ed: NDArray[np.float64], integral: NDArray[np.float64],
                 tau_ff: NDArray[np.float64], qdd_ref: NDArray[np.float64] | None,
                 dynamics: tuple[NDArray[np.float64], NDArray[np.float64]] | None, limit: NDArray[np.float64],
                 dt: float, *, residual: NDArray[np.float64] | None = None,
                 override: NDArray[np.float64] | None = None, state: NDArray[np.float64] | None = None,
                 q: NDArray[np.float64] | None = None, qd: NDArray[np.float64] | None = None) -> ControlOutput:
        """One period for the batch: the filter's correction and its one-step prediction under the linearisation's
        torque (B, n), N m (the command; `override` replaces it, and the prediction counts what was applied)."""
        assert state is not None and q is not None and qd is not None
        if np.all(self._plan["window"] > 0):  # protocol v2's episodes alone: the compiled filter
            out = self._compiled(state, np.concatenate([q, qd], axis=1), tau_ff, limit, integral, residual)
        else:
            out = self._numpy(state, np.concatenate([q, qd], axis=1), tau_ff, limit, integral, residual)
        if override is None:
            return out
        applied = overridden(override, limit, integral)
        assert out.state is not None
        return applied._replace(state=self.applied_state(out.state, out.dtau, applied.dtau))

    def _numpy(self, state: NDArray[np.float64], measured: NDArray[np.float64], tau_ff: NDArray[np.float64],
               limit: NDArray[np.float64], integral: NDArray[np.float64], residual: NDArray[np.float64] | None
               ) -> ControlOutput:
        """The period through `mpc`'s own code (its estimate, the prediction without a plan, its output)."""
        estimate = self._estimate(state, measured)
        ks = self._periods(estimate.counter)
        predicted = [self._predicted(b, int(ks[b]), estimate.state[b], estimate.disturbance[b],
                                     estimate.torque[b] if estimate.filtered[b] else None)
                     for b in range(estimate.state.shape[0])]
        return self._output(predicted, estimate, tau_ff, limit, integral, residual)

    def _compiled(self, state: NDArray[np.float64], measured: NDArray[np.float64], tau_ff: NDArray[np.float64],
                  limit: NDArray[np.float64], integral: NDArray[np.float64], residual: NDArray[np.float64] | None
                  ) -> ControlOutput:
        """The period through the compiled filter (`mjtraj.core.filter_kernel`), every simulation in a settle-window
        episode: the same estimate as `_numpy`'s to rounding (tested against `mpc`)."""
        from mjtraj.core.filter_kernel import filter_periods

        p = self._plan
        rows = np.arange(state.shape[0])
        ks = self._periods(state[:, :1])
        declared = p["sensor"]
        fresh = np.isnan(state[:, 1:1 + 2 * self.n]).any(axis=1)
        initial = (self.filter.initial(rows.size, declared) if fresh.any()
                   else np.empty((rows.size, self.filter.size, self.filter.size)))
        B = p["B"][rows, ks]
        out = filter_periods(state, measured, p["x"][rows, ks], p["x"][rows, ks + 1], p["A"][rows, ks], B,
                             p["c"][rows, ks], self.filter.variances(declared), initial, self.filter.process)
        planned = p["u"][rows, ks]
        command, dtau = self._saturated(planned, residual, limit)
        beyond = dtau - planned  # what the plant receives beyond the linearisation's torque: 0 unless a residual
        if np.any(beyond != 0):
            out[:, 1:1 + 2 * self.n] += np.einsum("bij,bj->bi", B, beyond)
        self._response = (rows, B)
        return ControlOutput(tau_ff, command - tau_ff, dtau, dtau != command, integral, out)

    def _predicted(self, b: int, k: int, x: NDArray[np.float64], disturbance: NDArray[np.float64],
                   torque: NDArray[np.float64] | None) -> Solved:
        """Simulation b's period k without a plan: the linearisation's torque W_k and the state the model predicts
        after it from the estimate x (2n,), `solve`'s prediction with no change v: X_{k+1} + A_k (x - X_k) + c_k
        (+ the disturbance: protocol v1's d, or B_k times protocol v2's filtered torque)."""
        p = self._plan
        n = self.n
        A, B = p["A"][b, k], p["B"][b, k]
        predicted = p["x"][b, k + 1] + A @ (x - p["x"][b, k]) + p["c"][b, k] + disturbance
        if torque is not None:
            predicted = predicted + B @ torque[:n]
        return Solved(p["u"][b, k].copy(), predicted, A, B)
