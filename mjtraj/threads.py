"""mjtraj's own BLAS threads: its computations on small matrices run their BLAS on one thread, whatever the
environment says, scoped to mjtraj's calls so that a caller's other numerical work keeps its threads.

Why (docs/design.md, "Threads"): mjtraj's matrices are small (a few hundred rows at most), so a second BLAS thread
buys nothing and, on a machine whose other core is busy, costs 8 to 10 times (the linear optimal plan took 7.95 ms
instead of 0.93 ms); and the nonlinear planners' iterates depend on the BLAS's summation order, which depends on its
thread count, so a plan made from Python and the same plan made by the CLI differed in their last bits. Parallelism
stays across scenarios (sweep workers), where it pays.

The limit is set with threadpoolctl on every BLAS loaded when an mjtraj call begins (NumPy's and SciPy's OpenBLAS,
MKL), and the caller's counts are restored when the last call returns: the limit is process-wide (a BLAS has one
thread count), so it is counted process-wide, under a lock. Nested calls and calls from several Python threads keep
the limit until the last of them returns (about 8 us a call); a per-thread count let a thread that returned first
restore the counts under another thread still inside, and that one then left the process at one thread. Where a
BLAS keeps a count per thread (an OpenMP build of OpenBLAS, MKL) the restore runs in whichever thread leaves last;
threadpoolctl itself applies OpenBLAS limits from one controlling thread only.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

_lock = threading.Lock()
_active = 0
"""How many mjtraj calls are inside `one_blas_thread` now, over every Python thread (the limit is set by the first
and lifted by the last)."""
_limiter: Any = None
"""threadpoolctl's limiter while `_active` > 0: it restores the counts it found."""


@functools.cache
def _controller(libraries: frozenset[str]) -> Any:
    """threadpoolctl's controller over the BLAS libraries loaded now (`libraries`: the modules that can load one)."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController().select(user_api="blas")


def _loaded() -> frozenset[str]:
    """The BLAS-loading modules imported so far: the controller is made again when one more has loaded its BLAS."""
    import sys

    return frozenset(name for name in ("numpy", "scipy.linalg", "torch") if name in sys.modules)


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with every loaded BLAS on one thread; the counts found by the first of the calls inside (in any
    Python thread) are restored when the last returns (re-entrant, thread-safe)."""
    global _active, _limiter
    import scipy.linalg  # noqa: F401  (SciPy carries a BLAS of its own: load it before the controller lists them)

    with _lock:
        if _active == 0:
            _limiter = _controller(_loaded()).limit(limits=1)
        _active += 1
    try:
        yield
    finally:
        with _lock:
            _active -= 1
            if _active == 0:
                _limiter.restore_original_limits()
                _limiter = None


def single_blas_thread(function: F) -> F:
    """Decorator: `function` runs under `one_blas_thread`."""

    @functools.wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with one_blas_thread():
            return function(*args, **kwargs)

    wrapper.one_blas_thread = True  # type: ignore[attr-defined]
    return wrapper  # type: ignore[return-value]
