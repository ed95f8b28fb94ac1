"""Oracles and tasks shared by the planner, QP and nonlinear planner tests, and the provenance oracle of the results
tests."""

from __future__ import annotations

import re
import shutil
import subprocess
from importlib import metadata
from pathlib import Path

import numpy as np

from mjtraj.core.task import Task

SHORT_Q0 = np.array([0.0, -np.pi / 2, 0.0])
SHORT_DIRECTION = np.array([1.0, 0.5, -1.0])
"""`short_task`'s default start and its direction of motion."""

WEIGHTS = {"state_weight": (1.0, 1.0, 1.0, 0.1, 0.1, 0.1), "input_weight": (1 / 3600,) * 3}
"""Fixed optimal-planner weights (Bryson's for a 1 rad move)."""


def unit_task(model, n_move=1.0):
    """From (0, -1.5, 0.5) rad, every joint by n_move rad, in 2 s at 0.02 s."""
    q0 = np.array([0.0, -1.5, 0.5])
    return Task.create(q0, q0 + n_move, 2.0, 0.02, model=model)


def short_task(model, move, duration=0.5, q0=SHORT_Q0):
    """A move of `move` rad along SHORT_DIRECTION in `duration` s (N = 25 at dt = 0.02: the nonlinear planners plan
    it in seconds, not minutes)."""
    return Task.create(q0, q0 + move * SHORT_DIRECTION, duration, 0.02, model=model)


def kkt_solve(qp):
    """Dense KKT solve of the equality-constrained QP (bounds dropped): the independent solve."""
    n, m = qp.H.shape[0], qp.A_eq.shape[0]
    K = np.block([[qp.H, qp.A_eq.T], [qp.A_eq, np.zeros((m, m))]])
    return np.linalg.solve(K, np.concatenate([-qp.f, qp.b_eq]))[:n]


def same_outcome(a, b) -> bool:
    """Outcomes equal bit for bit, NaN metrics (not measured) included."""
    return (a.status, a.reason, sorted(a.metrics)) == (b.status, b.reason, sorted(b.metrics)) and all(
        np.array_equal(a.metrics[k], b.metrics[k], equal_nan=True) for k in a.metrics)


DISTRIBUTIONS = ("mujoco", "numpy", "scipy", "osqp", "daqp", "numba", "llvmlite", "pin", "ruckig", "torch",
                 "gymnasium")
"""Every distribution mjtraj's numbers pass through: a result records the version of each."""


def provenance_oracle() -> dict[str, str]:
    """The provenance a result of this process must record, found without mjtraj's code: mjtraj's version from its
    installed metadata's source (pyproject.toml in a checkout), each of DISTRIBUTIONS' from its metadata ('' if not
    installed), the CPU model from lscpu (/proc/cpuinfo where lscpu is missing), and the commit from git run in the
    folder above the imported package when that folder is a git work tree's top ('' otherwise); the commit of a
    tree whose package folders differ from HEAD is only a prefix, HEAD's hash + '+dirty.'. The BLAS: `blas_oracle`."""
    import mjtraj

    root = Path(mjtraj.__file__).resolve().parents[1]
    if (root / "pyproject.toml").is_file():
        version = re.search(r'^version = "([^"]+)"$', (root / "pyproject.toml").read_text(), flags=re.M).group(1)
    else:
        version = metadata.version("mjtraj")
    out = {"mjtraj": version}
    for name in DISTRIBUTIONS:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = ""
    if shutil.which("lscpu"):
        text = subprocess.run(["lscpu"], capture_output=True, text=True, check=True,
                              env={"LC_ALL": "C", "PATH": "/usr/bin:/bin"}).stdout
        out["cpu"] = " ".join(re.search(r"^Model name:\s*(.+)$", text, flags=re.M).group(1).split())
    else:
        out["cpu"] = " ".join(re.search(r"^model name\s*:\s*(.+)$", Path("/proc/cpuinfo").read_text(),
                                        flags=re.M).group(1).split())
    top = subprocess.run(["git", "rev-parse", "--show-toplevel"], cwd=root, capture_output=True, text=True)
    out["commit"] = ""
    if top.returncode == 0 and Path(top.stdout.strip()).resolve() == root:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                              check=True).stdout.strip()
        changed = subprocess.run(["git", "status", "--porcelain", "--", "mjtraj", "envs", "assets"], cwd=root,
                                 capture_output=True, text=True, check=True).stdout
        out["commit"] = f"{head}+dirty." if changed else head
    return out


def blas_oracle() -> list[tuple[str, str]]:
    """(implementation, version) of each BLAS that NumPy and SciPy load, as threadpoolctl finds them by file."""
    import scipy.linalg  # noqa: F401 - loaded, so that threadpoolctl lists its BLAS
    from threadpoolctl import threadpool_info

    return sorted({(lib["internal_api"], lib["version"]) for lib in threadpool_info()
                   if lib["user_api"] == "blas" and re.search(r"(numpy|scipy)", lib["filepath"])})


def assert_provenance(recorded) -> None:
    """`recorded` (a row or a summary's versions) holds the provenance `provenance_oracle` and `blas_oracle` find."""
    want = provenance_oracle()
    commit = want.pop("commit")
    assert {k: recorded[k] for k in want} == want
    assert recorded["commit"] == commit or commit.endswith("+dirty.") and recorded["commit"].startswith(commit)
    libraries = blas_oracle()
    assert libraries and all(f"{api} {version} " in recorded["blas"] for api, version in libraries), recorded["blas"]
