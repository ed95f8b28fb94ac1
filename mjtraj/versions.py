"""mjtraj's version, and the versions of the libraries that shape its numbers."""

from __future__ import annotations

import sys
from importlib import metadata

__version__ = "0.4.0.dev1"
"""Changes whenever rows can move (a CHANGELOG entry says why), so that a result's version names its numbers."""

LIBRARIES = ("mujoco", "numpy", "scipy", "osqp", "gymnasium")
"""The distributions whose versions every result records, after mjtraj's own."""


def library_version(name: str) -> str:
    """The version of library `name`: the running module's __version__ where it is imported, else the installed
    distribution's (read without importing it; parsing its metadata costs about 3 ms); '' if not installed."""
    version = getattr(sys.modules.get(name), "__version__", None)
    if isinstance(version, str):
        return version
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return ""


def versions(*extra: str) -> dict[str, str]:
    """{'mjtraj': ..., 'mujoco': ..., ...} for LIBRARIES and any `extra` distributions ('' if not installed)."""
    return {"mjtraj": __version__, **{name: library_version(name) for name in (*LIBRARIES, *extra)}}
