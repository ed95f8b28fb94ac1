"""Quintic polynomial planner: q = q0 + dq (10 s^3 - 15 s^4 + 6 s^5), s = t / T."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import mujoco

from mjtraj.core.planners.base import Planner, register, sampled_reference
from mjtraj.core.reference import Reference
from mjtraj.core.task import Task


@register("quintic")
@dataclass(frozen=True)
class Quintic(Planner):
    """Rest-to-rest quintic: zero boundary velocities and accelerations."""

    name: ClassVar[str] = "quintic"

    def plan(self, task: Task, model: mujoco.MjModel) -> Reference:
        """Sample the quintic on the task grid; `model` is unused (kinematic planner)."""
        T = task.duration
        s = task.times / T
        return sampled_reference(self.name, task, 10 * s**3 - 15 * s**4 + 6 * s**5,
                                 (30 * s**2 - 60 * s**3 + 30 * s**4) / T,
                                 (60 * s - 180 * s**2 + 120 * s**3) / T**2)
