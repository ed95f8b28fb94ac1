"""Cubic polynomial planner: q = q0 + dq (3 s^2 - 2 s^3), s = t / T."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import mujoco

from mjtraj.core.planners.base import Planner, register, sampled_reference
from mjtraj.core.reference import Reference
from mjtraj.core.task import Task


@register("cubic")
@dataclass(frozen=True)
class Cubic(Planner):
    """Rest-to-rest cubic: zero boundary velocities, acceleration jumps at both ends."""

    name: ClassVar[str] = "cubic"

    def plan(self, task: Task, model: mujoco.MjModel) -> Reference:
        """Sample the cubic on the task grid; `model` is unused (kinematic planner)."""
        T = task.duration
        s = task.times / T
        return sampled_reference(self.name, task, 3 * s**2 - 2 * s**3, (6 * s - 6 * s**2) / T,
                                 (6 - 12 * s) / T**2)
