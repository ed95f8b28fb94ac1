"""`mjtraj doctor`: which OpenGL backends render here, the library versions, and (--warm-up) numba's kernels."""

from __future__ import annotations

import argparse
import sys
from typing import Any


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj doctor`."""
    p = sub.add_parser("doctor", help="which OpenGL backends render here, and the library versions")
    p.add_argument("--warm-up", action="store_true",
                   help="also compile the nonlinear planners' numba kernels once (one small nonlinear plan; tens of "
                   "seconds the first time in an installation, under a second once cached) and say how long it took "
                   "and where they are cached")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from mjtraj.media import gl
    from mjtraj.versions import versions

    print("versions: " + ", ".join(f"{k} {v}" for k, v in versions().items()))
    user = gl.user_backend()
    chosen = user or gl.default_backend()
    print(f"python {sys.version.split()[0]}; MUJOCO_GL set by you: {user or '(unset)'}; renderers use: "
          f"{chosen or 'none found'}" + ("" if user else " (mjtraj's choice when MUJOCO_GL is unset: OSMesa if "
                                         "libOSMesa is present, else EGL)"))
    working = []
    for backend in gl.BACKENDS:
        ok, detail = gl.probe_backend(backend) if gl.library_present(backend) else (False, "library not found")
        print(f"  {backend:<7} {'works' if ok else 'fails'}: {detail}")
        if ok:
            working.append(backend)
    if args.warm_up:
        warm_up()
    if not working:
        print(f"no OpenGL backend renders here: {gl.INSTALL_HINT}")
        return 1
    return 0


def warm_up() -> None:
    """Print what `mjtraj.core.planners.warm_up.warm_up` did."""
    from mjtraj.core.planners.warm_up import warm_up as run_warm_up

    print("numba kernels: compiling or loading (one small nonlinear plan) ...", flush=True)
    done = run_warm_up()
    where = (f"cached {done.choice.where} ({done.choice.folder})" if done.choice.folder is not None else
             "not cached: no folder can be written; set NUMBA_CACHE_DIR")
    print(f"numba kernels: ready in {done.seconds:.1f} s ({done.compiled} compiled, {done.loaded} loaded from the "
          f"cache); {where}")
