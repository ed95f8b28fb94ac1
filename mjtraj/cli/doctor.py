"""`mjtraj doctor`: which OpenGL backends render here, and the library versions."""

from __future__ import annotations

import argparse
import sys
from typing import Any


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj doctor`."""
    p = sub.add_parser("doctor", help="which OpenGL backends render here, and the library versions")

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
    if not working:
        print(f"no OpenGL backend renders here: {gl.INSTALL_HINT}")
        return 1
    return 0
