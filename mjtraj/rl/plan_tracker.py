"""How a plan policy follows its plan: computed torque with gains from the score's own weights, its own estimate of
the torque disturbance, and a plan that ends at the goal at rest.

Gains. Computed torque (commanded acceleration qdd_p + u, u = kp e + kd ed, e = q_p - q) turns every joint's error
from the plan into a double integrator driven by the feedback acceleration u. Over one period dt it moves
x = (q - q_p, qd - qd_p) as x' = A x + B u, A = [[1, dt], [0, 1]], B = [dt^2 / 2, dt], and is charged x^T Q_j x
with Q_j = diag(Q_q,j, Q_qd,j) (the score's weights on joint j, Bryson's rule for the task; the score itself
measures the error from the held cubic) and R_j (M_jj u)^2, the torque u costs at the start's mass matrix M.
The `lqr` rule's gains (kp_k, kd_k) = K_k are the finite-horizon LQR's over the episode's N periods of motion and
S of the settle window: the stage weight is Q_j in the motion, `window_boost` Q_j in the window and `end_boost` Q_j
over the window's last `end_periods` periods, its position part there times `end_position`, the terminal weight
`terminal` Q_j (the at-rest rule, which the score itself does not charge). The end's stiffer weight holds the arm
where the anchor would otherwise integrate against a joint's dry friction until it breaks free, still moving when
the window ends; its stiffer position weight brings the arm into the at-rest rule's band where a fast motion leaves
it behind its plan when the window begins (docs/benchmark.md). Both cost little score, since by then the error is
small. `computed_torque` keeps CT_RULE's fixed gains (plan files of format 1).

Anchor. The torque the nominal model does not explain is subtracted from the command. `nominal` (the default)
estimates it itself: each period the nominal plant (the project's `BatchPlant` of the policy's model, as the env
steps it) is stepped from the last measured state under the last command, and the velocity it misses over the
period, times the mass matrix there, (M (qd_k - qd_pred,k) / dt), is low-passed by `anchor_gain` (d_k = d_k-1 +
gain (raw - d_k-1); 0 at an episode's start, and exactly 0 on the nominal plant without noise or actuation
delay). `mpc_filter` reads `mpc`'s filtered disturbance from the observation instead (plan files of format 1): its
estimate also holds what `mpc`'s linear prediction misses on the nominal plant, which computed torque does not
need removed.

Taper. With `taper`, the plan's offsets o(t) from the held cubic are multiplied by g(t), 1 until the motion's end T
and falling to 0 at the window's end E by the quintic smoothstep; their rates follow by the product rule
(o g, o' g + o g', o'' g + 2 o' g' + o g''), so that a plan whose offsets are a motion's position, velocity and
acceleration stays one, and ends at the goal at rest.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import choice, in_range, nonnegative_int, positive
from mjtraj.core import BatchPlant, ComputedTorque
from mjtraj.exceptions import InvalidInputError

TRACKER_RULES = ("lqr", "computed_torque")
ANCHORS = ("nominal", "mpc_filter")
LQR_FIELDS = ("window_boost", "end_boost", "end_periods", "end_position", "terminal")
"""The fields only the lqr rule's gains read."""
BEFORE = {"end_periods": 0, "end_position": 1.0}
"""Tracker fields added since plan files of format 2 were first written, with the values that tracked those files
(no end segment: the window's weight to its end; an end segment's position weighed as its velocity)."""


@dataclass(frozen=True)
class Tracker:
    """A plan policy's tracker (module docstring): its gain rule, the window's and the end's weights, the taper and
    the anchor. The defaults' weights and gain were chosen on the validation scenarios (docs/benchmark.md)."""

    rule: str = "lqr"
    window_boost: float = 3.0
    """The LQR's stage weight in the settle window over the motion's."""
    end_boost: float = 30.0
    """The LQR's stage weight over the window's last `end_periods` periods over the motion's."""
    end_periods: int = 8
    """How many of the window's last periods take `end_boost` (0: none; at most the window)."""
    end_position: float = 30.0
    """The end segment's stage weight on the position error over `end_boost`'s (its velocity weight stays
    `end_boost`'s)."""
    terminal: float = 1000.0
    """The LQR's weight on the last sample's error over the motion's stage weight."""
    taper: bool = True
    anchor: str = "nominal"
    anchor_gain: float = 1.0
    """The nominal anchor's low-pass gain per period, in (0, 1]."""

    def __post_init__(self) -> None:
        choice("tracker", self.rule, TRACKER_RULES)
        positive("window_boost", self.window_boost)
        positive("end_boost", self.end_boost)
        positive("end_position", self.end_position)
        positive("terminal", self.terminal)
        nonnegative_int("end_periods", self.end_periods)
        choice("anchor", self.anchor, ANCHORS)
        in_range("anchor_gain", self.anchor_gain, 0.0, 1.0, high_open=False)

    @classmethod
    def of_record(cls, fields: dict[str, Any]) -> Tracker:
        """The tracker a run record names; fields it lacks (written before they existed) take the values that
        tracked it then (`BEFORE`), not today's defaults."""
        return cls(**{**BEFORE, **fields})

    @classmethod
    def of_rule(cls, rule: str) -> Tracker:
        """The tracker `mjtraj rl plan --tracker RULE` gives: lqr's defaults, or computed_torque as plan files of
        format 1 were tracked (no taper, mpc_filter's anchor; no end segment, as its fixed gains ignore the
        weights)."""
        return cls() if rule == "lqr" else cls(rule, end_periods=0, taper=False, anchor="mpc_filter")

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def departures(self) -> list[str]:
        """'field value' for every field that differs from its rule's tracker (`of_rule`) and acts, in field order
        (computed_torque's fixed gains ignore the LQR's weights; no end segment ignores its weights)."""
        usual = Tracker.of_rule(self.rule).as_dict()
        idle = (set(LQR_FIELDS) if self.rule == "computed_torque" else {"end_boost", "end_position"}
                if self.end_periods == 0 else set())
        return [f"{k} {v}" for k, v in self.as_dict().items() if v != usual[k] and k not in idle]

    @property
    def settle_periods(self) -> int:
        """The fewest settle-window periods this tracker's gains need: its end segment (lqr), none (computed_torque)."""
        return self.end_periods if self.rule == "lqr" else 0

    def check_window(self, window: int) -> None:
        """Refuse (InvalidInputError naming end_periods) a settle window of `window` periods shorter than it needs."""
        if self.settle_periods > window:
            raise InvalidInputError(f"end_periods: expected at most the settle window's {window} periods, got "
                                    f"{self.end_periods}")

    def gains(self, weights: tuple[NDArray[np.float64], NDArray[np.float64]], mass: NDArray[np.float64],
              motion: int, window: int, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(kp, kd), each (motion + window + 1, n) in 1/s^2 and 1/s: the gains at every sample of an episode of
        `motion` + `window` periods of dt s, for the score's weights (diag Q (2n,), diag R (n,)) and the mass
        matrix M (n, n) at the start. The last sample repeats the one before it."""
        n = mass.shape[0]
        if self.rule == "computed_torque":
            law = ComputedTorque.for_period(dt, n)
            return np.tile(law.kp, (motion + window + 1, 1)), np.tile(law.kd, (motion + window + 1, 1))
        self.check_window(window)
        boosts, position = np.ones(motion + window), np.ones(motion + window)
        boosts[motion:] = self.window_boost
        end = motion + window - self.end_periods
        boosts[end:], position[end:] = self.end_boost, self.end_position
        return lqr_gains(weights[0][:n], weights[0][n:], weights[1] * np.diag(mass) ** 2, dt, boosts, self.terminal,
                         position)


def lqr_gains(q_position: NDArray[np.float64], q_velocity: NDArray[np.float64], r: NDArray[np.float64],
              dt: float, boosts: NDArray[np.float64], terminal: float,
              position_boosts: NDArray[np.float64] | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The finite-horizon LQR gains of n independent double integrators of period dt s (module docstring), every
    joint's 2 x 2 Riccati recursion written out elementwise: stage weights diag(q_position, q_velocity) (n,) each
    (1/rad^2, s^2/rad^2) times boosts[k] at period k (K,), the position's also times position_boosts[k] (K,; default
    1), control weight r (n,) on the feedback acceleration (s^4/rad^2), terminal weight `terminal` times the motion's
    stage weight. Returns kp (1/s^2), kd (1/s), each (K + 1, n)."""
    steps = boosts.size
    position_boosts = np.ones(steps) if position_boosts is None else np.asarray(position_boosts, dtype=np.float64)
    if position_boosts.shape != (steps,):
        raise InvalidInputError(f"position_boosts: expected one factor per period, shape ({steps},), got shape "
                                f"{position_boosts.shape}")
    b1, b2 = dt * dt / 2.0, dt
    p11, p12, p22 = terminal * q_position, np.zeros_like(q_position), terminal * q_velocity
    kp, kd = np.empty((steps + 1, r.size)), np.empty((steps + 1, r.size))
    for k in range(steps - 1, -1, -1):
        g1, g2 = b1 * p11 + b2 * p12, b1 * (dt * p11 + p12) + b2 * (dt * p12 + p22)  # B^T P A
        s = b1 * g1 + b2 * (b1 * p12 + b2 * p22) + r  # B^T P B + r
        kp[k], kd[k] = g1 / s, g2 / s
        boost = boosts[k]
        p11, p12, p22 = (boost * position_boosts[k] * q_position + p11 - g1 * g1 / s,
                         dt * p11 + p12 - g1 * g2 / s,
                         boost * q_velocity + dt * dt * p11 + 2.0 * dt * p12 + p22 - g2 * g2 / s)
    kp[steps], kd[steps] = kp[steps - 1], kd[steps - 1]
    return kp, kd


def taper(t: NDArray[np.float64], start: float, end: float) -> tuple[NDArray[np.float64], ...]:
    """g(t) (1), g'(t) (1/s), g''(t) (1/s^2), each like t (s): 1 before `start`, 0 after `end` (s), the quintic
    smoothstep between."""
    length = end - start
    s = np.clip((t - start) / length, 0.0, 1.0)
    g = 1.0 - s ** 3 * (10.0 - 15.0 * s + 6.0 * s * s)
    g1 = -30.0 * s * s * (1.0 - s) ** 2 / length
    g2 = -60.0 * s * (1.0 - s) * (1.0 - 2.0 * s) / length ** 2
    return g, g1, g2


def tapered(offsets: NDArray[np.float64], t: NDArray[np.float64], start: float, end: float
            ) -> NDArray[np.float64]:
    """(K, 3n) offsets (position, velocity, acceleration at times t (K,)) times `taper(t, start, end)`, their rates
    by the product rule."""
    n = offsets.shape[1] // 3
    o, o1, o2 = offsets[:, :n], offsets[:, n:2 * n], offsets[:, 2 * n:]
    g, g1, g2 = (v[:, None] for v in taper(t, start, end))
    return np.concatenate([g * o, g * o1 + g1 * o, g * o2 + 2.0 * g1 * o1 + g2 * o], axis=1)


class DisturbanceObserver:
    """The nominal anchor's estimate (module docstring) for a batch of episodes: call `estimate` with each period's
    measured state, then `remember` the command; `reset` forgets the episodes that start.

    Args:
      model: the nominal model; gravity_comp, substeps: the loop's (`BatchPlant`'s arguments); gain: anchor_gain.
    """

    def __init__(self, model: Any, gravity_comp: str, substeps: int, gain: float) -> None:
        self.model, self.gravity_comp, self.substeps, self.gain = model, gravity_comp, substeps, gain
        self.dt = float(model.opt.timestep)
        self._plant: BatchPlant | None = None
        self._known = np.zeros(0, dtype=bool)

    def reset(self, starts: NDArray[np.bool_]) -> None:
        """Episodes `starts` (bool (B,)) begin: no last period, estimate 0."""
        starts = np.asarray(starts, dtype=bool)
        if self._known.size != starts.size:
            rows, n = starts.size, self.model.nv
            self._plant = BatchPlant(self.model, rows, gravity_comp=self.gravity_comp, substeps=self.substeps)
            self._known = np.zeros(rows, dtype=bool)
            self._d, self._q, self._qd, self._u = (np.zeros((rows, n)) for _ in range(4))
            self._mass = np.zeros((rows, n, n))
        self._known &= ~starts
        self._d[starts] = 0.0

    def estimate(self, q: NDArray[np.float64], qd: NDArray[np.float64]) -> NDArray[np.float64]:
        """(B, n) N m: the disturbance estimate after measuring (q, qd) (B, n) this period."""
        if self._known.size != q.shape[0]:
            self.reset(np.ones(q.shape[0], dtype=bool))
        if self._known.any():
            assert self._plant is not None
            self._plant.reset(self._q, self._qd)
            self._plant.step(self._u)
            raw = np.einsum("bij,bj->bi", self._mass, (qd - self._plant.qvel) / self.dt)
            known = self._known
            self._d[known] += self.gain * (raw[known] - self._d[known])
        return self._d.copy()

    def remember(self, q: NDArray[np.float64], qd: NDArray[np.float64], dtau: NDArray[np.float64],
                 mass: NDArray[np.float64]) -> None:
        """The period's measured state (q rad, qd rad/s, each (B, n)), the command dtau (B, n) N m it applies and the
        mass matrix (B, n, n) kg m^2 there."""
        self._q[:], self._qd[:], self._u[:], self._mass[:] = q, qd, dtau, mass
        self._known[:] = True
