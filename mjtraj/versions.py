"""mjtraj's version, and the provenance of its numbers: the libraries' versions, the BLAS, the CPU and the commit."""

from __future__ import annotations

import functools
import platform
import sys
from collections.abc import Mapping, Sequence
from importlib import metadata
from pathlib import Path

from mjtraj._checkout import MAPPED, checkout_root

__version__ = "0.4.0.dev4"
"""Changes whenever rows can move (a CHANGELOG entry says why), so that a result's version names its numbers."""

LIBRARIES = ("mujoco", "numpy", "scipy", "osqp", "daqp", "numba", "llvmlite", "pin", "ruckig", "torch", "gymnasium")
"""The distributions whose versions every result records, after mjtraj's own: every library its numbers pass through
(pin is Pinocchio; torch is recorded '' where the rl extra is not installed)."""
MACHINE = ("blas", "cpu", "commit")
"""The provenance besides the versions: NumPy's and SciPy's BLAS (`blas`), the CPU model (`cpu_model`) and the source
commit (`commit`)."""
PROVENANCE = ("mjtraj", *LIBRARIES, *MACHINE)
"""What every sweep row and `rl eval` summary records of where its numbers come from (`provenance`). A results store
holds rows of one provenance: `--resume` refuses a store whose rows differ in any of these."""
SOURCE = ("mjtraj", *MAPPED)
"""A checkout's folders the package is made of: a change in them (tracked or not, not ignored) marks its commit
dirty."""
GIT_TIMEOUT = 10.0
"""Seconds each git call of `commit` may take before the commit is given up as unknown ('')."""


def library_version(name: str) -> str:
    """The version of library `name`: the running module's __version__ where it is imported, else the installed
    distribution's (read without importing it; parsing its metadata costs about 3 ms); '' if not installed."""
    version = getattr(sys.modules.get(name), "__version__", None)
    if isinstance(version, str):
        return str(version)  # torch's is a str subclass
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return ""


def versions(*extra: str) -> dict[str, str]:
    """{'mjtraj': ..., 'mujoco': ..., ...} for LIBRARIES and any `extra` distributions ('' if not installed)."""
    return {"mjtraj": __version__, **{name: library_version(name) for name in (*LIBRARIES, *extra)}}


def blas() -> str:
    """NumPy's and SciPy's BLAS (the libraries mjtraj's float64 paths call) as threadpoolctl reports them:
    implementation, version and the kernels' architecture, e.g. 'openblas 0.3.30 SkylakeX' (each distinct one, sorted,
    joined by ', '). Others that a process happens to have loaded (PyTorch's) are left out, so that it does not depend
    on what ran before."""
    import numpy  # noqa: F401  (loaded before they are listed)
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_info

    libraries = [lib for lib in threadpool_info() if lib.get("user_api") == "blas"]
    ours = [lib for lib in libraries if any(name in str(lib.get("filepath", "")) for name in ("numpy", "scipy"))]
    return ", ".join(sorted({f"{lib.get('internal_api')} {lib.get('version')} {lib.get('architecture')}"
                             for lib in ours or libraries}))


def cpu_model(cpuinfo: Path = Path("/proc/cpuinfo")) -> str:
    """The CPU's model name: /proc/cpuinfo's first 'model name' (Linux on x86-64), else `platform.processor()`, else
    the machine type ('arm64')."""
    try:
        for line in cpuinfo.read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and value.strip():
                return " ".join(value.split())
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _git(root: Path, *args: str) -> bytes | None:
    """The output of `git -C root ARGS`; None if git is missing, fails or takes longer than GIT_TIMEOUT."""
    import subprocess  # here: `import mjtraj` stays light

    try:
        done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, timeout=GIT_TIMEOUT, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout if done.returncode == 0 else None


def commit(package_dir: Path | None = None) -> str:
    """The git commit of the source tree mjtraj runs from (`package_dir`, default this package): HEAD's hash, with
    '+dirty.DIGEST' when its SOURCE folders differ from HEAD (DIGEST: 12 hex digits of sha256 over `git diff HEAD`
    and the untracked files' names and bytes there, so that two runs of the same uncommitted code agree and of other
    code do not); '' where mjtraj does not run from a git checkout (an installed wheel) or git cannot tell."""
    import hashlib

    root = checkout_root(Path(__file__).resolve().parent if package_dir is None else package_dir)
    if root is None:
        return ""
    head = _git(root, "rev-parse", "--verify", "HEAD")
    changes = _git(root, "status", "--porcelain", "-z", "--", *SOURCE)
    if not head or changes is None:
        return ""
    sha = head.decode().strip()
    if not changes:
        return sha
    diff = _git(root, "diff", "HEAD", "--binary", "--", *SOURCE)
    untracked = _git(root, "ls-files", "--others", "--exclude-standard", "-z", "--", *SOURCE)
    if diff is None or untracked is None:
        return ""
    digest = hashlib.sha256(diff)
    for name in sorted(n for n in untracked.split(b"\0") if n):
        digest.update(b"\0" + name + b"\0")
        try:
            digest.update((root / name.decode()).read_bytes())
        except OSError:
            return ""
    return f"{sha}+dirty.{digest.hexdigest()[:12]}"


@functools.cache
def _provenance() -> tuple[tuple[str, str], ...]:
    return tuple({**versions(), "blas": blas(), "cpu": cpu_model(), "commit": commit()}.items())


def provenance() -> dict[str, str]:
    """Where this process's numbers come from, PROVENANCE's fields in order: mjtraj's version and LIBRARIES'
    (`versions`), the BLAS (`blas`), the CPU model (`cpu_model`) and the source commit (`commit`). Computed once per
    process (the git calls and threadpoolctl's scan take tens of ms); a new dict each call."""
    return dict(_provenance())


_LABELS = {"blas": "BLAS", "cpu": "CPU", "commit": "commit", "python": "Python"}


def describe(record: Mapping[str, str], names: Sequence[str] | None = None) -> str:
    """The provenance `record` (its fields `names`, default all) as text: "mjtraj 0.4.0.dev4, numpy 2.4.6, no torch,
    BLAS 'openblas 0.3.30 SkylakeX', CPU 'Intel(R) Xeon(R) Processor', commit 1a2b...", or "no git commit"."""
    parts = []
    for name in record if names is None else names:
        label, value = _LABELS.get(name, name), record[name]
        if not value:
            parts.append("no git commit" if name == "commit" else f"no {label}")
        else:
            parts.append(f"{label} {value!r}" if name in ("blas", "cpu") else f"{label} {value}")
    return ", ".join(parts)


def difference(stored: Mapping[str, str], now: Mapping[str, str]) -> str:
    """'' if `stored` records the provenance `now` has (equal on every field of PROVENANCE either records); else what
    differs, one line to follow "its rows ": "were computed with numpy 2.2.1, commit abc, this run has numpy 2.3.0,
    commit def", and "record no daqp, ... (written before mjtraj recorded them)" for fields `now` has and `stored`
    lacks."""
    recorded = [k for k in PROVENANCE if k in stored and stored[k] != now.get(k, "")]
    absent = [k for k in PROVENANCE if k in now and k not in stored]
    parts = []
    if recorded:
        parts.append(f"were computed with {describe(stored, recorded)}, this run has "
                     f"{describe({k: now.get(k, '') for k in recorded}, recorded)}")
    if absent:
        parts.append(f"record no {', '.join(_LABELS.get(k, k) for k in absent)} (written before mjtraj recorded "
                     f"{'it' if len(absent) == 1 else 'them'})")
    return "; ".join(parts)
