"""The sweep results file: resume after a kill gives the uninterrupted file; other settings are refused."""


from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

from mjtraj.exceptions import InvalidInputError
from mjtraj.study.runner import run_sweep
from mjtraj.study.sweep import SweepSettings

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
    text = path.read_text().splitlines()
    header = text[0].split(",")
    i = header.index("mujoco")
    cells = text[1].split(",")
    cells[i] = "3.0.0"
    path.write_text("\n".join([text[0], ",".join(cells), *text[2:]]) + "\n")
    with pytest.raises(InvalidInputError, match=r"it was written by mujoco 3.0.0, this is mujoco "):
        run_sweep(SweepSettings(**SMALL), path, resume=True, workers=1, progress=False)

