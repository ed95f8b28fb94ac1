"""numba's cache of the planners' kernels: beside the source where it can be written, else a user cache folder, else
a private temporary one, never the user's own NUMBA_CACHE_DIR overridden; a read-only installation compiles once
across processes, and `mjtraj doctor --warm-up` compiles or loads the kernels and says so."""

from __future__ import annotations

import logging
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numba.core.config
import pytest

import mjtraj.core.planners
from mjtraj.core.planners.numba_cache import VARIABLE, CacheChoice, choose, configure

UID = os.getuid() if hasattr(os, "getuid") else "user"


def blocked(tmp_path: Path) -> Path:
    """A folder nobody can create, not even root: its parent is a plain file."""
    (tmp_path / "file.txt").write_text("a file, not a folder\n")
    return tmp_path / "file.txt" / "folder"


def test_the_users_numba_cache_dir_is_left_alone(tmp_path):
    environ = {VARIABLE: "/theirs", "HOME": str(tmp_path)}
    choice = choose(tmp_path / "src", environ, tmp_path)
    assert choice == CacheChoice(VARIABLE, Path("/theirs"))
    configure(choice, environ)
    assert environ == {VARIABLE: "/theirs", "HOME": str(tmp_path)}
    assert not (tmp_path / "src").exists()  # not even looked at


def test_a_writable_installation_caches_beside_the_source(tmp_path):
    environ = {"HOME": str(tmp_path / "home")}
    choice = choose(tmp_path / "src", environ, tmp_path)
    assert choice == CacheChoice("beside the source", tmp_path / "src" / "__pycache__")
    configure(choice, environ)
    assert environ == {"HOME": str(tmp_path / "home")}  # numba's own choice: nothing set


def test_a_read_only_installation_caches_in_the_users_cache_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", numba.core.config.CACHE_DIR)  # restored after the test
    source = blocked(tmp_path)
    home = tmp_path / "home"
    assert choose(source, {"HOME": str(home)}, tmp_path) == CacheChoice("user cache", home / ".cache/mjtraj/numba")
    assert (home / ".cache/mjtraj/numba").is_dir()
    xdg = {"HOME": str(home), "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    assert choose(source, xdg, tmp_path) == CacheChoice("user cache", tmp_path / "xdg/mjtraj/numba")
    relative = {"HOME": str(home), "XDG_CACHE_HOME": "xdg"}  # the XDG specification: a relative path is ignored
    assert choose(source, relative, tmp_path) == CacheChoice("user cache", home / ".cache/mjtraj/numba")
    environ = dict(xdg)
    configure(choose(source, xdg, tmp_path), environ)
    assert environ == {**xdg, VARIABLE: str(tmp_path / "xdg/mjtraj/numba")}
    assert numba.core.config.CACHE_DIR == str(tmp_path / "xdg/mjtraj/numba")  # numba, already imported, told too


def test_without_a_writable_home_the_cache_is_a_private_temporary_folder(tmp_path, caplog):
    source, home = blocked(tmp_path), tmp_path / "file.txt"  # a home that is a file: no .cache in it
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    choice = choose(source, {"HOME": str(home)}, temporary)
    assert choice == CacheChoice("temporary folder", temporary / f"mjtraj-numba-{UID}")
    assert (temporary / f"mjtraj-numba-{UID}").stat().st_mode & 0o777 == 0o700
    (temporary / f"mjtraj-numba-{UID}").chmod(0o777)  # a folder others may write in is never used
    assert choose(source, {"HOME": str(home)}, temporary) == CacheChoice("none", None)
    none = choose(source, {"HOME": str(home)}, blocked(tmp_path))
    assert none == CacheChoice("none", None)
    environ = {"HOME": str(home)}
    with caplog.at_level(logging.WARNING, logger="mjtraj.core.planners.numba_cache"):
        configure(none, environ)
    assert environ == {"HOME": str(home)}
    assert "they are compiled in every process; set NUMBA_CACHE_DIR to a writable folder" in caplog.text


def _child_environment(**extra: str) -> dict[str, str]:
    """This process's environment without a numba cache folder of the user's, with `extra`."""
    return {**{k: v for k, v in os.environ.items() if k not in (VARIABLE, "XDG_CACHE_HOME")}, **extra}


@pytest.mark.slow
def test_a_read_only_installation_compiles_the_kernels_once_across_processes(tmp_path):
    """A copy of the package whose planners' __pycache__ is a plain file (numba cannot cache beside the source, as in
    a read-only installation): the first process compiles the Riccati kernel into the user cache folder, the second
    loads it from there."""
    site = tmp_path / "site"
    shutil.copytree(Path(mjtraj.__file__).parent, site / "mjtraj",
                    ignore=shutil.ignore_patterns("__pycache__", "baselines"))
    (site / "mjtraj/core/planners/__pycache__").write_text("not a folder\n")
    home = tmp_path / "home"
    code = ("import os, numpy as np; from mjtraj.core.planners import numba_cache, tracking; "
            "tracking.tracking_gains(np.tile(np.eye(2), (3, 1, 1)), np.ones((3, 2, 1)), np.eye(2), np.eye(1)); "
            "s = tracking._riccati.stats; print(tracking.__file__, numba_cache.CHOICE.where, os.environ['"
            f"{VARIABLE}'], sum(s.cache_misses.values()), sum(s.cache_hits.values()))")
    runs = [subprocess.run([sys.executable, "-c", code], env=_child_environment(PYTHONPATH=str(site), HOME=str(home)),
                           capture_output=True, text=True, check=True, cwd=tmp_path).stdout.split()
            for _ in range(2)]
    cache = str(home / ".cache/mjtraj/numba")
    tracking = str(site / "mjtraj/core/planners/tracking.py")
    assert runs == [[tracking, "user", "cache", cache, "1", "0"], [tracking, "user", "cache", cache, "0", "1"]]
    assert any(path.suffix == ".nbi" for path in Path(cache).rglob("*"))  # numba's index of the cached kernel


@pytest.mark.slow
def test_doctor_warm_up_compiles_or_loads_every_kernel_and_says_where(tmp_path):
    """In a fresh process no kernel is in memory: the warm-up compiles or loads the three called from Python (the
    RK4 steps with the dynamics' derivatives, the sensitivities, the Riccati recursion), beside this installation's
    source."""
    source = Path(mjtraj.core.planners.__file__).resolve().parent
    done = subprocess.run([sys.executable, "-m", "mjtraj", "doctor", "--warm-up"], capture_output=True, text=True,
                          env=_child_environment(MUJOCO_GL="osmesa"), cwd=source.parents[2], timeout=600)  # this mjtraj
    assert done.returncode == 0, done.stderr[-2000:]
    line = done.stdout.strip().splitlines()[-1]
    found = re.fullmatch(r"numba kernels: ready in ([0-9.]+) s \((\d+) compiled, (\d+) loaded from the cache\); "
                         r"cached beside the source \((.+)\)", line)
    assert found is not None, line
    seconds, compiled, loaded, folder = float(found[1]), int(found[2]), int(found[3]), found[4]
    assert seconds > 0 and compiled + loaded >= 3
    assert folder == str(source / "__pycache__")


@pytest.mark.parametrize("name", ["tree_dynamics", "shooting", "tracking"])
def test_every_kernel_module_compiles_through_the_chosen_cache(name):
    """No kernel module calls numba.njit itself (its cache=True would ignore a folder that cannot be written)."""
    text = (Path(mjtraj.core.planners.__file__).parent / f"{name}.py").read_text()
    assert "from mjtraj.core.planners.numba_cache import njit" in text and "numba.njit" not in text
