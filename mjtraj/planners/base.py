"""The planner protocol and the registry that maps names to planner classes."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Protocol, TypeVar, runtime_checkable

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.exceptions import InvalidInputError
from mjtraj.reference import Reference
from mjtraj.task import Task


@runtime_checkable
class Planner(Protocol):
    """Anything with `plan(task, model) -> Reference`; planners hold configuration only, no state."""

    name: str

    def plan(self, task: Task, model: mujoco.MjModel) -> Reference:
        """Plan `task` on the nominal `model`; samples at t_k = k task.dt, k = 0..N."""
        ...


_REGISTRY: dict[str, type] = {}
P = TypeVar("P", bound=type)


def register(name: str) -> Callable[[P], P]:
    """Class decorator: make a planner class available under `name`."""

    def add(cls: P) -> P:
        _REGISTRY[name] = cls
        return cls

    return add


def available() -> tuple[str, ...]:
    """Names of the registered planners, in registration order."""
    return tuple(_REGISTRY)


def make(name: str, **options: Any) -> Planner:
    """Build the registered planner `name` with keyword `options`.

    Raises:
      InvalidInputError: unknown name or option (the message lists the valid ones).
    """
    if name not in _REGISTRY:
        raise InvalidInputError(f"planner: unknown planner {name!r}; valid: {', '.join(_REGISTRY)}")
    cls = _REGISTRY[name]
    fields = [f.name for f in dataclasses.fields(cls) if f.init]
    unknown = sorted(set(options) - set(fields))
    if unknown:
        raise InvalidInputError(f"planner {name!r}: unknown option {unknown[0]!r}; valid: "
                                f"{', '.join(fields) if fields else '(none)'}")
    planner: Planner = cls(**options)
    return planner


def sampled_reference(name: str, task: Task, s_q: NDArray[np.float64], s_qd: NDArray[np.float64],
                      s_qdd: NDArray[np.float64], **extra: Any) -> Reference:
    """Reference q = q0 + dq*s(t) from a time-scaling s sampled on the task grid.

    Args:
      s_q, s_qd, s_qdd: s(t_k), s'(t_k) in 1/s, s''(t_k) in 1/s^2; shape (N+1,) each.
    """
    dq = task.displacement
    return Reference(planner=name, t=task.times, q=task.q0 + np.outer(s_q, dq), qd=np.outer(s_qd, dq),
                     qdd=np.outer(s_qdd, dq), **extra)
