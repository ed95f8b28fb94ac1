"""Jerk-limited S-curve planner (ruckig), the profile industrial controllers use, synchronised to the duration T."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np

from mjtraj.core.planners.base import Planner, register, sampled_reference
from mjtraj.core.reference import Reference
from mjtraj.core.scoring import JOINT_SPEED_LIMIT
from mjtraj.core.task import Task
from mjtraj.exceptions import InfeasibleError, InvalidInputError, SolverError

LIMIT_RULE = ("every joint follows q = q0 + dq s(t), s a rest-to-rest jerk-limited profile from 0 to 1 in exactly T "
              "(ruckig, minimum duration T). Limits on s: speed pi / max|dq| (the UR5's joint speed limit on the "
              "joint that moves most); acceleration 6/T^2 (the cubic's peak: no more than the minimum-effort "
              "profile asks, since the UR5 publishes no acceleration limit); jerk 60/T^3 (each jerk phase lasts at "
              "least T/10)")


@register("scurve")
@dataclass(frozen=True)
class SCurve(Planner):
    """Rest-to-rest jerk-limited profile from ruckig, all joints synchronised, duration exactly T (LIMIT_RULE).

    Attributes:
      acceleration_factor: the acceleration limit on s is acceleration_factor / T^2 (default 6, the cubic's peak).
      jerk_factor: the jerk limit on s is jerk_factor / T^3 (default 60).
      speed_limit: the joint speed limit, rad/s (default pi, the UR5's).
    """

    acceleration_factor: float = 6.0
    jerk_factor: float = 60.0
    speed_limit: float = float(JOINT_SPEED_LIMIT)
    name: ClassVar[str] = "scurve"

    def __post_init__(self) -> None:
        for key in ("acceleration_factor", "jerk_factor", "speed_limit"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
                raise InvalidInputError(f"{key}: expected a positive number, got {value!r}")

    def limits(self, task: Task) -> tuple[float, float, float]:
        """(speed, acceleration, jerk) limits on the normalised profile s, in 1/s, 1/s^2, 1/s^3."""
        move = float(np.max(np.abs(task.displacement)))
        T = task.duration
        return self.speed_limit / move, self.acceleration_factor / T**2, self.jerk_factor / T**3

    def plan(self, task: Task, model: mujoco.MjModel) -> Reference:
        """Sample the profile on the task grid; `model` is unused (kinematic planner).

        Raises:
          InfeasibleError: the limits cannot complete the move in T (names the limit).
          SolverError: ruckig returned an error (its result code).
        """
        from ruckig import InputParameter, Result, Ruckig, Trajectory

        n = task.steps + 1
        if not np.any(task.displacement):
            zero = np.zeros(n)
            return sampled_reference(self.name, task, zero, zero, zero, info={"duration": task.duration})
        speed, acceleration, jerk = self.limits(task)
        inp = InputParameter(1)
        inp.current_position, inp.target_position = [0.0], [1.0]
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [speed], [acceleration], [jerk]
        inp.minimum_duration = task.duration
        trajectory = Trajectory(1)
        result = Ruckig(1).calculate(inp, trajectory)
        if result != Result.Working:
            raise SolverError(f"scurve: ruckig failed with result {result.name} ({int(result)}) for speed "
                              f"{speed:.4g} 1/s, acceleration {acceleration:.4g} 1/s^2, jerk {jerk:.4g} 1/s^3")
        if trajectory.duration > task.duration * (1 + 1e-9):
            joint = int(np.argmax(np.abs(task.displacement)))
            raise InfeasibleError(f"scurve: the limits need {trajectory.duration:.4g} s for the move, more than T = "
                                  f"{task.duration:.4g} s (joint {joint} moves {task.displacement[joint]:.4g} rad at "
                                  f"most {self.speed_limit:.4g} rad/s); lengthen the duration or raise the limits")
        samples = np.array([trajectory.at_time(min(float(t), trajectory.duration)) for t in task.times])[:, :, 0]
        samples[-1] = (1.0, 0.0, 0.0)  # the end, exactly
        return sampled_reference(self.name, task, samples[:, 0], samples[:, 1], samples[:, 2],
                                 info={"duration": float(trajectory.duration), "speed_limit_s": speed,
                                       "acceleration_limit_s": acceleration, "jerk_limit_s": jerk})
