"""Atomic file output: a result file is either complete or absent, never half-written."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path beside `path` (same suffix) to write; on success it replaces `path` (mode 0644),
    on any failure it is deleted and `path` is left as it was. An OSError without a file name (a write that
    found the disk full) is raised again naming `path`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, 0o644)  # mkstemp creates 0600
        os.replace(tmp, path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise with_path(e, path) from e
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def with_path(error: OSError, path: str | os.PathLike[str]) -> OSError:
    """`error` itself if it names a file; else an OSError of the same errno and message naming `path`."""
    if error.filename:
        return error
    return OSError(error.errno, error.strerror or str(error), str(path))


def write_text_atomic(path: Path, text: str) -> None:
    """Write `text` to `path` atomically (see `atomic_path`)."""
    with atomic_path(Path(path)) as tmp:
        tmp.write_text(text)
