"""Off-screen OpenGL backend selection: MUJOCO_GL, else OSMesa when libOSMesa is present, else EGL.

MuJoCo reads MUJOCO_GL once, when `mujoco` is first imported; `mjtraj/__init__.py` therefore calls
`select_backend` before it imports mujoco.
"""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys

BACKENDS = ("osmesa", "egl", "glfw")
INSTALL_HINT = ("install an off-screen OpenGL library: OSMesa (Debian/Ubuntu: apt-get install libosmesa6) or EGL "
                "(apt-get install libegl1, with a GPU driver or Mesa), or set MUJOCO_GL to a backend that works here")
_LIBRARIES = {"osmesa": ("OSMesa",), "egl": ("EGL",), "glfw": ("glfw", "GL")}


def library_present(backend: str) -> bool:
    """Whether the shared library `backend` needs can be found (it may still fail to open a context)."""
    return any(ctypes.util.find_library(name) for name in _LIBRARIES[backend])


def default_backend() -> str | None:
    """The backend mjtraj picks when MUJOCO_GL is unset: 'osmesa', else 'egl', else None."""
    for backend in ("osmesa", "egl"):
        if library_present(backend):
            return backend
    return None


def select_backend() -> str | None:
    """Set MUJOCO_GL to the default backend unless the user set it; return the backend in force (None: none)."""
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen.lower()
    backend = default_backend()
    if backend is not None and "mujoco" not in sys.modules:
        os.environ["MUJOCO_GL"] = backend
    return backend


def active_backend() -> str:
    """The backend MuJoCo loaded at import ('glfw' when MUJOCO_GL was unset then)."""
    from mujoco.rendering.classic import gl_context

    return getattr(gl_context, "_MUJOCO_GL", "") or "glfw"


_PROBE = """
import mujoco
m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size="0.1"/></worldbody></mujoco>')
r = mujoco.Renderer(m, 24, 32)
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
r.update_scene(d)
img = r.render()
r.close()
print(int(img.max()))
"""


def probe_backend(backend: str, *, timeout: float = 60.0) -> tuple[bool, str]:
    """Try to render one small frame with `backend` in a fresh interpreter; (works, detail)."""
    env = {**os.environ, "MUJOCO_GL": backend}
    env.pop("PYOPENGL_PLATFORM", None)
    try:
        done = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                              timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return False, f"timed out after {timeout:.0f} s"
    if done.returncode == 0 and done.stdout.strip().isdigit() and int(done.stdout.strip()) > 0:
        return True, "renders"
    lines = [line for line in (done.stderr or done.stdout).strip().splitlines() if line.strip()]
    return False, lines[-1] if lines else f"exit code {done.returncode}"
