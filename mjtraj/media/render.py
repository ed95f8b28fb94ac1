"""Off-screen frames of the arm at its executed pose, with the reference pose as a translucent ghost."""

from __future__ import annotations

import atexit
import copy
import weakref
from types import TracebackType

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.checks import choice, positive_int, vector
from mjtraj.exceptions import InvalidInputError, RenderError
from mjtraj.media.gl import INSTALL_HINT, use_backend

GHOST_RGBA = (0.95, 0.55, 0.15, 0.3)
"""Colour of the reference (ghost) arm: translucent orange."""
GHOST_SCALE = 1.04
"""The ghost's geoms are this much thicker, so that it wraps the executed arm as a shell (no z-fighting)."""
RENDER_QUALITIES = ("fast", "high")
"""fast (default): no shadows, no floor reflection, and round geoms drawn with FAST_SLICES x FAST_STACKS facets.
Software OpenGL (OSMesa) spends most of a frame on these: at 320x240, shadows and reflection cost 5 to 10 times the
rest of the frame, and the facet count halves it again. high: the model's own visual settings, shadows and
reflection included, for publication frames."""
FAST_SLICES, FAST_STACKS = 16, 8
"""Facets of round geoms in fast frames (MuJoCo's defaults: 28 and 16)."""
_FAST_OFF = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION)


_LIVE: weakref.WeakSet[ArmRenderer] = weakref.WeakSet()
"""Renderers not closed yet: closed at interpreter exit, while ctypes and OpenGL can still free their contexts
(left to garbage collection at shutdown, OSMesa's free fails with a ctypes traceback)."""


@atexit.register
def _close_live() -> None:
    for renderer in list(_LIVE):
        renderer.close()


def cameras(model: mujoco.MjModel) -> tuple[str, ...]:
    """Names of the model's cameras."""
    return tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_CAMERA, i) for i in range(model.ncam))


FREE_CAMERA = "free"
"""A camera every model has: MuJoCo's free camera aimed at the model's centre from 1.6 times its extent, azimuth
135 degrees, elevation -20 degrees. The default camera 'front' falls back to it on a model without a 'front'."""
DEFAULT_CAMERA = "front"


def free_camera(model: mujoco.MjModel) -> mujoco.MjvCamera:
    """FREE_CAMERA of `model`."""
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = model.stat.center
    cam.distance = 1.6 * float(model.stat.extent)
    cam.azimuth, cam.elevation = 135.0, -20.0
    return cam


def check_render_options(model: mujoco.MjModel, width: int, height: int, camera: str) -> tuple[int, int, str]:
    """Validate an image size against the offscreen buffer and a camera name (one of the model's, or
    FREE_CAMERA; the default 'front' falls back to FREE_CAMERA on a model without it); return them (no GL
    needed)."""
    width, height = positive_int("width", width), positive_int("height", height)
    valid = (*cameras(model), FREE_CAMERA)
    if camera == DEFAULT_CAMERA and camera not in valid:
        camera = FREE_CAMERA
    if camera not in valid:
        raise InvalidInputError(f"camera: unknown camera {camera!r}; valid: {', '.join(valid)} (the model's "
                                f"cameras, and {FREE_CAMERA!r}, a free camera framed on the model)")
    for name, size, limit, attribute in (("width", width, model.vis.global_.offwidth, "offwidth"),
                                         ("height", height, model.vis.global_.offheight, "offheight")):
        if size > limit:
            raise InvalidInputError(
                f"{name}: expected at most the offscreen buffer's {limit} pixels, got {size}; raise it with "
                f"the MJCF attribute <visual><global {attribute}=\"{size}\"/></visual>")
    return width, height, camera


class ArmRenderer:
    """Renders `model` at joint positions q, optionally with a ghost arm at q_ref; close() it (or use `with`).

    Args:
      width, height: image size in pixels, at most the model's offscreen buffer
        (MJCF `<visual><global offwidth=... offheight=...>`).
      camera: one of the model's named cameras, or FREE_CAMERA.
      quality: one of RENDER_QUALITIES.
    """

    def __init__(self, model: mujoco.MjModel, *, width: int = 640, height: int = 480, camera: str = "front",
                 quality: str = "fast") -> None:
        self.width, self.height, self.camera = check_render_options(model, width, height, camera)
        self._view: str | mujoco.MjvCamera = free_camera(model) if self.camera == FREE_CAMERA else self.camera
        self.quality = choice("quality", quality, RENDER_QUALITIES)
        self.model = model
        self._data = mujoco.MjData(model)
        self._ghost = mujoco.MjData(model)
        self._option = mujoco.MjvOption()
        self._perturb = mujoco.MjvPerturb()
        backend = use_backend()
        if self.quality == "fast":
            model = copy.copy(model)  # the caller's model keeps its visual settings
            model.vis.quality.numslices = min(int(model.vis.quality.numslices), FAST_SLICES)
            model.vis.quality.numstacks = min(int(model.vis.quality.numstacks), FAST_STACKS)
        try:
            self._renderer = mujoco.Renderer(model, self.height, self.width)
        except Exception as e:  # the GL backends raise many kinds
            raise RenderError(f"cannot open an off-screen OpenGL context with the {backend!r} backend: "
                              f"{type(e).__name__}: {e}. {INSTALL_HINT}") from e
        if self.quality == "fast":
            for flag in _FAST_OFF:
                self._renderer.scene.flags[flag] = False
        _LIVE.add(self)

    def frame(self, q: npt.ArrayLike, q_ref: npt.ArrayLike | None = None) -> NDArray[np.uint8]:
        """The image, shape (height, width, 3) uint8, of the arm at q (rad) and the ghost at q_ref (if given)."""
        self._data.qpos[:] = vector("q", q, self.model.nq)
        mujoco.mj_kinematics(self.model, self._data)
        mujoco.mj_camlight(self.model, self._data)
        self._renderer.update_scene(self._data, self._view)
        if q_ref is not None:
            self._ghost.qpos[:] = vector("q_ref", q_ref, self.model.nq)
            mujoco.mj_kinematics(self.model, self._ghost)
            scene = self._renderer.scene
            first = scene.ngeom
            mujoco.mjv_addGeoms(self.model, self._ghost, self._option, self._perturb,
                                mujoco.mjtCatBit.mjCAT_DYNAMIC, scene)
            for i in range(first, scene.ngeom):
                scene.geoms[i].rgba[:] = GHOST_RGBA
                scene.geoms[i].size[:] *= GHOST_SCALE
        return self._renderer.render()

    def depth(self, q: npt.ArrayLike) -> NDArray[np.float32]:
        """The depth image of the arm at q (rad), no ghost: distances from the camera, shape (height, width), m."""
        self._data.qpos[:] = vector("q", q, self.model.nq)
        mujoco.mj_kinematics(self.model, self._data)
        mujoco.mj_camlight(self.model, self._data)
        self._renderer.update_scene(self._data, self._view)
        self._renderer.enable_depth_rendering()
        try:
            return self._renderer.render()
        finally:
            self._renderer.disable_depth_rendering()

    def close(self) -> None:
        """Free the GL context (OSMesa complains at interpreter exit otherwise)."""
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.close()
            self._renderer = None

    def __enter__(self) -> ArmRenderer:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()
