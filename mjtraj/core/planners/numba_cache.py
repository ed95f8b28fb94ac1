"""numba for the nonlinear planners' compiled kernels, with its on-disk cache in a folder that can be written.

The kernels (`tree_dynamics`, `shooting._propagate`, `tracking._riccati`, and `mjtraj.core.filter_kernel`'s, the
`mpc_filter` estimator's) are compiled with numba's cache: the first
process compiles them (about 9 s here, 25 s on a slower machine), later processes load them. numba writes its cache
beside the source (`__pycache__`) or, where that folder is read-only, in its own folder in the user's cache; where
neither can be written (a read-only installation run by an account without a writable home) numba refuses to cache,
and the import of the planners fails. `choose` decides, before numba is imported, where mjtraj's kernels go:

- NUMBA_CACHE_DIR set by the user: theirs, untouched;
- the planners' `__pycache__` writable: there (numba's own choice; nothing is set);
- else the user cache folder, $XDG_CACHE_HOME/mjtraj/numba (by default ~/.cache/mjtraj/numba), if it can be written;
- else mjtraj-numba-UID in the system's temporary folder, made private to the user (kept until that folder is
  cleaned);
- else none: the kernels are compiled in every process, uncached (`CACHE` is False), and the log says so.

Importing this module applies the choice (`configure`): NUMBA_CACHE_DIR in this process's environment, so that its
child processes share the folder, and in numba's configuration if numba is already imported. `mjtraj doctor
--warm-up` compiles the kernels once and reports where they are cached (`mjtraj.core.planners.warm_up`).
"""

from __future__ import annotations

import functools
import logging
import os
import stat
import sys
import tempfile
from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

logger = logging.getLogger(__name__)

SOURCE = Path(__file__).resolve().parent
"""The folder of the kernels' source files; numba's own cache is its `__pycache__`."""
VARIABLE = "NUMBA_CACHE_DIR"


@dataclass(frozen=True)
class CacheChoice:
    """Where the kernels are cached.

    Attributes:
      where: "NUMBA_CACHE_DIR" (the user's), "beside the source", "user cache", "temporary folder" or "none".
      folder: the folder (None for "none").
    """

    where: str
    folder: Path | None

    @property
    def sets_variable(self) -> bool:
        """Whether `configure` sets NUMBA_CACHE_DIR for this choice (the user cache or the temporary folder)."""
        return self.where in ("user cache", "temporary folder")


def writable(folder: Path) -> bool:
    """Whether a file can be created in `folder` (made if missing), checked as numba checks it: by creating one."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        return False
    return True


def user_cache(environ: Mapping[str, str]) -> Path:
    """$XDG_CACHE_HOME/mjtraj/numba (an absolute XDG_CACHE_HOME only, as the XDG specification says), else
    $HOME/.cache/mjtraj/numba."""
    xdg = environ.get("XDG_CACHE_HOME", "")
    base = Path(xdg) if xdg and os.path.isabs(xdg) else Path(environ.get("HOME") or Path.home()) / ".cache"
    return base / "mjtraj" / "numba"


def private_temporary(temporary: Path) -> Path | None:
    """mjtraj-numba-UID in `temporary`, made with mode 0700; None if it cannot be made, or exists but belongs to
    another user or others may write in it (a shared folder where another user could leave compiled code)."""
    uid = os.getuid() if hasattr(os, "getuid") else None
    folder = temporary / f"mjtraj-numba-{uid if uid is not None else 'user'}"
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        mode = folder.lstat()
    except OSError:
        return None
    if not stat.S_ISDIR(mode.st_mode) or (uid is not None and mode.st_uid != uid) or mode.st_mode & 0o022:
        return None
    return folder if writable(folder) else None


def choose(source: Path, environ: Mapping[str, str], temporary: Path) -> CacheChoice:
    """Where to cache kernels whose source is in the folder `source`, for a process with `environ` and the system's
    temporary folder `temporary` (the rules in the module docstring)."""
    if environ.get(VARIABLE):
        return CacheChoice(VARIABLE, Path(environ[VARIABLE]))
    if writable(source / "__pycache__"):
        return CacheChoice("beside the source", source / "__pycache__")
    user = user_cache(environ)
    if writable(user):
        return CacheChoice("user cache", user)
    folder = private_temporary(temporary)
    if folder is not None:
        return CacheChoice("temporary folder", folder)
    return CacheChoice("none", None)


def configure(choice: CacheChoice, environ: MutableMapping[str, str]) -> None:
    """Apply `choice`: NUMBA_CACHE_DIR in `environ` and, if numba is imported, in its configuration; a log line
    where nothing can be cached."""
    if choice.sets_variable:
        environ[VARIABLE] = str(choice.folder)
        config = sys.modules.get("numba.core.config")
        if config is not None:
            config.CACHE_DIR = str(choice.folder)  # type: ignore[attr-defined]
        logger.info("mjtraj's installation is read-only: numba caches its kernels in %s", choice.folder)
    elif choice.where == "none":
        logger.warning("numba cannot cache mjtraj's kernels (neither %s, %s nor the temporary folder can be "
                       "written): they are compiled in every process; set NUMBA_CACHE_DIR to a writable folder",
                       SOURCE / "__pycache__", user_cache(os.environ))


CHOICE = choose(SOURCE, os.environ, Path(tempfile.gettempdir()))
"""Where this process caches the kernels."""
configure(CHOICE, os.environ)
CACHE = CHOICE.where != "none"
"""Whether the kernels are cached on disk."""

import numba  # noqa: E402 - after NUMBA_CACHE_DIR is set

njit: Any = functools.partial(numba.njit, cache=CACHE)
"""numba.njit with the on-disk cache wherever it can be written (`CACHE`)."""

