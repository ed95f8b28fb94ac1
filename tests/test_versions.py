"""The provenance every result records (mjtraj.versions): each field is what the libraries' metadata, threadpoolctl,
lscpu and git say; the commit marks a dirty tree with a digest of its changes; a difference reads as one line."""

from __future__ import annotations

import platform
import re
import subprocess

import pytest
from oracles import assert_provenance

from mjtraj.versions import PROVENANCE, commit, cpu_model, difference, provenance


def test_the_provenance_is_what_the_libraries_the_cpu_and_git_say():
    recorded = provenance()
    assert list(recorded) == list(PROVENANCE)
    assert_provenance(recorded)
    recorded["numpy"] = "0.0.1"  # a copy: the process's provenance stays
    assert provenance()["numpy"] != "0.0.1"


def _git(folder, *args):
    return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false",
                           *args], cwd=folder, capture_output=True, text=True, check=True).stdout.strip()


@pytest.fixture
def checkout(tmp_path):
    """A git checkout laid out as mjtraj's (pyproject.toml naming mjtraj, envs/ beside mjtraj/), one commit."""
    (tmp_path / "mjtraj").mkdir()
    (tmp_path / "envs").mkdir()
    (tmp_path / "envs" / "__init__.py").write_text("")
    (tmp_path / "mjtraj" / "core.py").write_text("GAIN = 1.0\n")
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "mjtraj"\n')
    (tmp_path / "README.md").write_text("read me\n")
    (tmp_path / ".gitignore").write_text("__pycache__/\n")
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-q", "-m", "first")
    return tmp_path


def test_the_commit_marks_a_dirty_tree_with_a_digest_of_its_changes(checkout):
    """HEAD's hash on a clean tree; '+dirty.' and 12 hex digits when mjtraj/, envs/ or assets/ differ, the same
    digits for the same change and others for another; a change elsewhere (the README) or an ignored file is not
    dirt; an untracked source file is."""
    package = checkout / "mjtraj"
    head = _git(checkout, "rev-parse", "HEAD")
    assert re.fullmatch(r"[0-9a-f]{40}", head) and commit(package) == head
    (checkout / "README.md").write_text("edited\n")
    (package / "__pycache__").mkdir()
    (package / "__pycache__" / "core.pyc").write_bytes(b"\0")
    assert commit(package) == head
    (package / "core.py").write_text("GAIN = 2.0\n")
    dirty = commit(package)
    assert re.fullmatch(rf"{head}\+dirty\.[0-9a-f]{{12}}", dirty)
    (package / "core.py").write_text("GAIN = 1.0\n")
    assert commit(package) == head
    (package / "core.py").write_text("GAIN = 2.0\n")
    assert commit(package) == dirty
    (package / "core.py").write_text("GAIN = 3.0\n")
    assert commit(package) not in (head, dirty) and commit(package).startswith(f"{head}+dirty.")
    (package / "core.py").write_text("GAIN = 1.0\n")
    (checkout / "envs" / "arm.py").write_text("")
    assert commit(package).startswith(f"{head}+dirty.")
    (checkout / "envs" / "arm.py").unlink()
    _git(checkout, "commit", "-q", "-am", "second")
    assert commit(package) == _git(checkout, "rev-parse", "HEAD") != head


def test_no_commit_outside_a_git_checkout(checkout, tmp_path_factory):
    """An installed mjtraj (envs/ inside the package) and a source tree outside git record ''."""
    (checkout / "mjtraj" / "envs").mkdir()
    assert commit(checkout / "mjtraj") == ""
    plain = tmp_path_factory.mktemp("plain")
    for name in ("mjtraj", "envs"):
        (plain / name).mkdir()
    (plain / "envs" / "__init__.py").write_text("")
    (plain / "pyproject.toml").write_text('[project]\nname = "mjtraj"\n')
    assert commit(plain / "mjtraj") == ""


def test_the_cpu_model_is_cpuinfos_model_name_or_the_platforms(tmp_path):
    (tmp_path / "x86").write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel name\t: AMD EPYC  7B13 64-Core "
                                  "Processor\n\nprocessor\t: 1\nmodel name\t: other\n")
    (tmp_path / "arm").write_text("processor\t: 0\nBogoMIPS\t: 50.00\nCPU part\t: 0xd0c\n")
    assert cpu_model(tmp_path / "x86") == "AMD EPYC 7B13 64-Core Processor"
    fallback = platform.processor() or platform.machine()
    assert fallback and cpu_model(tmp_path / "arm") == cpu_model(tmp_path / "missing") == fallback


def test_a_difference_reads_as_one_line_naming_what_differs():
    now = provenance()
    assert difference(now, now) == ""
    stored = {**now, "numpy": "2.2.1", "commit": "abc123"}
    here = {**now, "numpy": "2.3.0", "commit": "def456+dirty.0123456789ab"}
    assert difference(stored, here) == ("were computed with numpy 2.2.1, commit abc123, this run has numpy 2.3.0, "
                                        "commit def456+dirty.0123456789ab")
    assert difference({**here, "torch": "", "cpu": "AMD EPYC 7B13"},
                      {**here, "torch": "2.13.0+cpu", "cpu": "Intel(R) Xeon(R)", "commit": ""}) == (
        "were computed with no torch, CPU 'AMD EPYC 7B13', commit def456+dirty.0123456789ab, this run has torch "
        "2.13.0+cpu, CPU 'Intel(R) Xeon(R)', no git commit")
    old = {"mjtraj": "0.4.0.dev0", "mujoco": now["mujoco"], "numpy": now["numpy"]}  # a 0.4.0.dev0 row
    assert difference(old, now) == (
        f"were computed with mjtraj 0.4.0.dev0, this run has mjtraj {now['mjtraj']}; record no scipy, osqp, daqp, "
        "numba, llvmlite, pin, ruckig, torch, gymnasium, BLAS, CPU, commit (written before mjtraj recorded them)")
