"""`mjtraj render`: execution videos per planner, a side-by-side clip of up to four, and the paper's Fig. 1
snapshot strip."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mjtraj.domain.comparison import Comparison
from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path
from mjtraj.media.render import ArmRenderer

VIDEO_FORMATS = ("mp4", "gif")
SNAPSHOT_TIMES = (0.0, 0.25, 0.5, 0.75, 1.0)
"""Fractions of T at which the snapshot strip shows each planner."""
STRIP_PANEL = (480, 400)
"""Smallest panel of the snapshot strip, px (a paper figure's; larger video frames give larger panels, up to the
model's offscreen buffer)."""
GIF_COLORS = 128
"""Colours of a GIF's one palette, shared by all its frames (median cut over a sample of them, no dithering): a
shared palette lets unchanged pixels repeat, so each frame stores only the region that moved."""
STRIP_TEXT_PER_WIDTH = 110
"""The snapshot strip's labels and caption are its width over this, px (22 px on a 2,400 px strip of five panels):
read at a column's width in a paper."""
LABEL_LINES_PER_HEIGHT = 30
"""A label's text size is the image height over this (16 px at 480, 8 px at 240), at least 6 px."""


def check_formats(formats: Sequence[str]) -> None:
    """Raise InvalidInputError for a video format other than VIDEO_FORMATS."""
    for fmt in formats:
        if fmt not in VIDEO_FORMATS:
            raise InvalidInputError(f"format: unknown format {fmt!r}; valid: {', '.join(VIDEO_FORMATS)}")


def executed_pose(result: Comparison, b: int, k: int) -> NDArray[np.float64]:
    """q at period k of rollout row b (k = N: the final state), rad."""
    return result.rollout.q[b, k] if k < result.rollout.q.shape[1] else result.rollout.q_final[b]


def label_size(height: int) -> int:
    """Text size in px for an image `height` px tall (LABEL_LINES_PER_HEIGHT)."""
    return max(6, round(height / LABEL_LINES_PER_HEIGHT))


def label(image: NDArray[np.uint8], lines: Sequence[str], *, size: int | None = None,
          light: bool = False) -> NDArray[np.uint8]:
    """`image` with `lines` of text drawn top-left on a dark band (`light`: dark text on a white one); a new array.
    `size`: text size in px (default: scaled to the image, label_size); the band and its margins scale with it."""
    from PIL import Image, ImageDraw, ImageFont

    size = label_size(image.shape[0]) if size is None else size
    pad = max(2, size // 4)
    picture = Image.fromarray(image)
    draw = ImageDraw.Draw(picture)
    font = ImageFont.load_default(size=size)
    band, ink = ((255, 255, 255), (20, 20, 24)) if light else ((20, 20, 24), (240, 240, 240))
    draw.rectangle((0, 0, picture.width, 2 * pad + (size + pad) * len(lines)), fill=band)
    for i, line in enumerate(lines):
        draw.text((2 * pad, pad + (size + pad) * i), line, fill=ink, font=font)
    return np.asarray(picture)


def frames(result: Comparison, planner: str, renderer: ArmRenderer, *, every: int = 1,
           text: bool = True) -> list[NDArray[np.uint8]]:
    """Frames of one planner's execution: period k shows q_k with the ghost at q_ref,k, and the live error."""
    b = result.planners.index(planner)
    ref = result.references[planner]
    images = []
    for k in range(0, ref.steps + 1, every):
        q = executed_pose(result, b, k)
        image = renderer.frame(q, ref.q[k])
        if text:
            error = np.abs(ref.q[k] - q).max()
            image = label(image, [f"{planner}", f"t = {k * ref.dt:4.2f} s  max|e| = {1e3 * error:6.2f} mrad"])
        images.append(image)
    return images


def motion_poses(result: Comparison, samples: int = 20) -> NDArray[np.float64]:
    """About `samples` poses of every planner's reference and execution, evenly spaced in time, ends included;
    shape (P, nq), rad: what the videos' free camera frames."""
    poses = []
    for b, planner in enumerate(result.planners):
        ref = result.references[planner]
        for k in np.unique(np.linspace(0, ref.steps, samples).round().astype(int)):
            poses += [ref.q[k], executed_pose(result, b, int(k))]
    return np.array(poses)


def _write(path: Path, images: Sequence[NDArray[np.uint8]], fps: float) -> None:
    """Write a video or image atomically (a failure leaves no partial file)."""
    import imageio.v3 as iio

    with atomic_path(path) as tmp:
        if path.suffix == ".mp4":
            iio.imwrite(tmp, np.stack(images), fps=fps, codec="libx264", macro_block_size=8)
        elif path.suffix == ".gif":
            _write_gif(tmp, images, fps)
        else:
            iio.imwrite(tmp, images[0])


def _write_gif(path: Path, images: Sequence[NDArray[np.uint8]], fps: float) -> None:
    """An endlessly looping GIF of `images` at `fps` with one shared palette (GIF_COLORS)."""
    from PIL import Image

    sample = np.vstack(images[:: max(1, len(images) // 8)])
    palette = Image.fromarray(sample).quantize(colors=GIF_COLORS, method=Image.Quantize.MEDIANCUT)
    frames = [Image.fromarray(image).quantize(palette=palette, dither=Image.Dither.NONE) for image in images]
    frames[0].save(path, format="GIF", save_all=True, append_images=frames[1:], duration=round(1000.0 / fps),
                   loop=0, optimize=True)


def render_all(result: Comparison, out: Path, *, formats: Sequence[str] = ("mp4",), width: int = 640,
               height: int = 480, camera: str = "front", quality: str = "fast", every: int = 1,
               progress: Callable[[int], None] | None = None) -> list[Path]:
    """Write `<scenario>_<planner>.<fmt>` per planner, `<scenario>_grid.<fmt>` (the first four planners side by
    side, when there are at least two) and `<scenario>_snapshots.png`; return the paths. `every` keeps one control
    period in `every` (fps = 1/(every dt)).

    Args:
      quality: a RENDER_QUALITIES value (mjtraj.media.render).
      progress: called with the number of frames just rendered.
    """
    check_formats(formats)
    plant = result.scenario.model
    name = result.scenario.name
    fps = 1.0 / (every * result.scenario.task.dt)
    written: list[Path] = []
    clips = {}
    with ArmRenderer(plant, width=width, height=height, camera=camera, quality=quality) as renderer:
        renderer.frame_motion(motion_poses(result))
        for planner in result.planners:
            clips[planner] = frames(result, planner, renderer, every=every)
            if progress:
                progress(len(clips[planner]))
            for fmt in formats:
                path = out / f"{name}_{planner}.{fmt}"
                _write(path, clips[planner], fps)
                written.append(path)
        if len(result.planners) >= 2:
            grid = _grid([clips[p] for p in result.planners[:4]])
            for fmt in formats:
                path = out / f"{name}_grid.{fmt}"
                _write(path, grid, fps)
                written.append(path)
    size = (min(max(width, STRIP_PANEL[0]), int(plant.vis.global_.offwidth)),
            min(max(height, STRIP_PANEL[1]), int(plant.vis.global_.offheight)))
    with ArmRenderer(plant, width=size[0], height=size[1], camera=camera, quality=quality) as renderer:
        strip = snapshot_strip(result, renderer)
        if progress:
            progress(len(SNAPSHOT_TIMES) * len(result.planners))
        path = out / f"{name}_snapshots.png"
        _write(path, [strip], fps)
        written.append(path)
    return written


def _grid(clips: Sequence[Sequence[NDArray[np.uint8]]]) -> list[NDArray[np.uint8]]:
    """Tile two equally long clips side by side, three or four 2x2 (a missing tile black)."""
    h, w, _ = clips[0][0].shape
    black = np.zeros((h, w, 3), dtype=np.uint8)
    out = []
    for k in range(len(clips[0])):
        tiles = [clip[k] for clip in clips]
        if len(tiles) == 2:
            out.append(np.hstack(tiles))
            continue
        tiles += [black] * (4 - len(tiles))
        out.append(np.vstack([np.hstack(tiles[:2]), np.hstack(tiles[2:])]))
    return out


def snapshot_strip(result: Comparison, renderer: ArmRenderer) -> NDArray[np.uint8]:
    """The paper's Fig. 1 in a paper's style: one stroboscopic panel per planner, side by side at one scale, on
    white: the executed arm at the times SNAPSHOT_TIMES (earlier ones paler), its flange path (solid blue) and the
    reference's (dashed orange, with dots at those times), which stay distinguishable where they coincide; a
    caption line says so under the panels."""
    panels = []
    for b, planner in enumerate(result.planners):
        ref = result.references[planner]
        ks = [round(fraction * ref.steps) for fraction in SNAPSHOT_TIMES]
        executed = [executed_pose(result, b, k) for k in range(ref.steps + 1)]
        panels.append((planner, [executed[k] for k in ks],
                       np.array([renderer.flange_position(q) for q in executed]),
                       np.array([renderer.flange_position(q) for q in ref.q]),
                       np.array([renderer.flange_position(ref.q[k]) for k in ks])))
    frame = np.vstack([np.vstack([renderer.body_positions(q) for q in poses] + [path, ref_path])
                       for _, poses, path, ref_path, _ in panels])
    size = max(label_size(renderer.height), round(len(panels) * renderer.width / STRIP_TEXT_PER_WIDTH))
    images = [label(renderer.strobe(poses, path, ref_path, marks, frame=frame), [planner], size=size, light=True)
              for planner, poses, path, ref_path, marks in panels]
    strip = np.hstack(images)
    times = ", ".join(f"{fraction * result.scenario.task.duration:g}" for fraction in SNAPSHOT_TIMES)
    caption = np.full((2 * size + 8, strip.shape[1], 3), 255, dtype=np.uint8)
    caption = label(caption, [f"{result.scenario.name}: the executed arm at t = {times} s (earlier poses paler); "
                              "flange path executed (solid blue) and planned (dashed orange; dots at those times)"],
                    size=size, light=True)
    return np.vstack([strip, caption])
