"""Off-screen OpenGL backend: the user's MUJOCO_GL if set, else OSMesa when libOSMesa is present, else EGL.

Nothing happens at import. MuJoCo reads MUJOCO_GL once, when `mujoco` is first imported; when it was unset then
(MuJoCo picked GLFW, which needs a display), `use_backend` installs the chosen off-screen context class in
MuJoCo's renderer when the first ArmRenderer is made. A MUJOCO_GL the user set is never overridden.
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
_chosen: list[str] = []
"""The backend use_backend installed in this process (at most one entry)."""


def library_present(backend: str) -> bool:
    """Whether the shared library `backend` needs can be found (it may still fail to open a context)."""
    return any(ctypes.util.find_library(name) for name in _LIBRARIES[backend])


def default_backend() -> str | None:
    """The backend mjtraj picks when MUJOCO_GL is unset: 'osmesa', else 'egl', else None."""
    for backend in ("osmesa", "egl"):
        if library_present(backend):
            return backend
    return None


def user_backend() -> str | None:
    """MUJOCO_GL as the user set it (lower case), or None."""
    value = os.environ.get("MUJOCO_GL", "").strip().lower()
    return value or None


def use_backend() -> str:
    """Make MuJoCo's renderer use the backend in force and return its name: the user's MUJOCO_GL, else (once per
    process) the default backend, else 'glfw' (MuJoCo's own default, which needs a display)."""
    user = user_backend()
    if user is not None:
        return user
    if _chosen:
        return _chosen[0]
    backend = default_backend()
    if backend is None:
        return "glfw"
    from mujoco.rendering.classic import gl_context

    if backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco.egl import GLContext
    gl_context.GLContext = GLContext  # type: ignore[attr-defined]
    _chosen.append(backend)
    return backend


def active_backend() -> str:
    """The backend renderers of this process use (or would use): see `use_backend`."""
    return user_backend() or (_chosen[0] if _chosen else default_backend() or "glfw")


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
