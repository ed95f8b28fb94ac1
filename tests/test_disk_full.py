"""A full disk, simulated by a file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored so writes fail with EFBIG): every
command ends with one line naming the file, leaves no partial or temporary file, and a sweep resumes to the rows
of an uninterrupted run."""

from __future__ import annotations

import json
import resource
import signal
import subprocess
import sys

import pytest

from mjtraj.study.store import read_rows

LIMIT = 40_000
"""Bytes: more than a store's schema and a few units, less than the whole sweep."""
SWEEP = ["sweep", "--scenarios", "60", "--batch", "5", "--planners", "cubic", "--workers", "1", "--no-progress"]


def _limited() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def _mjtraj(args: list[str], *, limited: bool) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "mjtraj", *args], preexec_fn=_limited if limited else None,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["s.sqlite", "s.csv"])
def test_a_sweep_that_fills_the_disk_stops_in_one_line_and_resumes_to_the_whole_run(tmp_path, name):
    out = tmp_path / name
    whole = out.with_stem("whole")
    full = _mjtraj([*SWEEP, "--out", str(out)], limited=True)
    assert full.returncode == 2, full.stderr
    (line,) = full.stderr.strip().splitlines()
    assert line.startswith(f"mjtraj: error: {out}: ")
    assert 0 < len(read_rows(out) if name.endswith(".sqlite") else out.read_bytes().splitlines()) < 61
    resumed = _mjtraj([*SWEEP, "--out", str(out), "--resume"], limited=False)
    assert resumed.returncode == 0, resumed.stderr
    assert _mjtraj([*SWEEP, "--out", str(whole)], limited=False).returncode == 0
    assert read_rows(out) == read_rows(whole)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, whole.name])  # no journal, no temporary


@pytest.mark.slow
def test_compare_on_a_full_disk_names_the_file_and_leaves_no_partial_file(tmp_path):
    out = tmp_path / "results"
    full = _mjtraj(["compare", "--out", str(out)], limited=True)
    assert full.returncode == 2
    (line,) = full.stderr.strip().splitlines()
    assert line.startswith(f"mjtraj: error: {out}/") and line.endswith("File too large")
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary file left
    written = {p.name: p for p in out.iterdir()}
    assert "results.json" in written  # written before the disk filled: whole, it parses
    json.loads(written["results.json"].read_text())
