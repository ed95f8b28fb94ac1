"""Trapezoidal velocity (LSPB) planner, all joints synchronised to one blend time."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np

from mjtraj.core.planners.base import Planner, register, sampled_reference
from mjtraj.core.reference import Reference
from mjtraj.core.task import Task
from mjtraj.exceptions import InvalidInputError


@register("trapezoidal")
@dataclass(frozen=True)
class Trapezoidal(Planner):
    """Linear segment with parabolic blends (paper eq. for q(t), Siciliano et al. 2009 §4.2.1).

    Each joint cruises at V_i = cruise_factor |dq_i| / T, so every joint shares the blend time
    t_b = T (1 - 1/cruise_factor) and blend acceleration V_i / t_b. The default 1.5 gives t_b = T/3 and
    acceleration 4.5 dq / T^2. Valid factors are (1, 2]: 1 has no blend, above 2 the blends overlap.
    Piecewise as the paper: accelerate on [0, t_b), cruise on [t_b, T - t_b), decelerate on [T - t_b, T].
    """

    cruise_factor: float = 1.5
    name: ClassVar[str] = "trapezoidal"

    def __post_init__(self) -> None:
        factor = self.cruise_factor
        if not isinstance(factor, (int, float)) or not np.isfinite(factor) or not 1.0 < factor <= 2.0:
            raise InvalidInputError(
                f"cruise_factor: expected a value in (1, 2] (cruise velocity V = cruise_factor*|dq|/T must lie "
                f"in (|dq|/T, 2|dq|/T]), got {factor!r}")

    def plan(self, task: Task, model: mujoco.MjModel) -> Reference:
        """Sample the LSPB profile on the task grid; `model` is unused (kinematic planner)."""
        T = task.duration
        t = task.times
        v = self.cruise_factor / T                    # normalised cruise velocity, 1/s
        tb = T - 1.0 / v                              # blend time, s
        a = v / tb                                    # normalised blend acceleration, 1/s^2
        accel = t < tb
        decel = t >= T - tb
        cruise = ~accel & ~decel
        s = np.where(accel, 0.5 * a * t**2, np.where(cruise, v * (t - tb / 2), 1 - 0.5 * a * (T - t) ** 2))
        sd = np.where(accel, a * t, np.where(cruise, v, a * (T - t)))
        sdd = np.where(accel, a, np.where(cruise, 0.0, -a))
        return sampled_reference(self.name, task, s, sd, sdd, info={"blend_time": tb, "cruise_factor":
                                                                   self.cruise_factor})
