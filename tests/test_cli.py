"""The mjtraj command, called as main([...]) and as `python -m mjtraj`."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import pytest

from mjtraj.cli import main
from mjtraj.study.comparison import compare
from mjtraj.study.plots import FIGURES


def test_compare_writes_everything(tmp_path, capsys, scenario):
    assert main(["compare", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "Table I (ours" in out and "Table I as published" in out
    record = json.loads((tmp_path / "results.json").read_text())
    expected = compare(scenario)
    for name in ("optimal", "cubic", "quintic", "trapezoidal"):
        assert record["planners"][name]["metrics"] == expected.metrics[name].as_dict()  # deterministic
    rows = list(csv.DictReader((tmp_path / "results.csv").open()))
    assert [r["planner"] for r in rows] == ["optimal", "cubic", "quintic", "trapezoidal", "scurve"]
    assert float(rows[1]["cost"]) == expected.metrics["cubic"].cost
    for figure in FIGURES:
        assert (tmp_path / figure).stat().st_size > 10_000



def test_compare_json_and_overrides(tmp_path, capsys):
    args = ["compare", "--out", str(tmp_path), "--json", "--no-figures", "--planners", "cubic,quintic",
            "--ff-accel", "step_average", "--gravity-comp", "zoh", "--duration", "1.5"]
    assert main(args) == 0
    record = json.loads(capsys.readouterr().out)
    assert list(record["planners"]) == ["cubic", "quintic"]
    assert record["scenario"]["controller"]["ff_accel"] == "step_average"
    assert record["scenario"]["controller"]["gravity_comp"] == "zoh"
    assert record["scenario"]["task"]["duration"] == 1.5
    assert not list(tmp_path.glob("*.png"))



@pytest.mark.parametrize(("args", "message"), [
    (["--q0", "0,0"], "mjtraj: error: q0: expected 3 values, got shape (2,)"),
    (["--qg", "0,0,4"], "mjtraj: error: qg: joint 'elbow_joint' = 4 rad is outside its range [-3.14159, 3.14159]"),
    (["--duration", "0"], "mjtraj: error: duration: expected a positive number, got 0.0"),
    (["--dt", "0.03"], "mjtraj: error: duration: expected a whole number of control periods dt=0.03 s, got 2.0 s "
                       "(66.6667 periods)"),
    (["--planners", "spline"], "mjtraj: error: planners: unknown planner 'spline'; valid: cubic, optimal, quintic, "
                               "scurve, trapezoidal"),
    (["--ff", "model"], "mjtraj: error: feedforward: unknown value 'model'; valid: inverse, planned, none"),
    (["--ff", "planned", "--planners", "cubic"], "mjtraj: error: feedforward: mode 'planned' needs a planner that "
     "publishes u_plan; the 'cubic' reference has none; valid for it: inverse, none"),
    (["--config", "/nonexistent.toml"], "mjtraj: error: config: scenario file not found: /nonexistent.toml (shipped "
                                        "scenarios, by name: paper, paper_oracle, paper_tuned)"),
    (["--duration", "0.1", "--planners", "optimal"], None),
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    assert main(["compare", "--out", str(tmp_path / "out"), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    if message is None:
        assert err.startswith("mjtraj: error: optimal: x_N = 0 cannot be reached within the torque bounds")
    else:
        assert err == message + "\n"
    assert not (tmp_path / "out").exists()  # nothing half-written



def test_argparse_errors_are_one_line(capsys):
    with pytest.raises(SystemExit) as info:
        main(["compare", "--q0", "a,b"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("mjtraj: error: argument --q0: expected numbers")



def test_python_dash_m(tmp_path):
    done = subprocess.run([sys.executable, "-m", "mjtraj", "gains"], capture_output=True, text=True, check=True)
    assert done.stdout.startswith("# gain rule: ")

