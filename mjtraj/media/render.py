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
from mjtraj.core import flange
from mjtraj.exceptions import InvalidInputError, RenderError
from mjtraj.media.gl import INSTALL_HINT, use_backend

GHOST_RGBA = (0.95, 0.55, 0.15, 0.3)
"""Colour of the reference (ghost) arm: translucent orange."""
GHOST_SCALE = 1.04
"""The ghost's geoms are this much thicker, so that it wraps the executed arm as a shell (no z-fighting)."""
RENDER_QUALITIES = ("fast", "high")
"""fast (default): no shadows, no floor reflection, no skybox, and round geoms drawn with FAST_SLICES x FAST_STACKS
facets. Software OpenGL (OSMesa) spends most of a frame on these: at 320x240, shadows and reflection cost 5 to 10
times the rest of the frame, and the facet count halves it again. high: the model's own visual settings, reflection
and skybox included, with one shadow (see HIGH_SHADOW_SIZE), for publication frames."""
HIGH_SHADOW_SIZE, HIGH_SHADOW_CLIP = 4096, 0.6
"""High frames' shadow map: at least 4096 px, its light frustum clipped to 0.6 of the model's extent, and cast by the
model's brightest shadow-casting light alone. Software OpenGL renders every shadow-casting light's map at every
frame: with the UR5's two lights at 8192 px a 640x480 frame took 0.25 s; one light at 4096 px draws the same floor
free of shadow acne (at 2048 px speckles return on the far floor) in about a third of that."""
FAST_SLICES, FAST_STACKS = 16, 8
"""Facets of round geoms in fast frames (MuJoCo's defaults: 28 and 16)."""
_FAST_OFF = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION, mujoco.mjtRndFlag.mjRND_SKYBOX)
STROBE_ALPHAS = (0.25, 1.0)
"""Strength of the first and the last pose of a stroboscopic frame (linear in between): each earlier pose is drawn
opaque with its colours this much of the way from white."""
EXECUTED_RGBA = (0.12, 0.35, 0.75, 1.0)
"""The executed flange path: solid blue."""
REFERENCE_RGBA = (0.95, 0.5, 0.1, 1.0)
"""The reference flange path and marks: orange (the ghost's hue), dashed."""


def _one_shadow(model: mujoco.MjModel) -> None:
    """Let only the brightest (largest diffuse sum) of `model`'s shadow-casting lights cast a shadow, in place."""
    casting = np.flatnonzero(model.light_castshadow)
    if casting.size > 1:
        keep = casting[np.argmax(model.light_diffuse[casting].sum(axis=1))]
        model.light_castshadow[:] = False
        model.light_castshadow[keep] = True


def framing_camera(points: NDArray[np.float64], fovy: float, aspect: float, *, pad: float = 0.0,
                   azimuth: float = 135.0, elevation: float = -20.0) -> mujoco.MjvCamera:
    """A free camera at `azimuth`, `elevation` (degrees) aimed at the centre of `points` (K, 3) m and as close as
    keeps every point in view with a 15 % margin (room for a label band), at vertical field of view `fovy`
    (degrees) and image `aspect` (width / height): each point's offset across the view (plus `pad`, m) over the
    tangent of the half field of view, plus how far it stands out towards the camera."""
    low, high = points.min(axis=0), points.max(axis=0)
    centre = (low + high) / 2
    az, el = np.radians(azimuth), np.radians(elevation)
    forward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    offsets = points - centre
    tan_v = np.tan(np.radians(fovy) / 2)
    tan_h = tan_v * aspect
    need = ((np.abs(offsets @ right) + pad) / tan_h, (np.abs(offsets @ up) + pad) / tan_v)
    distance = float(np.max(np.maximum(*need) - offsets @ forward))  # a point nearer the camera needs more room
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = centre
    cam.distance = max(1.15 * distance, 1e-3)
    cam.azimuth, cam.elevation = azimuth, elevation
    return cam


def decor_geom(scene: mujoco.MjvScene, kind: int, size: npt.ArrayLike, pos: npt.ArrayLike, mat: npt.ArrayLike,
               rgba: npt.ArrayLike) -> mujoco.MjvGeom | None:
    """Append a decor geom of type `kind` (mjtGeom) to `scene` and return it, or None if the scene is full. size,
    pos (m) and mat (3x3, row-major) as in mjv_initGeom. mjv_initGeom leaves the object type and id, the category,
    the segmentation id and the transparency flag as the scene's memory held them (an allocator's leftovers in a
    fresh scene, where a segmentation could read the geom as background): they are set here."""
    if scene.ngeom >= scene.maxgeom:
        return None
    geom = scene.geoms[scene.ngeom]
    colour = np.asarray(rgba, dtype=np.float32)
    mujoco.mjv_initGeom(geom, int(kind), np.asarray(size, dtype=np.float64), np.asarray(pos, dtype=np.float64),
                        np.asarray(mat, dtype=np.float64).ravel(), colour)
    geom.objtype, geom.objid = int(mujoco.mjtObj.mjOBJ_UNKNOWN), -1
    geom.category = int(mujoco.mjtCatBit.mjCAT_DECOR)
    geom.segid = scene.ngeom
    geom.transparent = int(colour[3] < 1)
    scene.ngeom += 1
    return geom


def _segment(scene: mujoco.MjvScene, a: NDArray[np.float64], b: NDArray[np.float64], width: float,
             rgba: tuple[float, ...]) -> None:
    """Append a capsule from a to b (m) of radius `width` to `scene`, if it has room."""
    if np.allclose(a, b):
        return
    geom = decor_geom(scene, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3), rgba)
    if geom is not None:
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, width, a, b)


def _sphere(scene: mujoco.MjvScene, at: NDArray[np.float64], radius: float, rgba: tuple[float, ...]) -> None:
    """Append a sphere at `at` (m) to `scene`, if it has room."""
    decor_geom(scene, mujoco.mjtGeom.mjGEOM_SPHERE, np.full(3, radius), at, np.eye(3), rgba)


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
        model = copy.copy(model)  # the caller's model keeps its visual settings
        if self.quality == "fast":
            model.vis.quality.numslices = min(int(model.vis.quality.numslices), FAST_SLICES)
            model.vis.quality.numstacks = min(int(model.vis.quality.numstacks), FAST_STACKS)
        else:
            model.vis.quality.shadowsize = max(int(model.vis.quality.shadowsize), HIGH_SHADOW_SIZE)
            model.vis.map.shadowclip = min(float(model.vis.map.shadowclip), HIGH_SHADOW_CLIP)
            _one_shadow(model)
        try:
            self._renderer = mujoco.Renderer(model, self.height, self.width)
        except Exception as e:  # the GL backends raise many kinds
            raise RenderError(f"cannot open an off-screen OpenGL context with the {backend!r} backend: "
                              f"{type(e).__name__}: {e}. {INSTALL_HINT}") from e
        if self.quality == "fast":
            for flag in _FAST_OFF:
                self._renderer.scene.flags[flag] = False
        _LIVE.add(self)

    def _scene_at(self, q: npt.ArrayLike) -> None:
        """The renderer's scene: the arm at q (rad), seen through this renderer's view."""
        self._data.qpos[:] = vector("q", q, self.model.nq)
        mujoco.mj_kinematics(self.model, self._data)
        mujoco.mj_camlight(self.model, self._data)
        self._renderer.update_scene(self._data, self._view)

    def frame(self, q: npt.ArrayLike, q_ref: npt.ArrayLike | None = None) -> NDArray[np.uint8]:
        """The image, shape (height, width, 3) uint8, of the arm at q (rad) and the ghost at q_ref (if given)."""
        self._scene_at(q)
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

    def frame_motion(self, poses: npt.ArrayLike) -> None:
        """Aim the free camera (`camera="free"`, or a model without the camera asked for) at everything the arm's
        moving geoms sweep through at `poses` (P, nq), rad, framed as the snapshot strip is (`framing_camera`),
        instead of at the whole model at rest (its scene included): the arm stays in view and fills the frame. A
        camera of the model is left as it is."""
        if self.camera != FREE_CAMERA:
            return
        points = np.vstack([self.body_positions(pose, moving=True) for pose in np.asarray(poses, dtype=np.float64)])
        self._view = framing_camera(points, float(self.model.vis.global_.fovy), self.width / self.height)

    def strobe(self, poses: npt.ArrayLike, executed_path: npt.ArrayLike, reference_path: npt.ArrayLike,
               reference_marks: npt.ArrayLike, *, frame: npt.ArrayLike | None = None) -> NDArray[np.uint8]:
        """A stroboscopic frame for a paper figure: the arm at each of `poses` (P, nq) rad in one image, the last
        opaque and the earlier ones fading (STROBE_ALPHAS), on a white background without the floor; the executed
        flange path `executed_path` (K, 3) m as a solid blue line, the reference's `reference_path` (K, 3) as a
        dashed orange line over it and `reference_marks` (P, 3) as orange dots at the poses' times, so that the two
        stay distinguishable where they coincide. The camera frames everything drawn (`framing_camera`), or the
        points `frame` (K, 3) m: panels that share them share their scale."""
        q = np.asarray(poses, dtype=np.float64)
        exec_path = np.asarray(executed_path, dtype=np.float64)
        ref_path = np.asarray(reference_path, dtype=np.float64)
        marks = np.asarray(reference_marks, dtype=np.float64)
        points = (np.vstack([self.body_positions(pose) for pose in q] + [exec_path, ref_path]) if frame is None
                  else np.asarray(frame, dtype=np.float64))
        camera = framing_camera(points, float(self.model.vis.global_.fovy), self.width / self.height)
        option = mujoco.MjvOption()
        option.geomgroup[:] = 1
        self._data.qpos[:] = q[-1]
        mujoco.mj_kinematics(self.model, self._data)
        mujoco.mj_camlight(self.model, self._data)
        self._renderer.update_scene(self._data, camera, option)
        scene = self._renderer.scene
        self._drop_planes(scene)
        alphas = np.linspace(STROBE_ALPHAS[0], STROBE_ALPHAS[1], len(q))
        for pose, alpha in zip(q[:-1], alphas[:-1], strict=True):
            self._ghost.qpos[:] = pose
            mujoco.mj_kinematics(self.model, self._ghost)
            first = scene.ngeom
            mujoco.mjv_addGeoms(self.model, self._ghost, option, self._perturb, mujoco.mjtCatBit.mjCAT_DYNAMIC, scene)
            for i in range(first, scene.ngeom):  # opaque, paler the earlier: translucency would blend with the
                rgba = scene.geoms[i].rgba      # black the scene is drawn on before the background turns white
                rgba[:3] = 1.0 - alpha * (1.0 - rgba[:3])
                rgba[3] = 1.0
        width = 0.004 * float(self.model.stat.extent)
        for a, b in zip(exec_path[:-1], exec_path[1:], strict=True):
            _segment(scene, a, b, width, EXECUTED_RGBA)
        for k, (a, b) in enumerate(zip(ref_path[:-1], ref_path[1:], strict=True)):
            if k % 2 == 0:  # dashes
                _segment(scene, a, b, 1.6 * width, REFERENCE_RGBA)
        for point in marks:
            _sphere(scene, point, 3.5 * width, REFERENCE_RGBA)
        rgb = self._renderer.render().copy()
        self._renderer.enable_segmentation_rendering()
        try:
            segmentation = self._renderer.render()
        finally:
            self._renderer.disable_segmentation_rendering()
        objid, objtype = segmentation[..., 0], segmentation[..., 1]
        floor = (objtype == int(mujoco.mjtObj.mjOBJ_GEOM)) & np.isin(objid, self._planes)
        rgb[((objid < 0) & (objtype < 0)) | floor] = 255
        return rgb

    def flange_position(self, q: npt.ArrayLike) -> NDArray[np.float64]:
        """The flange's world position at joint positions q (rad), m, shape (3,) (FLANGE_RULE's point)."""
        self._ghost.qpos[:] = vector("q", q, self.model.nq)
        mujoco.mj_kinematics(self.model, self._ghost)
        body, point = flange(self.model)
        return self._ghost.xpos[body] + self._ghost.xmat[body].reshape(3, 3) @ point  # type: ignore[no-any-return]

    def body_positions(self, q: npt.ArrayLike, *, moving: bool = False) -> NDArray[np.float64]:
        """The corners of the bounding boxes of the model's geoms but planes at q (rad), in the world, shape
        (8 K, 3), m: what a frame of the arm must show (`moving`: only the geoms the joints move, not the scene's);
        for an arm without such geoms (a URDF of inertias only) the origins of its bodies, shape (B - 1, 3)."""
        self._ghost.qpos[:] = vector("q", q, self.model.nq)
        mujoco.mj_kinematics(self.model, self._ghost)
        keep = self.model.geom_type != mujoco.mjtGeom.mjGEOM_PLANE
        if moving:
            keep &= self.model.body_weldid[self.model.geom_bodyid] != 0
        solid = np.flatnonzero(keep)
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
        if solid.size == 0:
            return self._ghost.xpos[1:].copy()  # type: ignore[no-any-return]
        out = []
        for g in solid:
            centre, half = self.model.geom_aabb[g, :3], self.model.geom_aabb[g, 3:]
            local = centre + signs * half
            out.append(self._ghost.geom_xpos[g] + local @ self._ghost.geom_xmat[g].reshape(3, 3).T)
        return np.vstack(out)

    @property
    def _planes(self) -> NDArray[np.intp]:
        """Ids of the model's plane geoms (the floor)."""
        return np.flatnonzero(self.model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE)

    @staticmethod
    def _drop_planes(scene: mujoco.MjvScene) -> None:
        """Make the scene's planes (the floor) invisible: a paper figure's white background."""
        for i in range(scene.ngeom):
            if scene.geoms[i].type == mujoco.mjtGeom.mjGEOM_PLANE:
                scene.geoms[i].rgba[3] = 0.0

    def depth(self, q: npt.ArrayLike) -> NDArray[np.float32]:
        """The depth image of the arm at q (rad), no ghost: distances from the camera, shape (height, width), m."""
        self._scene_at(q)
        self._renderer.enable_depth_rendering()
        try:
            return self._renderer.render()
        finally:
            self._renderer.disable_depth_rendering()

    def geoms(self, q: npt.ArrayLike) -> NDArray[np.int32]:
        """The geom seen at each pixel with the arm at q (rad), no ghost: its id, -1 where none; shape (height,
        width): a mask of any part of the scene (the arm's bodies: `model.geom_bodyid[ids] > 0`)."""
        self._scene_at(q)
        self._renderer.enable_segmentation_rendering()
        try:
            seen = self._renderer.render()
        finally:
            self._renderer.disable_segmentation_rendering()
        return np.where(seen[:, :, 1] == int(mujoco.mjtObj.mjOBJ_GEOM), seen[:, :, 0], -1).astype(np.int32)

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
