"""mjtraj's version, and the versions of the libraries that shape its numbers (read without importing them)."""

from __future__ import annotations

from importlib import metadata

__version__ = "0.1.0"

LIBRARIES = ("mujoco", "numpy", "scipy", "osqp", "gymnasium")
"""The distributions whose versions every result records, after mjtraj's own."""


def versions(*extra: str) -> dict[str, str]:
    """{'mjtraj': ..., 'mujoco': ..., ...} for LIBRARIES and any `extra` distributions ('' if not installed)."""
    out = {"mjtraj": __version__}
    for name in (*LIBRARIES, *extra):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = ""
    return out
