"""The media layer: off-screen OpenGL, frames of the arm with its reference as a ghost, and videos of a
comparison. Every name below loads on first use."""

from __future__ import annotations

from typing import TYPE_CHECKING

from mjtraj._lazy import lazy_exports

_EXPORTS = {
    "use_backend": "mjtraj.media.gl",
    "active_backend": "mjtraj.media.gl",
    "user_backend": "mjtraj.media.gl",
    "default_backend": "mjtraj.media.gl",
    "ArmRenderer": "mjtraj.media.render",
    "check_render_options": "mjtraj.media.render",
    "RENDER_QUALITIES": "mjtraj.media.render",
    "render_all": "mjtraj.media.videos",
    "check_formats": "mjtraj.media.videos",
    "VIDEO_FORMATS": "mjtraj.media.videos",
    "SNAPSHOT_TIMES": "mjtraj.media.videos",
    "HumanViewer": "mjtraj.media.window",
    "check_display": "mjtraj.media.window",
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from mjtraj.media.gl import active_backend, default_backend, use_backend, user_backend
    from mjtraj.media.render import RENDER_QUALITIES, ArmRenderer, check_render_options
    from mjtraj.media.videos import SNAPSHOT_TIMES, VIDEO_FORMATS, check_formats, render_all
    from mjtraj.media.window import HumanViewer, check_display

__all__ = [
    "ArmRenderer", "HumanViewer", "RENDER_QUALITIES", "SNAPSHOT_TIMES", "VIDEO_FORMATS", "active_backend",
    "check_display", "check_formats", "check_render_options", "default_backend", "render_all", "use_backend",
    "user_backend",
]
