"""The mjtraj command, called as main([...]) and as `python -m mjtraj`."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mjtraj.cli import main
from mjtraj.study.comparison import compare
from mjtraj.study.plots import FIGURES


@pytest.mark.slow
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
    (["--qg", "0,0,4"], "mjtraj: error: qg: joint 'elbow_joint' = 4.0 rad is outside its range "
                        "[-3.141592653589793, 3.141592653589793]"),
    (["--duration", "0"], "mjtraj: error: duration: expected a positive number, got 0.0"),
    (["--dt", "0.03"], "mjtraj: error: duration: expected a whole number of control periods dt=0.03 s, got 2.0 s "
                       "(66.6667 periods)"),
    (["--planners", "spline"], "mjtraj: error: planners: unknown planner 'spline'; valid: cubic, optimal, "
                               "nonlinear_optimal, nonlinear_min_effort, quintic, scurve, trapezoidal"),
    (["--ff", "model"], "mjtraj: error: feedforward: unknown value 'model'; valid: inverse, planned, none"),
    (["--ff", "planned", "--planners", "cubic"], "mjtraj: error: feedforward: mode 'planned' needs a planner that "
     "publishes u_plan; the 'cubic' reference has none; valid for it: inverse, none"),
    (["--config", "/nonexistent.toml"], "mjtraj: error: config: scenario file not found: /nonexistent.toml (shipped "
                                        "scenarios, by name: paper, paper_adaptive, paper_computed_torque, "
                                        "paper_oracle, paper_tuned)"),
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



@pytest.mark.slow
def test_python_dash_m(tmp_path):
    done = subprocess.run([sys.executable, "-m", "mjtraj", "gains"], capture_output=True, text=True, check=True)
    assert done.stdout.startswith("# gain rule: ")



def test_negative_vectors_need_no_equals_sign(tmp_path, capsys):
    assert main(["compare", "--q0", "-1,-1.5707963267948966,0", "--no-figures", "--json", "--out", str(tmp_path)]) == 0
    assert json.loads(capsys.readouterr().out)["scenario"]["task"]["q0"] == [-1.0, -1.5707963267948966, 0.0]


def test_a_zero_move_compares_without_error(tmp_path, capsys):
    still = "0,-1.5707963267948966,0"
    assert main(["compare", "--q0", still, "--qg", still, "--no-figures", "--out", str(tmp_path)]) == 0
    assert "Table I (ours" in capsys.readouterr().out


@pytest.mark.parametrize(("args", "message"), [
    (["bench", "loop", "--sizes", "0"], "mjtraj: error: argument --sizes: expected whole numbers >= 1, got '0'"),
    (["compare", "--planners", "cubic,cubic", "--no-figures"],
     "mjtraj: error: planners: expected distinct planners, got cubic more than once"),
])
def test_more_bad_input(args, message, capsys, tmp_path):
    try:
        code = main([*args, *(["--out", str(tmp_path / "o")] if args[0] == "compare" else [])])
    except SystemExit as exit_:
        code = exit_.code
    assert code == 2 and capsys.readouterr().err == message + "\n"


def test_os_errors_are_one_line(tmp_path, capsys):
    occupied = tmp_path / "a_file"
    occupied.write_text("")
    assert main(["compare", "--no-figures", "--out", str(occupied)]) == 2
    assert capsys.readouterr().err == f"mjtraj: error: {occupied}: File exists\n"


def test_interrupt_exits_130_with_one_line(monkeypatch, capsys):
    import mjtraj.cli.gains as gains

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(gains, "run", interrupted)
    assert main(["gains"]) == 130
    assert capsys.readouterr().err == "mjtraj: interrupted; run the same command to continue\n"


@pytest.mark.slow
def test_a_closed_pipe_is_not_a_traceback(tmp_path):
    command = f"{sys.executable} -m mjtraj compare --json --no-figures --out {tmp_path} | head -1"
    done = subprocess.run(["bash", "-o", "pipefail", "-c", command], capture_output=True, text=True)
    assert done.stdout == "{\n" and "Traceback" not in done.stderr and done.returncode == 0


def test_defaults_leave_tracked_files_alone():
    """Run from a checkout, the commands' default outputs are under results/ (ignored by git)."""
    from mjtraj.cli import build_parser
    from mjtraj.cli.compare import output_folder as _compare_out

    parser = build_parser()
    assert parser.parse_args(["render"]).out == Path("results/videos")
    assert parser.parse_args(["audit", "x.csv"]).out == Path("results/AUDIT.md")
    assert _compare_out(parser.parse_args(["compare"])) == Path("results")
    assert _compare_out(parser.parse_args(["compare", "--model", "arms/z1.xml"])) == Path("results/z1")
    assert _compare_out(parser.parse_args(["compare", "--controller", "mpc"])) == Path("results/mpc")
    assert _compare_out(parser.parse_args(["compare", "--controller", "pid"])) == Path("results")
    assert _compare_out(parser.parse_args(["compare", "--model", "z1.xml", "--out", "o"])) == Path("o")


def test_compare_keeps_its_time_series(tmp_path, scenario):
    assert main(["compare", "--no-figures", "--planners", "cubic,optimal", "--out", str(tmp_path)]) == 0
    series = np.load(tmp_path / "results.npz")
    expected = compare(scenario, ("cubic", "optimal"))
    assert series["planners"].tolist() == ["cubic", "optimal"]
    np.testing.assert_array_equal(series["dtau"], expected.rollout.dtau)
    np.testing.assert_array_equal(series["q_ref"][1], expected.references["optimal"].q)
    assert series["e"].shape == (2, 100, 3) and series["t"].shape == (101,)


def test_version_and_a_bare_command_print_what_a_user_needs(capsys):
    from mjtraj import __version__

    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0 and capsys.readouterr().out == f"mjtraj {__version__}\n"
    assert main([]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: mjtraj") and "compare" in out and "rl" in out


@pytest.mark.slow
def test_compare_writes_figures_in_every_format_asked(tmp_path, capsys):
    assert main(["compare", "--planners", "cubic,quintic", "--figure-format", "pdf,svg", "--out", str(tmp_path)]) == 0
    written = sorted(p.suffix for p in tmp_path.glob("fig*"))
    assert written == [".pdf"] * 6 + [".svg"] * 6
    assert (tmp_path / "fig3_tracking_error.pdf").read_bytes().startswith(b"%PDF")
    assert b"<svg" in (tmp_path / "fig3_tracking_error.svg").read_bytes()[:500]
    with pytest.raises(SystemExit) as exit_info:
        main(["compare", "--figure-format", "eps", "--out", str(tmp_path)])
    assert exit_info.value.code == 2 and "expected png, pdf, svg" in capsys.readouterr().err


@pytest.mark.slow
def test_reproduce_runs_the_studys_commands_at_a_small_size(tmp_path, capsys):
    """`mjtraj reproduce` runs every documented step (Table I, the frontiers, the audit sweeps, the effort sweep,
    their audits) and writes each one's files; its list of commands is the one it reports."""
    from mjtraj.cli.reproduce import steps

    out = tmp_path / "r"
    assert main(["reproduce", "--scenarios", "3", "--no-progress", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    for argv in steps(out, 3, progress=False):
        assert f"ok      mjtraj {' '.join(argv)}" in text
    for path in ("compare/results.json", "frontier/frontier.json", "frontier/frontier_nominal.json",
                 "sweeps/audit.csv", "sweeps/tuned.csv", "sweeps/oracle.csv", "sweeps/effort.csv", "AUDIT.md",
                 "AUDIT_effort.md"):
        assert (out / path).stat().st_size > 0, path
    assert "Claim 1" in (out / "AUDIT.md").read_text()


def test_bare_rl_and_bench_say_what_they_hold(capsys):
    """A bare `mjtraj rl` lists its subcommands (exit 0); `bench --help` names what a bare bench runs."""
    assert main(["rl"]) == 0
    out = capsys.readouterr().out
    assert " ".join(out.split()).startswith("usage: mjtraj rl [-h] {train,search,distill,plan,plot,eval,baselines,"
                                            "best,ship,ensemble}")
    for command in ("train", "search", "distill", "plan", "plot", "eval", "baselines", "best", "ship"):
        assert f"    {command} " in out
    from mjtraj.cli.bench import BENCH_ALL

    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    assert f"default all: {', '.join(BENCH_ALL)}" in " ".join(capsys.readouterr().out.split())


def test_observing_mpcs_filter_needs_batched_training_with_a_settle_window(tmp_path, capsys):
    """SB3's training runs no filter beside the loop; batched training runs it in protocol v2's episodes alone."""
    assert main(["rl", "train", "--algo", "ppo", "--observe-disturbance", "--out", str(tmp_path / "a")]) == 2
    assert capsys.readouterr().err == ("mjtraj: error: observe_disturbance: only batched training (--batched --settle "
                                       "S) runs mpc's filter beside the loop; add --batched\n")
    assert main(["rl", "train", "--algo", "ppo", "--batched", "--observe-disturbance", "--out",
                 str(tmp_path / "b")]) == 2
    assert capsys.readouterr().err == ("mjtraj: error: observe_disturbance: mpc's filter runs in protocol v2's "
                                       "episodes; expected settle > 0, got 0.0\n")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_a_policy_that_observes_mpcs_filter_is_refused_under_protocol_v1(tmp_path, capsys):
    """The filter runs in protocol v2's episodes alone: `rl eval --protocol v1` of such a policy is refused by name,
    before anything is written."""
    import dataclasses

    from mjtraj.envs import resolve

    from mjtraj.rl.batched_policy import BatchedSettings, batched_policy_class, save_policy

    settings = BatchedSettings(num_envs=3, action_mode="torque", observe_disturbance=True, settle=0.5)
    size = resolve(**settings.env_kwargs("nominal")).obs_size
    save_policy(batched_policy_class()(size, 3, settings), tmp_path / "p.pt",
                {"settings": dataclasses.asdict(settings),
                 "streams": {"train": {"gym_seeds": []}, "validation": {"count": 0}}})
    out = tmp_path / "eval"
    assert main(["rl", "eval", "--policy", str(tmp_path / "p.pt"), "--protocol", "v1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mjtraj: error: policy: ") and err.endswith(
        " observes mpc's filter, which runs in protocol v2's episodes alone; expected --protocol v2, got v1\n")
    assert not out.exists()
