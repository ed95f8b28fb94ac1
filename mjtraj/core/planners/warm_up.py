"""Compile the numba kernels (the nonlinear planners', and `mpc_filter`'s) ahead of their first use (`mjtraj doctor
--warm-up`)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from mjtraj.core.model import load_model
from mjtraj.core.planners import make, shooting, tracking, tree_dynamics
from mjtraj.core.planners.numba_cache import CHOICE, CacheChoice
from mjtraj.core.task import Task

WARM_UP_TASK = ((0.0, -1.5707963267948966, 0.0), (0.3, -1.2707963267948966, 0.3), 0.5)
"""q0, qg (rad) and duration (s) of the plan that `warm_up` makes on the shipped UR5 at dt = 0.02 s: a small move."""


@dataclass(frozen=True)
class WarmUp:
    """What `warm_up` did.

    Attributes:
      seconds: wall time of the plan and the gains, s (compilation or loading included).
      compiled: kernels numba compiled (its cache misses: a kernel called from another is compiled into it).
      loaded: kernels loaded from the cache (its cache hits).
      choice: where they are cached.
    """

    seconds: float
    compiled: int
    loaded: int
    choice: CacheChoice


def kernels() -> dict[str, Any]:
    """Every numba dispatcher of the kernel modules, by module.function."""
    from numba.core.dispatcher import Dispatcher

    from mjtraj.core import filter_kernel

    return {f"{module.__name__.rsplit('.', 1)[-1]}.{name}": value
            for module in (tree_dynamics, shooting, tracking, filter_kernel) for name, value in vars(module).items()
            if isinstance(value, Dispatcher)}


def warm_up() -> WarmUp:
    """Compile every kernel, or load it from the cache: one nonlinear_optimal plan of WARM_UP_TASK (the dynamics'
    derivatives, the RK4 steps and the sensitivities) and one set of tracking gains (the Riccati recursion the
    tracked start and the line search use). The first call in an installation takes tens of seconds; a later
    process's, under a second."""
    model = load_model()
    q0, qg, duration = WARM_UP_TASK
    task = Task.create(q0, qg, duration, 0.02, model=model)
    before = _counts()
    start = time.perf_counter()
    make("nonlinear_optimal").plan(task, model)
    n = task.n
    tracking.tracking_gains(np.tile(np.eye(2 * n), (2, 1, 1)), np.zeros((2, 2 * n, n)), np.eye(2 * n), np.eye(n))
    _filter_period(n)
    seconds = time.perf_counter() - start
    compiled, loaded = (a - b for a, b in zip(_counts(), before, strict=True))
    return WarmUp(seconds, compiled, loaded, CHOICE)


def _filter_period(n: int) -> None:
    """One period of `mpc_filter`'s compiled filter (`mjtraj.core.filter_kernel`) from a fresh state, at rest."""
    from mjtraj.core.filter_kernel import filter_periods

    m = 3 * n
    state = np.zeros((1, 1 + 5 * n + m * m))
    state[:, 1:1 + 2 * n] = np.nan
    x = np.zeros((1, 2 * n))
    filter_periods(state, x, x, x, np.eye(2 * n)[None], np.zeros((1, 2 * n, n)), x, np.ones((1, 2 * n)),
                   np.eye(m)[None], np.ones(m))


def _counts() -> tuple[int, int]:
    """Kernel signatures compiled (cache misses) and loaded (cache hits) so far in this process."""
    stats = [k.stats for k in kernels().values()]
    return sum(sum(s.cache_misses.values()) for s in stats), sum(sum(s.cache_hits.values()) for s in stats)
