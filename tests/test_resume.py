"""`mjtraj rl train --resume`: a run killed mid-training and resumed ends with the policy bits of an uninterrupted
run (same machine, one thread), and its record says where it resumed."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import zipfile

import pytest

from mjtraj.cli import main
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.train import TrainSettings, resume_training, train

ARGS = ["rl", "train", "--algo", "sac", "--action-mode", "residual", "--observe-control", "--task", "random",
        "--validation", "4", "--threads", "1", "--no-progress", "--plant-randomization", "mismatch", "--controller",
        "adaptive_computed_torque", "--observe-plant", "estimate", "--steps", "1200", "--checkpoints", "4",
        "--evaluations", "3", "--seed", "3"]


def _policy_bits(run) -> bytes:
    with zipfile.ZipFile(run / "policy.zip") as z:
        return z.read("policy.pth")


@pytest.mark.slow
def test_a_killed_run_resumes_to_the_uninterrupted_runs_policy(tmp_path):
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    assert main([*ARGS, "--out", str(whole)]) == 0
    proc = subprocess.Popen([sys.executable, "-m", "mjtraj", *ARGS, "--out", str(killed)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    while not (killed / "resume" / "state.pkl").exists() or not (killed / "checkpoints").exists():
        assert time.time() < deadline and proc.poll() is None, "the run ended before its first resume point"
        time.sleep(0.05)
    time.sleep(1.0)  # let it run on past the resume point: what it does next is thrown away and redone
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    record = json.loads((killed / "run.json").read_text())
    assert record["status"] == "running"  # a killed process records nothing more
    assert main(["rl", "train", "--resume", str(killed), "--no-progress"]) == 0
    record = json.loads((killed / "run.json").read_text())
    assert record["status"] == "complete" and record["timesteps"] == 1200
    assert [r["timesteps"] for r in record["resumed"]] and 0 < record["resumed"][0]["timesteps"] < 1200
    assert not (killed / "resume").exists()
    assert _policy_bits(killed) == _policy_bits(whole)
    assert (killed / "learning_curve.csv").read_text().count("\n") == (whole / "learning_curve.csv").read_text(
    ).count("\n")
    with pytest.raises(InvalidInputError, match="is complete; nothing to continue"):
        resume_training(killed)


def test_resume_refuses_a_folder_without_a_run_or_a_resume_point(tmp_path):
    with pytest.raises(InvalidInputError, match="holds no training run"):
        resume_training(tmp_path)
    (tmp_path / "run.json").write_text(json.dumps({"status": "running", "settings": {}}))
    with pytest.raises(InvalidInputError, match="stopped before its first checkpoint"):
        resume_training(tmp_path)


def test_train_refuses_a_run_folder_and_points_to_resume(tmp_path):
    (tmp_path / "run.json").write_text("{}")
    with pytest.raises(InvalidInputError, match=r"continue an interrupted one with --resume"):
        train(TrainSettings(steps=10), tmp_path)
