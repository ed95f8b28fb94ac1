"""The lock that keeps two sweeps from writing one results file or store at once."""

from __future__ import annotations

from pathlib import Path
from typing import IO

from mjtraj.exceptions import InvalidInputError


def lock_file(file: Path) -> IO[bytes] | None:
    """An open handle on `file` (created if absent) holding its exclusive lock; None where flock is unavailable.

    Raises:
      InvalidInputError: another process holds the lock.
    """
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock, as before
        file.touch()
        return None
    handle = open(file, "ab")
    try:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.close()
        raise InvalidInputError(f"out: {file} is being written by another sweep right now (it holds the file's "
                                f"lock); wait for that sweep to end, or choose another path") from None
    return handle
