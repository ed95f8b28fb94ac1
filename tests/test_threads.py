"""mjtraj owns its BLAS threads: one inside its calls, the caller's count outside them, and the same bits from every
entry point at any OPENBLAS_NUM_THREADS."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from mjtraj.core.planners.base import register
from mjtraj.core.reference import Reference
from mjtraj.threads import one_blas_thread


def blas_threads() -> list[int]:
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


@dataclass(frozen=True)
class _Spy:
    """A planner that records the BLAS thread counts it ran under."""

    seen: list

    def plan(self, task, model) -> Reference:
        self.seen.append(blas_threads())
        raise NotImplementedError


def test_a_registered_planner_runs_on_one_thread_and_the_callers_count_is_restored(task, model):
    import scipy.linalg  # noqa: F401  (its BLAS too)

    cls = register("_thread_spy")(_Spy)
    try:
        spy = cls([])
        with threadpool_limits(limits=2, user_api="blas"):
            before = blas_threads()
            with pytest.raises(NotImplementedError):
                spy.plan(task, model)
            assert blas_threads() == before
        assert spy.seen == [[1] * len(before)]
        assert 2 in before  # the caller's count really differed
    finally:
        from mjtraj.core.planners import base

        base._REGISTRY.pop("_thread_spy")


def test_nested_calls_keep_the_limit_and_the_outer_exit_restores():
    with threadpool_limits(limits=2, user_api="blas"):
        with one_blas_thread():
            with one_blas_thread():
                assert set(blas_threads()) == {1}
            assert set(blas_threads()) == {1}
        assert 2 in blas_threads()


def test_two_python_threads_keep_the_limit_until_the_last_returns(monkeypatch):
    """A BLAS has one thread count per process: the limit is set by the first call to enter (in any Python thread)
    and lifted by the last to leave, so a thread that leaves first cannot lift it under a thread still inside, nor
    leave the process limited (a per-thread count did both). Oracle: a recording controller in place of
    threadpoolctl's (which itself ignores the calls of threads other than the one that controls OpenBLAS)."""
    import threading

    import mjtraj.threads as threads

    events = []

    class Limiter:
        def __init__(self):
            events.append(("limit", threading.current_thread().name))

        def restore_original_limits(self):
            events.append(("restore", threading.current_thread().name))

    class Controller:
        def limit(self, *, limits):
            assert limits == 1
            return Limiter()

    monkeypatch.setattr(threads, "_controller", lambda libraries: Controller())
    inside, leave = threading.Event(), threading.Event()

    def first():
        with one_blas_thread():
            inside.set()
            leave.wait(10)

    worker = threading.Thread(target=first, name="first")
    worker.start()
    assert inside.wait(10)
    with one_blas_thread():
        leave.set()
        worker.join(10)
        assert events == [("limit", "first")]  # the first to leave lifted nothing
    assert events == [("limit", "first"), ("restore", "MainThread")]
    with one_blas_thread(), one_blas_thread():
        pass
    assert events[2:] == [("limit", "MainThread"), ("restore", "MainThread")]


HASHES = r"""
import hashlib, sys
import numpy as np
entry = sys.argv[1]
if entry == "api":
    import mjtraj
    s = mjtraj.load_scenario()
    ref = s.planner("nonlinear_optimal").plan(s.task, s.model)
    data = ref.q.tobytes() + ref.qd.tobytes()
elif entry == "env":
    import gymnasium as gym
    import mjtraj.envs  # noqa: F401
    env = gym.make("UR5Track-v0", planner="nonlinear_optimal", task="paper")
    env.reset(seed=0)
    done, parts = False, []
    while not done:
        obs, r, term, trunc, info = env.step(np.zeros(3))
        parts.append(np.float64(r).tobytes())
        done = term or trunc
    data = b"".join(parts) + env.unwrapped.reference.q.tobytes()
else:
    from mjtraj.cli import main
    import contextlib, io, json
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        main(["compare", "--planners", "nonlinear_optimal", "--json", "--no-figures", "--out", sys.argv[2]])
    def untimed(x):  # wall-clock times aside
        if isinstance(x, dict):
            return {k: untimed(v) for k, v in x.items() if not k.endswith("_time")}
        return [untimed(v) for v in x] if isinstance(x, list) else x
    data = json.dumps(untimed(json.loads(out.getvalue())), sort_keys=True).encode()
print(hashlib.sha256(data).hexdigest())
"""


@pytest.mark.slow
@pytest.mark.parametrize("entry", ["api", "env", "cli"])
def test_the_same_bits_at_any_blas_thread_count(entry, tmp_path):
    """The nonlinear planner's plan, an env episode on it and compare's output hash the same at 1, 2 and 4 BLAS
    threads (before the limit, the plan's last bits followed the count)."""
    hashes = set()
    for threads in ("1", "2", "4"):
        env = {**os.environ, "OPENBLAS_NUM_THREADS": threads, "MKL_NUM_THREADS": threads}
        run = subprocess.run([sys.executable, "-c", HASHES, entry, str(tmp_path / threads)], env=env,
                             capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, run.stderr
        hashes.add(run.stdout.strip().splitlines()[-1])
    assert len(hashes) == 1, hashes
    assert np.all([len(h) == 64 for h in hashes])
