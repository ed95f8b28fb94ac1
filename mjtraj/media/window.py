"""`render_mode="human"`: the arm and its ghost reference in a window, the Gymnasium way (its MuJoCo WindowViewer,
on GLFW). It needs a display; on a server without one, use render_mode="rgb_array" or run under Xvfb."""

from __future__ import annotations

import atexit
import os
import sys
import weakref
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from mjtraj.checks import vector
from mjtraj.exceptions import RenderError
from mjtraj.media.gl import user_backend
from mjtraj.media.render import GHOST_RGBA, GHOST_SCALE, decor_geom

_LIVE: weakref.WeakSet[HumanViewer] = weakref.WeakSet()
"""Windows not closed yet: closed at interpreter exit (mjtraj.media.render's exit hook closes them too)."""


def check_display() -> None:
    """RenderError (one line, saying what to do) unless a window can be opened here: a display on Linux, and no
    off-screen MUJOCO_GL (OSMesa or EGL cannot show a window)."""
    backend = user_backend()
    if backend is not None and backend != "glfw":
        raise RenderError(f"render_mode='human' opens a window with GLFW, but MUJOCO_GL={backend} selects an "
                          "off-screen backend; unset MUJOCO_GL (or set it to glfw), or use render_mode='rgb_array'")
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RenderError("render_mode='human' needs a display, and DISPLAY is not set: on a server use "
                          "render_mode='rgb_array' (frames, RecordVideo), or run under a virtual display (xvfb-run)")


def _visual_size(kind: int, size: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """A model geom's size (radius, half-length, ...) as an mjvGeom's (its three half-extents)."""
    if kind in (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER):
        return np.array([size[0], size[0], size[1]])
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return np.full(3, size[0])
    return np.asarray(size, dtype=np.float64)


class HumanViewer:
    """A window showing `model` at joint positions q and, translucent, the reference pose q_ref (the ghost)."""

    def __init__(self, model: mujoco.MjModel, *, width: int = 640, height: int = 480) -> None:
        check_display()
        from gymnasium.envs.mujoco.mujoco_rendering import WindowViewer

        self.model = model
        self._data = mujoco.MjData(model)
        self._ghost = mujoco.MjData(model)
        try:
            self._viewer: Any = WindowViewer(model, self._data, width=width, height=height)
        except Exception as e:  # GLFW raises many kinds
            raise RenderError(f"render_mode='human': cannot open a window: {type(e).__name__}: {e}") from e
        # the ghost's geoms go into the scene through MuJoCo's mjv_initGeom: Gymnasium before 1.2 writes its markers
        # field by field in the layout of MuJoCo < 3.2, which corrupts the scene of a newer MuJoCo
        self._viewer._add_marker_to_scene = self._add_ghost_geom  # type: ignore[method-assign]
        self._moving = np.flatnonzero(model.geom_bodyid > 0)
        _LIVE.add(self)

    def _add_ghost_geom(self, marker: dict[str, Any]) -> None:
        """One marker of `show` (type, size, pos, mat, rgba) as a geom of the window's scene."""
        scene = self._viewer.scn
        if decor_geom(scene, int(marker["type"]), marker["size"], marker["pos"], marker["mat"],
                      marker["rgba"]) is None:
            raise RenderError(f"render_mode='human': the scene is full ({scene.maxgeom} geoms)")

    def show(self, q: npt.ArrayLike, q_ref: npt.ArrayLike | None = None) -> None:
        """Draw the arm at q (rad) and the ghost at q_ref (if given) in the window."""
        self._data.qpos[:] = vector("q", q, self.model.nq)
        mujoco.mj_kinematics(self.model, self._data)
        if q_ref is not None:
            self._ghost.qpos[:] = vector("q_ref", q_ref, self.model.nq)
            mujoco.mj_kinematics(self.model, self._ghost)
            for g in self._moving:
                self._viewer.add_marker(type=int(self.model.geom_type[g]), pos=self._ghost.geom_xpos[g].copy(),
                                        mat=self._ghost.geom_xmat[g].copy(), label="",
                                        size=GHOST_SCALE * _visual_size(int(self.model.geom_type[g]),
                                                                        self.model.geom_size[g]),
                                        rgba=np.array(GHOST_RGBA, dtype=np.float32))
        self._viewer.make_context_current()  # an off-screen renderer may have made its own current since
        self._viewer.render()

    def close(self) -> None:
        """Close the window."""
        viewer = getattr(self, "_viewer", None)
        if viewer is not None:
            viewer.close()
            self._viewer = None


@atexit.register
def _close_live() -> None:
    for viewer in list(_LIVE):
        viewer.close()
