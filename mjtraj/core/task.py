"""A point-to-point joint-space motion: start, goal, duration and control period."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.checks import frozen, positive, vector
from mjtraj.core.model import JointInfo
from mjtraj.exceptions import InvalidInputError

MAX_STEPS = 100_000
"""Most control periods a task may have (a 100 s motion at 1 ms): each execution records 8 arrays of N x n floats."""


@dataclass(frozen=True)
class Task:
    """Move from `q0` to `qg` (rad, shape (n,)) in `duration` s, sampled every `dt` s.

    The duration must be a whole number of control periods: N = duration / dt steps, N+1 samples.
    Use `Task.create` to normalise and validate inputs; `check_limits` validates against a model.
    """

    q0: NDArray[np.float64]
    qg: NDArray[np.float64]
    duration: float
    dt: float

    @classmethod
    def create(cls, q0: npt.ArrayLike, qg: npt.ArrayLike, duration: float, dt: float, *,
               model: mujoco.MjModel | None = None, n: int | None = None) -> Task:
        """Validate and build a task of `n` joints (default: the model's, else len(q0)); with `model`, also
        check the joint ranges."""
        size = model.nq if model is not None else (n if n is not None else int(np.size(q0)))
        task = cls(frozen(vector("q0", q0, size)), frozen(vector("qg", qg, size)),
                   positive("duration", duration), positive("dt", dt))
        _ = task.steps  # validates the grid
        if model is not None:
            task.check_limits(model)
        return task

    def __post_init__(self) -> None:
        if self.q0.shape != self.qg.shape or self.q0.ndim != 1:
            raise InvalidInputError(f"qg: expected shape {self.q0.shape} like q0, got {self.qg.shape}")

    @property
    def steps(self) -> int:
        """N, the number of control periods."""
        ratio = self.duration / self.dt
        if ratio > MAX_STEPS:
            raise InvalidInputError(f"duration, dt: expected at most MAX_STEPS = {MAX_STEPS} control periods, got "
                                    f"{self.duration} s / {self.dt} s = {ratio:.6g}")
        steps = round(ratio)
        if steps < 1 or abs(ratio - steps) > 1e-9 * max(1.0, ratio):
            raise InvalidInputError(f"duration: expected a whole number of control periods dt={self.dt} s, "
                                    f"got {self.duration} s ({ratio:.6g} periods)")
        return steps

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.q0.size

    @property
    def times(self) -> NDArray[np.float64]:
        """Sample times t_k = k dt, k = 0..N; shape (N+1,), s."""
        return np.arange(self.steps + 1, dtype=np.float64) * self.dt

    @property
    def displacement(self) -> NDArray[np.float64]:
        """qg - q0; shape (n,), rad."""
        return self.qg - self.q0

    def check_limits(self, model: mujoco.MjModel, joints: JointInfo | None = None) -> None:
        """Raise InvalidInputError if q0 or qg lies outside the model's joint ranges (`joints`: those of `model`,
        when already read)."""
        joints = JointInfo.of(model) if joints is None else joints
        if self.n != joints.n:
            raise InvalidInputError(f"q0: expected {joints.n} values ({', '.join(joints.names)}), got {self.n}")
        for label, q in (("q0", self.q0), ("qg", self.qg)):
            bad = np.flatnonzero((q < joints.lower) | (q > joints.upper))
            if bad.size:
                j = int(bad[0])
                raise InvalidInputError(
                    f"{label}: joint '{joints.names[j]}' = {float(q[j])!r} rad is outside its range "
                    f"[{float(joints.lower[j])!r}, {float(joints.upper[j])!r}]")


UNLIMITED_RANGE = np.pi
"""rad: random tasks draw a joint without a range (a continuous joint) in [-UNLIMITED_RANGE, UNLIMITED_RANGE]."""


def random_task(rng: np.random.Generator, model: mujoco.MjModel, *, max_displacement: float, duration: float,
                dt: float) -> Task:
    """A start uniform in the joint ranges and a goal uniform in the ranges within +-max_displacement (rad) of
    it, per joint: two draws of n uniforms from `rng`. A joint without a range (continuous) is drawn in
    [-pi, pi] (UNLIMITED_RANGE)."""
    joints = JointInfo.of(model)
    lower = np.where(np.isfinite(joints.lower), joints.lower, -UNLIMITED_RANGE)
    upper = np.where(np.isfinite(joints.upper), joints.upper, UNLIMITED_RANGE)
    q0 = rng.uniform(lower, upper)
    low = np.maximum(lower, q0 - max_displacement)
    high = np.minimum(upper, q0 + max_displacement)
    return Task.create(q0, rng.uniform(low, high), duration, dt)
