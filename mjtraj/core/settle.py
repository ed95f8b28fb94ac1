"""Arrive and stop (protocol v2, docs/design.md "The settle window"): the episode goes on after the motion, the
reference holding the goal, and succeeds only if the arm is at rest at the goal when the window ends.

J_exec (`mjtraj.core.scoring`) sums over the motion's periods k < N and never scores the state the motion ends in;
a law can then save torque by arriving late and still moving. Protocol v2 scores the episode: the motion's N periods
and the settle window's S periods that follow, every one with the same Q_exec and R_exec. Its score is called
J_settle; the paper's J_exec, Table I and the planner study are untouched (they run no window).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.core.reference import Reference
from mjtraj.core.rollout import Rollout
from mjtraj.core.task import Task
from mjtraj.exceptions import InvalidInputError

SETTLE_WINDOW = 0.5
"""s: how long the reference holds the goal after the motion (25 periods at 0.02 s). Rule: long enough for a loop
with the gain rule's bandwidth (omega = 2 pi / (20 dt), a time constant of 3.2 periods at damping ratio 1) to
decay through about 8 time constants from an error at the motion's end, short beside the motions (0.5 to 2 s)."""
SETTLE_BAND = 0.02
"""The settling band: every joint within this fraction of the move (the task's largest joint displacement) of the
goal, the control engineer's 2 % settling criterion."""
SETTLE_SPEED = 0.05
"""rad/s: every joint slower than this at the window's end (about 3 deg/s). For scale, on protocol v2's held-out
nominal episodes the adaptive law ends at a mean of 3.6e-4 rad/s and cubic + PID at 0.013 (docs/results/v2)."""
SETTLE_METRICS = ("cost_position", "cost_velocity", "cost_torque", "cost_motion", "end_err", "end_speed",
                  "settle_time")
"""What a protocol-v2 row adds to the metrics (which it computes over the whole episode, motion and window, so its
`cost` is J_settle): J_settle's three parts (position, velocity and torque sums, their total `cost`), J_exec over
the motion alone (`cost_motion`, the paper's score of the same execution), the largest joint error (rad) and speed
(rad/s) at the window's end, and the settling time: how long after the motion's end (s) the last joint entered the
settling band for good (NaN if it never did)."""
SETTLE_UNITS = {"cost_position": "-", "cost_velocity": "-", "cost_torque": "-", "cost_motion": "-", "end_err": "rad",
                "end_speed": "rad/s", "settle_time": "s"}


@dataclass(frozen=True)
class Settle:
    """One episode's settle window: its motion's N periods, the window's S, the goal q_g (n,) rad and the move
    (the task's largest joint displacement, rad; the band and the speed limit follow the module's rule)."""

    motion_steps: int
    window_steps: int
    goal: NDArray[np.float64]
    move: float

    @classmethod
    def of(cls, task: Task, motion_steps: int, window_steps: int) -> Settle:
        """The window of an episode of `task` whose motion runs `motion_steps` periods: its goal and move."""
        return cls(motion_steps, window_steps, task.qg, float(np.max(np.abs(task.displacement))))

    @property
    def band(self) -> float:
        """The settling band, rad: SETTLE_BAND of the move."""
        return SETTLE_BAND * self.move


def window_steps(window: float, dt: float) -> int:
    """The settle window of `window` seconds in periods of `dt` (a whole number of them, or InvalidInputError)."""
    if not (np.isfinite(window) and window >= 0):
        raise InvalidInputError(f"settle: expected a window >= 0 s, got {window!r}")
    steps = round(window / dt)
    if abs(steps * dt - window) > 1e-9 * max(1.0, window):
        raise InvalidInputError(f"settle: expected a whole number of control periods of {dt} s, got {window} s")
    return steps


def held(reference: Reference, steps: int, goal: npt.ArrayLike | None = None) -> Reference:
    """`reference` followed by `steps` periods that hold `goal` (default its last pose) at rest: q = goal, qd = qdd =
    0, u_plan 0 (the corrective torque that holds a gravity-compensated arm still). The motion's samples are kept
    as they are; info gains motion_steps and settle_steps."""
    if steps == 0:
        return reference
    n = reference.n
    pose = reference.q[-1] if goal is None else np.asarray(goal, dtype=np.float64).reshape(n)
    t = np.concatenate([reference.t, reference.t[-1] + reference.dt * np.arange(1, steps + 1)])
    rest = np.zeros((steps, n))
    q = np.concatenate([reference.q, np.tile(pose, (steps, 1))])
    qd = np.concatenate([reference.qd, rest])
    qdd = np.concatenate([reference.qdd, rest])
    u_plan = None if reference.u_plan is None else np.concatenate([reference.u_plan, rest])
    info = {**reference.info, "motion_steps": reference.steps, "settle_steps": steps}
    return Reference(reference.planner, t, q, qd, qdd, u_plan, info)


def with_window(task: Task, reference: Reference, steps: int) -> tuple[Reference, Settle | None]:
    """An episode of `task` along `reference` (its motion) with a settle window of `steps` periods: the reference
    holding the task's goal for them (`held`) and the window (`Settle.of`); without a window (0) `reference` as it is
    and None."""
    if not steps:
        return reference, None
    return held(reference, steps, task.qg), Settle.of(task, reference.steps, steps)


def settle_arrays(rollout: Rollout, q_diag: npt.ArrayLike, r_diag: npt.ArrayLike, settles: list[Settle]
                  ) -> dict[str, NDArray[np.float64]]:
    """SETTLE_METRICS of every execution of `rollout` (B episodes of the same motion_steps + window_steps
    periods), with J_exec's diagonal weights ((2n,) or (B, 2n); (n,) or (B, n)): name -> shape (B,).

    The parts sum over the episode, k < N + S; cost_motion over k < N. The settling time is measured on the state
    at the start of every period of the episode and at its end (q_final): the least t such that every later sample
    lies within the band of the goal, minus the motion's duration, 0 if the motion already ended inside it.
    """
    steps = rollout.e.shape[1]
    motion = {s.motion_steps for s in settles}
    if len(motion) != 1 or any(s.motion_steps + s.window_steps != steps for s in settles):
        raise InvalidInputError(f"settles: expected episodes of one motion length whose motion and window make the "
                                f"rollout's {steps} periods, got {sorted(motion)}")
    N = motion.pop()
    n = rollout.e.shape[2]
    q = np.broadcast_to(np.asarray(q_diag, dtype=np.float64), (rollout.e.shape[0], 2 * n))
    r = np.broadcast_to(np.asarray(r_diag, dtype=np.float64), (rollout.e.shape[0], n))
    e2, ed2, u2 = np.square(rollout.e), np.square(rollout.ed), np.square(rollout.dtau)
    position = np.sum(e2 * q[:, None, :n], axis=(-2, -1))
    velocity = np.sum(ed2 * q[:, None, n:], axis=(-2, -1))
    torque = np.sum(u2 * r[:, None, :], axis=(-2, -1))
    x2 = np.concatenate([e2[:, :N], ed2[:, :N]], axis=-1)
    cost_motion = np.sum(x2 * q[:, None, :], axis=(-2, -1)) + np.sum(u2[:, :N] * r[:, None, :], axis=(-2, -1))
    goal = np.array([s.goal for s in settles])
    band = np.array([s.band for s in settles])
    end_err = np.max(np.abs(goal - rollout.q_final), axis=-1)
    end_speed = np.max(np.abs(rollout.qd_final), axis=-1)
    poses = np.concatenate([rollout.q, rollout.q_final[:, None, :]], axis=1)  # (B, N + S + 1, n)
    outside = np.any(np.abs(poses - goal[:, None, :]) > band[:, None, None], axis=-1)
    last = np.where(outside.any(axis=1), steps + 1 - np.argmax(outside[:, ::-1], axis=1), 0)  # first in for good
    settle_time = np.where(outside[:, -1], np.nan, np.maximum(last - N, 0) * rollout.dt)
    return {"cost_position": position, "cost_velocity": velocity, "cost_torque": torque, "cost_motion": cost_motion,
            "end_err": end_err, "end_speed": end_speed, "settle_time": settle_time}


def unsettled(end_err: float, end_speed: float, settle: Settle) -> str:
    """Why an episode ending `end_err` (rad) from its goal at `end_speed` (rad/s, both the largest joint's) is not at
    rest at the goal ('' if it is: within the band and below SETTLE_SPEED)."""
    reasons = []
    if not end_err <= settle.band:
        reasons.append(f"end error {end_err:.3g} rad > {SETTLE_BAND:g} x the move ({settle.band:.3g} rad)")
    if not end_speed <= SETTLE_SPEED:
        reasons.append(f"end speed {end_speed:.3g} rad/s > {SETTLE_SPEED:g} rad/s")
    return "; ".join(reasons)
