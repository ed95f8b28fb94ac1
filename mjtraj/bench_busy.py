"""`mjtraj bench busy`: the library timed the way a Python user runs it, on a quiet machine and with one core taken.

Each measurement is a fresh interpreter that calls the public API (`mjtraj.load_scenario()`,
`scenario.planner(name).plan(task, model)`, `gym.make("UR5Track-v1")`) with the BLAS thread variables the user's
environment has, minus the CLI's own (`mjtraj` sets OPENBLAS_NUM_THREADS=1 for its commands; a script does not).
It runs twice in the same bench run: once quiet, once beside a helper process spinning on one core. The ratio busy
over quiet is the number to watch: mjtraj runs its BLAS on one thread (mjtraj.threads), so it stays near 1.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

HELD_OUT_TASK = ((0.5, -2.0, 1.2), (-0.6, -1.1, 2.3))
"""q0 and qg (rad) of a task outside the paper's, planned over the paper's duration (the one the issue measured)."""
PLANNERS = ("optimal", "nonlinear_min_effort", "nonlinear_optimal")
"""What `api_timings` plans on HELD_OUT_TASK."""

_CHILD = "import json; from mjtraj.bench_busy import api_timings; print(json.dumps(api_timings()))"
_SPIN = "while True:\n    pass"


def api_timings(*, repeats: int = 21, slow_repeats: int = 3, env_steps: int = 500) -> dict[str, float]:
    """Median seconds per plan of each of PLANNERS on HELD_OUT_TASK (`repeats` plans of the linear one,
    `slow_repeats` of the nonlinear ones, after one untimed plan each) and seconds per `env.step` of UR5Track-v1
    (median of 5 passes of `env_steps` steps), all through the public API in this process."""
    import gymnasium as gym
    import numpy as np

    import mjtraj
    from mjtraj.core.task import Task

    scenario = mjtraj.load_scenario()
    model = scenario.model
    task = Task.create(*HELD_OUT_TASK, scenario.task.duration, scenario.task.dt, model=model)
    out: dict[str, float] = {}
    for name in PLANNERS:
        planner = scenario.planner(name)
        planner.plan(task, model)
        times = []
        for _ in range(repeats if name == "optimal" else slow_repeats):
            start = time.perf_counter()
            planner.plan(task, model)
            times.append(time.perf_counter() - start)
        out[name] = float(np.median(times))
    env = gym.make("UR5Track-v1")
    passes = []
    for episode in range(5):
        env.reset(seed=episode)
        action = np.zeros(3)
        start = time.perf_counter()
        for _ in range(env_steps):
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        passes.append((time.perf_counter() - start) / env_steps)
    env.close()
    out["env.step"] = float(np.median(passes))
    return out


def user_environment() -> dict[str, str]:
    """This process's environment without the BLAS thread counts the CLI set for itself (a user's own count, set
    before `mjtraj` started, is kept: the CLI only sets them when absent, and records that in MJTRAJ_SET_THREADS)."""
    env = dict(os.environ)
    for name in os.environ.get("MJTRAJ_SET_THREADS", "").split(","):
        if name:
            env.pop(name, None)
    return env


@contextmanager
def busy_core() -> Iterator[None]:
    """A helper process spinning on one core for the block's duration."""
    spinner = subprocess.Popen([sys.executable, "-c", _SPIN])
    try:
        yield
    finally:
        spinner.kill()
        spinner.wait()


def _child() -> dict[str, float]:
    done = subprocess.run([sys.executable, "-c", _CHILD], env=user_environment(), capture_output=True, text=True,
                          check=True)
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def bench_busy() -> list[dict[str, Any]]:
    """Per timed call: seconds quiet, seconds with one core busy, and their ratio (see the module docstring)."""
    quiet = _child()
    with busy_core():
        busy = _child()
    return [{"call": name, "quiet_s": quiet[name], "busy_s": busy[name], "ratio": busy[name] / quiet[name]}
            for name in quiet]
