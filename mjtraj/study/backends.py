"""Where a sweep's units run: in this process, on a local process pool, or on a Ray cluster.

A backend maps `run_unit` over units and yields the results in unit order, so that the file is written in the
same order whichever backend computes it.
"""

from __future__ import annotations

import collections
import contextlib
import itertools
import multiprocessing
import os
import socket
from collections.abc import Iterator, Sequence
from typing import Any

from mjtraj.exceptions import BackendError, InvalidInputError
from mjtraj.study.sweep import SweepSettings, UnitResult, run_unit

BACKENDS = ("local", "ray")


def _exit_with(parent: int) -> None:
    """Worker initializer: end this process as soon as the sweep that started it is gone (a kill -9 of the parent
    leaves no orphan workers behind)."""
    import threading
    import time

    def watch() -> None:
        while True:
            if os.getppid() != parent:
                os._exit(1)
            time.sleep(0.5)

    threading.Thread(target=watch, name="mjtraj-parent-watch", daemon=True).start()


def _run(settings_dict: dict[str, Any], unit: tuple[str, int]) -> UnitResult:
    """run_unit from plain data (what crosses process and machine boundaries, pickled)."""
    return run_unit(SweepSettings(**settings_dict), unit)


def _import_ray():  # noqa: ANN202
    try:
        import ray
    except ImportError as e:
        raise BackendError("backend 'ray' needs Ray: pip install 'mjtraj[ray]'") from e
    return ray


def check_backend(backend: str, ray_address: str | None) -> None:
    """Everything about the backend that can be checked before a file is written.

    Raises:
      InvalidInputError: unknown backend, or a Ray address without the Ray backend.
      BackendError: Ray is not installed, or nothing answers at `ray_address` (see check_ray_address).
    """
    if backend not in BACKENDS:
        raise InvalidInputError(f"backend: unknown value {backend!r}; valid: {', '.join(BACKENDS)}")
    if backend == "local" and ray_address is not None:
        raise InvalidInputError("ray_address: only meaningful with --backend ray")
    if backend == "ray":
        _import_ray()
        check_ray_address(ray_address)


AHEAD = 2
"""Units in flight per worker: the driver submits at most AHEAD x workers units beyond the one it waits for, and
keeps no unit once it has handed its result on, so its memory does not grow with the sweep."""


def local_map(settings: SweepSettings, units: Sequence[tuple[str, int]], workers: int) -> Iterator[UnitResult]:
    """Units on `workers` processes (1: this process), results in order, at most AHEAD x workers in flight."""
    if workers <= 1 or len(units) <= 1:
        for unit in units:
            yield run_unit(settings, unit)
        return
    from concurrent.futures import ProcessPoolExecutor

    data = settings.as_dict()
    context = multiprocessing.get_context("spawn")  # no fork of a process that may hold MuJoCo threads
    todo = iter(units)
    window: collections.deque[Any] = collections.deque()
    with ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_exit_with,
                             initargs=(os.getpid(),)) as pool:

        def fill() -> None:
            with _one_blas_thread():  # workers start on submission
                for unit in itertools.islice(todo, AHEAD * workers - len(window)):
                    window.append(pool.submit(_run, data, unit))

        fill()
        try:
            while window:
                result = window.popleft().result()
                fill()
                yield result
        finally:
            for future in window:
                future.cancel()


BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def _one_blas_thread() -> Iterator[None]:
    """While a pool starts its workers (spawned processes inherit the environment), ask their BLAS for one thread
    each unless the user set a count: the workers already fill the cores, and a second BLAS thread per worker made
    the planners' dense solves several times slower (SLSQP's step 85 ms instead of 2 ms beside a second busy
    process). This process's BLAS, already loaded, is not affected; the environment is restored on leaving."""
    saved = {name: os.environ.get(name) for name in BLAS_THREAD_VARIABLES}
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def check_ray_address(address: str | None, timeout: float = 5.0) -> None:
    """Fail fast, before anything is written, when a Ray address names a host:port that does not answer.

    Raises:
      BackendError: the address is malformed or nothing listens there.
    """
    if address is None or address in ("auto", "local"):
        return
    target = address.split("://", 1)[-1]
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit():
        raise BackendError(f"ray_address: expected HOST:PORT or ray://HOST:PORT, got {address!r}")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            pass
    except OSError as e:
        raise BackendError(f"ray_address: cannot reach a Ray cluster at {address} ({e.strerror or e}); start one "
                           f"with `ray start --head` there, or leave out --ray-address to start a local one") from e


def ray_map(settings: SweepSettings, units: Sequence[tuple[str, int]], address: str | None,
            workers: int) -> Iterator[UnitResult]:
    """Units as Ray tasks (one CPU each) on the cluster at `address` (None: a local instance with `workers`
    CPUs), results in order. The cluster's nodes need this provenance (`mjtraj.versions.provenance`): mjtraj at this
    version and commit, the same libraries, BLAS and CPU model (`run_sweep` refuses a unit computed otherwise)."""
    ray = _import_ray()
    started = not ray.is_initialized()
    if started:
        try:
            if address is None:
                ray.init(num_cpus=max(1, workers), include_dashboard=False, log_to_driver=False,
                         runtime_env={"env_vars": {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa")}})
            else:
                ray.init(address=address, log_to_driver=False)
        except Exception as e:  # noqa: BLE001 - Ray raises ConnectionError, RuntimeError, ...
            raise BackendError(f"ray_address: cannot connect to Ray at {address or 'a new local instance'}: "
                               f"{' '.join(str(e).split())}") from e
    try:
        task = ray.remote(num_cpus=1)(_run)
        data = settings.as_dict()
        todo = iter(units)
        window: collections.deque[Any] = collections.deque()
        ahead = AHEAD * max(workers, int(ray.cluster_resources().get("CPU", workers)))
        window.extend(task.remote(data, unit) for unit in itertools.islice(todo, ahead))
        while window:  # in order, at most `ahead` tasks in flight; a result handed on is dropped
            result = ray.get(window.popleft())
            window.extend(task.remote(data, unit) for unit in itertools.islice(todo, ahead - len(window)))
            yield result
    finally:
        if started:
            ray.shutdown()


def backend_map(backend: str, settings: SweepSettings, units: Sequence[tuple[str, int]], *, workers: int,
                ray_address: str | None = None) -> Iterator[UnitResult]:
    """The results of `units` on `backend`, in order. Call `check_backend` first: here a bad backend or address
    shows only when the iteration starts."""
    if backend == "local":
        return local_map(settings, units, workers)
    return ray_map(settings, units, ray_address, workers)
