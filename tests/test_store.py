"""The sweep results file: resume after a kill gives the uninterrupted file; other settings, damage and a second
writer are refused, leaving the file untouched."""


from __future__ import annotations

import csv
import signal
import subprocess
import sys
import time

import pytest

from mjtraj.exceptions import InvalidInputError, ProvenanceError
from mjtraj.study.runner import run_sweep
from mjtraj.study.store import ResultsFile, csv_text
from mjtraj.study.sweep import SweepSettings, columns, fixed_columns

SMALL = dict(scenarios=6, batch=3, planners=("optimal", "cubic"))


@pytest.mark.slow
def test_resume_after_kill_gives_the_uninterrupted_file(tmp_path):
    args = ["--scenarios", "40", "--batch", "4", "--planners", "optimal,cubic", "--workers", "1", "--no-progress"]
    whole, cut = tmp_path / "whole.csv", tmp_path / "cut.csv"
    subprocess.run([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(whole)], check=True,
                   capture_output=True)
    proc = subprocess.Popen([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(cut)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and (not cut.exists() or cut.read_text().count("\n") < 1 + 3 * 8):
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    written = cut.read_bytes()
    assert 0 < len(written) < len(whole.read_bytes())
    with open(cut, "ab") as f:
        f.write(b"nominal,39,9,opt")  # a torn unit at the end
    out = subprocess.run([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(cut), "--resume"],
                         check=True, capture_output=True, text=True)
    assert "units were already done" in out.stdout
    assert cut.read_bytes() == whole.read_bytes()



def test_resume_refuses_other_settings_and_versions(tmp_path):
    path = tmp_path / "s.csv"
    run_sweep(SweepSettings(**SMALL), path, workers=1, progress=False)
    with pytest.raises(InvalidInputError, match=r"exists; pass --resume"):
        run_sweep(SweepSettings(**SMALL), path, workers=1, progress=False)
    with pytest.raises(InvalidInputError, match=r"^out: cannot resume .*: setting 'sweep_seed' differs \(file: '0', "
                                                r"now: '1'\)"):
        run_sweep(SweepSettings(**{**SMALL, "seed": 1}), path, resume=True, workers=1, progress=False)
    lines = list(csv.reader(path.read_text().splitlines()))
    i = lines[0].index("mujoco")
    now = lines[1][i]
    lines[2][i] = "3.0.0"  # a row of another provenance in the middle of the file
    path.write_text(csv_text(lines[0], [dict(zip(lines[0], cells, strict=True)) for cells in lines[1:]]))
    before = path.read_bytes()
    with pytest.raises(ProvenanceError) as refused:
        run_sweep(SweepSettings(**SMALL), path, resume=True, workers=1, progress=False)
    assert str(refused.value) == (f"out: cannot resume {path} (line 3): its rows were computed with mujoco 3.0.0, "
                                  f"this run has mujoco {now}; start a new file (a results file holds rows of one "
                                  f"provenance)")
    assert path.read_bytes() == before



@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory):
    """A finished small sweep: its path and its lines (header first); 6 scenarios in units of 3 -> 2 units."""
    path = tmp_path_factory.mktemp("store") / "small.csv"
    run_sweep(SweepSettings(**SMALL), path, workers=1, progress=False)
    return path, path.read_bytes().splitlines(keepends=True)


def _resume_refused(path, lines, match):
    """Write `lines`, resume: refused with `match`, the file byte for byte as written."""
    data = b"".join(lines)
    path.write_bytes(data)
    with pytest.raises(InvalidInputError, match=match):
        run_sweep(SweepSettings(**SMALL), path, resume=True, workers=1, progress=False)
    assert path.read_bytes() == data


def test_resume_refuses_damage_an_interruption_cannot_explain(small_sweep, tmp_path):
    _, lines = small_sweep
    per_unit = (len(lines) - 1) // 2
    assert per_unit * 2 + 1 == len(lines)
    path = tmp_path / "damaged.csv"
    cut_row = lines[2][: len(lines[2]) // 2] + b"\n"  # a row cut short, then a newline: not a torn tail
    _resume_refused(path, [*lines[:2], cut_row, *lines[3:]], r"^out: cannot resume .*: line 3 has \d+ cells, the "
                                                             r"header \d+; the file was damaged")
    _resume_refused(path, [*lines, *lines[1:1 + per_unit]], rf"unit \w+ 0 appears twice \(lines 2 and "
                                                            rf"{2 + 2 * per_unit}\)")
    _resume_refused(path, [lines[0], *lines[1:per_unit], *lines[1 + per_unit:]],
                    rf"unit \w+ 0 \(line 2\) has {per_unit - 1} of its {per_unit} rows and other units follow it")
    _resume_refused(path, [*lines, lines[1]], rf"unit \w+ 1 has more than its {per_unit} rows|appears twice")
    header, row = lines[0].decode().rstrip("\n").split(","), lines[1].decode().split(",")
    row[header.index("unit")] = "7"
    foreign = ",".join(row).encode()
    _resume_refused(path, [*lines, foreign], r"line \d+ belongs to unit \w+ '7', which this sweep does not have")


def test_resume_repairs_an_interruption(small_sweep, tmp_path):
    whole, lines = small_sweep
    per_unit = (len(lines) - 1) // 2
    path = tmp_path / "cut.csv"
    path.write_bytes(b"".join(lines[: 1 + per_unit + 1]) + lines[2 + per_unit][:10])  # a unit and a half, torn
    report = run_sweep(SweepSettings(**SMALL), path, resume=True, workers=1, progress=False)
    assert report.skipped_units == 1
    assert report.rows == per_unit
    assert path.read_bytes() == whole.read_bytes()


def test_a_second_writer_is_refused_while_the_first_holds_the_file(small_sweep, tmp_path):
    _, lines = small_sweep
    path = tmp_path / "busy.csv"
    path.write_bytes(b"".join(lines[: 1 + (len(lines) - 1) // 2]))
    settings = SweepSettings(**SMALL)
    unit_rows = {unit: settings.unit_rows(unit) for unit in settings.units()}
    first = ResultsFile.open(path, columns(settings), fixed_columns(settings), unit_rows, resume=True)
    try:
        with pytest.raises(InvalidInputError, match=r"^out: .* is being written by another sweep right now"):
            run_sweep(settings, path, resume=True, workers=1, progress=False)
    finally:
        first.close()
    report = run_sweep(settings, path, resume=True, workers=1, progress=False)  # the lock went with close()
    assert report.skipped_units == 1
