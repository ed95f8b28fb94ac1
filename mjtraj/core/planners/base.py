"""The planner protocol and the registry that maps names to planner classes."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any, ClassVar, Protocol, TypeVar, runtime_checkable

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.core.reference import Reference
from mjtraj.core.task import Task
from mjtraj.exceptions import InvalidInputError, MjtrajError
from mjtraj.threads import single_blas_thread


@runtime_checkable
class Planner(Protocol):
    """Anything with `plan(task, model) -> Reference`; planners hold configuration only, no state.

    `plan_many` plans several tasks, each entry the Reference or the MjtrajError its planning raised. Planners
    that derive from Planner inherit the loop below; a planner that can batch (the optimal one) overrides it.
    Use `plan_all` to call it on any planner, derived or not.
    """

    name: ClassVar[str]

    def plan(self, task: Task, model: mujoco.MjModel) -> Reference:
        """Plan `task` on the nominal `model`; samples at t_k = k task.dt, k = 0..N."""
        ...

    def plan_many(self, tasks: Sequence[Task], model: mujoco.MjModel) -> list[Reference | MjtrajError]:
        """Plan every task; a task that cannot be planned gets its error, and the others go on."""
        out: list[Reference | MjtrajError] = []
        for task in tasks:
            try:
                out.append(self.plan(task, model))
            except MjtrajError as e:
                out.append(e)
        return out


def plan_all(planner: Planner, tasks: Sequence[Task], model: mujoco.MjModel) -> list[Reference | MjtrajError]:
    """`planner.plan_many(tasks, model)`, or Planner's default loop for a planner that does not derive from it."""
    method = getattr(planner, "plan_many", None)
    if method is not None:
        return list(method(tasks, model))
    return Planner.plan_many(planner, tasks, model)


_REGISTRY: dict[str, type] = {}
_ON_REQUEST: set[str] = set()
P = TypeVar("P", bound=type)


def register(name: str, *, on_request: bool = False) -> Callable[[P], P]:
    """Class decorator: make a planner class available under `name`. A planner registered `on_request` (the slow
    nonlinear bounds) runs only when named, never in the default set of `mjtraj compare` or `render`. Its `plan` and
    `plan_many` run their BLAS on one thread (`mjtraj.threads`), however they are called."""

    def add(cls: P) -> P:
        for method in ("plan", "plan_many"):  # mjtraj's BLAS threads on every entry (mjtraj.threads)
            if callable(getattr(cls, method, None)) and not getattr(getattr(cls, method), "one_blas_thread", False):
                setattr(cls, method, single_blas_thread(getattr(cls, method)))
        _REGISTRY[name] = cls
        if on_request:
            _ON_REQUEST.add(name)
        return cls

    return add


def _with_plugins() -> dict[str, type]:
    """The registry after adding the planners of installed plug-ins (entry points `mjtraj.planners`, see
    `mjtraj.plugins`), which run only when named.

    Raises:
      PluginError: a plug-in cannot be loaded, is not a planner class, or takes a built-in planner's name.
    """
    from mjtraj.exceptions import PluginError
    from mjtraj.plugins import PLANNERS, plugins

    for name, cls in plugins(PLANNERS).items():
        if _REGISTRY.get(name) is cls:
            continue
        if name in _REGISTRY:
            raise PluginError(f"plug-in planner {name!r}: the name of a built-in planner")
        if not (isinstance(cls, type) and callable(getattr(cls, "plan", None))):
            raise PluginError(f"plug-in planner {name!r}: expected a class with plan(task, model), got {cls!r}")
        register(name, on_request=True)(cls)
    return _REGISTRY


def default_names() -> tuple[str, ...]:
    """The built-in planners that run when none are named, in registration order."""
    return tuple(name for name in _REGISTRY if name not in _ON_REQUEST)


def available() -> tuple[str, ...]:
    """Names of the registered planners (plug-ins included), in registration order."""
    return tuple(_with_plugins())


def check_name(argument: str, name: str) -> str:
    """`name` if a planner is registered under it; InvalidInputError naming `argument` and the valid names."""
    if name not in _with_plugins():
        raise InvalidInputError(f"{argument}: unknown planner {name!r}; valid: {', '.join(_REGISTRY)}")
    return name


def make(name: str, **options: Any) -> Planner:
    """Build the registered planner `name` with keyword `options`.

    Raises:
      InvalidInputError: unknown name or option (the message lists the valid ones).
    """
    check_name("planner", name)
    cls = _REGISTRY[name]
    fields = [f.name for f in dataclasses.fields(cls) if f.init] if dataclasses.is_dataclass(cls) else []
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
