"""`mjtraj bench`: the ratios it prints are the ones it measured (no timing assertion: machines are noisy).

The rates and ratios are checked against a scripted clock (`Clock`): the bench runs its real passes, but each span
it times lasts what the test says, so every rate and ratio has a value computed here by hand.
"""

from __future__ import annotations

import json
import re
import types

import numpy as np
import pytest

import mjtraj.bench as bench
from mjtraj.bench import bench_loop
from mjtraj.cli import main

PAPER_STEPS = 100
"""Control periods of the paper task (T = 2 s at dt = 0.02 s, paper.toml), the episode of UR5Track-v0."""


class Clock:
    """A stand-in for time.perf_counter: reads come in pairs (start, end), the k-th pair `spans[k]` seconds apart,
    1024 s between pairs (which no span may include). Spans of few binary digits (0.25, 0.375, 3) keep every
    difference exact. `done` says whether the code read it exactly as often as the spans scripted."""

    def __init__(self, spans: list[float]) -> None:
        self.spans, self.reads, self.now = list(spans), 0, 0.0

    def __call__(self) -> float:
        pair, end = divmod(self.reads, 2)
        self.reads += 1
        assert pair < len(self.spans), f"the clock was read more than the {2 * len(self.spans)} times scripted"
        self.now += self.spans[pair] if end else 1024.0
        return self.now

    @property
    def done(self) -> bool:
        return self.reads == 2 * len(self.spans)


def scripted(monkeypatch: pytest.MonkeyPatch, module: object, spans: list[float]) -> Clock:
    """Give `module` (which calls time.perf_counter) a Clock of `spans`."""
    clock = Clock(spans)
    monkeypatch.setattr(module, "time", types.SimpleNamespace(perf_counter=clock))
    return clock


def test_loop_ratio_is_loop_rate_over_raw_rate(scenario, monkeypatch):
    """Three rounds of (raw, loop) per batch size: the medians of the scripted spans give the rates, B N / median."""
    clock = scripted(monkeypatch, bench, [4.0, 5.0, 1.0, 9.0, 2.0, 3.0,  # B = 1: raw 4, 1, 2; loop 5, 9, 3
                                          0.5, 2.0, 0.25, 2.0, 1.0, 2.0])  # B = 8: raw 0.5, 0.25, 1; loop 2, 2, 2
    rows = bench_loop(scenario, (1, 8), rounds=3)
    assert clock.done
    assert rows == [{"scenarios": 1, "raw_steps_per_s": PAPER_STEPS / 2.0, "loop_steps_per_s": PAPER_STEPS / 5.0,
                     "ratio": pytest.approx(0.4, rel=1e-15)},
                    {"scenarios": 8, "raw_steps_per_s": 8 * PAPER_STEPS / 0.5, "loop_steps_per_s": 8 * PAPER_STEPS / 2,
                     "ratio": pytest.approx(0.25, rel=1e-15)}]


def test_printed_table_carries_the_measured_ratios(capsys):
    assert main(["bench", "loop", "--sizes", "1,8"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("closed loop (FF + PID + plant) vs raw mujoco.batch stepping")
    table = [re.split(r"\s+", line.strip()) for line in lines[2:]]
    assert [int(cells[0]) for cells in table] == [1, 8]
    for _, raw, loop, ratio in table:
        assert float(ratio) == pytest.approx(float(loop) / float(raw), abs=0.006)


def test_startup_ratio_is_compare_over_imports(monkeypatch):
    """Three commands, `repeats` fresh interpreters each (subprocess.run recorded here, not run): the medians of their
    scripted spans, and compare's over each anchor's."""
    import subprocess
    import sys

    commands = []
    monkeypatch.setattr(subprocess, "run", lambda command, **_: commands.append(command))
    clock = scripted(monkeypatch, bench, [1.0, 0.4, 0.5,  # python -c "import mujoco, gymnasium, scipy"
                                          0.625, 0.875, 0.75,  # ... scipy.linalg
                                          3.0, 2.0, 9.0])  # mjtraj compare
    row = bench.bench_startup(repeats=3)
    assert clock.done
    assert [c[1:3] for c in commands] == [["-c", "import mujoco, gymnasium, scipy"]] * 3 + [
        ["-c", "import mujoco, gymnasium, scipy.linalg"]] * 3 + [["-m", "mjtraj"]] * 3
    assert all(c[0] == sys.executable for c in commands) and all(c[3:5] == ["compare", "--no-figures"]
                                                                 for c in commands[6:])
    assert row == {"imports_s": 0.5, "linalg_s": 0.75, "compare_s": 3.0, "ratio": pytest.approx(6.0, rel=1e-15),
                   "ratio_linalg": pytest.approx(4.0, rel=1e-15)}


@pytest.mark.slow
def test_new_planners_table_prints_what_it_measured(capsys):
    assert main(["bench", "planners", "--planner-scenarios", "2", "--tail-tasks", "2"]) == 0
    out = capsys.readouterr().out
    linear = float(re.search(r"the linear optimal plan takes ([0-9.]+) ms", out)[1]) / 1e3
    scurve = re.search(r"^scurve\s+([0-9.]+)\s+([0-9.]+)\s+\(one closed-loop execution: ([0-9.]+) s; ratio "
                       r"([0-9.]+)\)$", out, re.MULTILINE)
    assert scurve is not None
    seconds, loop = float(scurve[1]), float(scurve[3])
    # the ratio is printed to 2 decimals from the unrounded times, which are printed to 5 (half a unit each)
    rounding = 0.005 + 5e-6 / (loop - 5e-6) + (seconds + 5e-6) * 5e-6 / (loop - 5e-6) ** 2
    assert float(scurve[4]) == pytest.approx(seconds / loop, abs=rounding)
    for name in ("nonlinear_min_effort", "nonlinear_optimal"):
        for solver in ("sqp", "slsqp"):
            row = re.search(rf"^{name}\s+{solver}\s+([0-9.]+)\s+([0-9]+)\s+([0-9]+)\s+([0-9.e+-]+)$", out, re.MULTILINE)
            seconds, times, iterations, objective = float(row[1]), int(row[2]), int(row[3]), float(row[4])
            # the multiple is rounded from the unrounded times, printed to 1e-3 s and 1e-2 ms (half a unit each)
            low, high = (seconds - 5e-4) / (linear + 5e-6), (seconds + 5e-4) / (linear - 5e-6)
            assert low - 0.5 <= times <= high + 0.5 and iterations >= 1 and objective > 0
    assert "over 2 nominal scenarios" in out
    assert re.search(r"batched differences on [1-9][0-9]* threads", out)
    analytic, differenced = map(int, re.search(r"^linearisations over these plans: (\d+) analytic, (\d+) "
                                               r"differenced$", out, re.MULTILINE).groups())
    assert analytic > 0 and differenced >= 0  # Pinocchio holds the shipped arm
    families = re.findall(r"^(nonlinear_\w+)\s+(auto|sqp|slsqp)(\*?)\s+(\d+)\s+([0-9.]+)\s+(\d+)\s+([0-9.]+)\s+"
                          r"(\d+)\s+([0-9.]+)\s+(\d+)\s+(\d+)\s+(\d+)\s+([+-][0-9.]+e[+-]\d+)\s+(\d+)$", out,
                          re.MULTILINE)
    assert {(name, solver, star) for name, solver, star, *_ in families} == {
        (name, solver, "*" if solver == "auto" else "") for name in ("nonlinear_min_effort", "nonlinear_optimal")
        for solver in ("auto", "sqp", "slsqp")}
    for _, solver, _, failed, median, times, p90, p90_times, largest, max_times, by_slsqp, tracked, gap, worse \
            in families:
        assert float(median) <= float(p90) + 0.0005 and float(p90) <= float(largest) + 0.005  # printed to 3, 3, 2
        for value, multiple, half_unit in ((median, times, 5e-4), (p90, p90_times, 5e-4), (largest, max_times, 5e-3)):
            # the multiple is printed from the unrounded time, the time to 3 or 2 decimals
            assert int(multiple) == pytest.approx(float(value) / linear, rel=0.02, abs=1 + half_unit / linear)
        assert int(tracked) <= 2 - int(failed)
        if solver == "slsqp":  # the reference of the gaps, and every plan its own
            assert (int(failed), int(by_slsqp), float(gap), int(worse)) == (0, 2, 0.0, 0)
    tail = re.findall(r"^(nonlinear_\w+)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)  (nominal|aggressive) (\d+) \(([0-9.]+) s\)$",
                      out, re.MULTILINE)
    assert [row[0] for row in tail] == ["nonlinear_min_effort", "nonlinear_optimal"]
    assert re.search(r"on 3 random tasks of seed 1 \(nominal and aggressive; 0 aggressive tasks", out)
    for _, median, p90, largest, failed, _, index, _ in tail:
        assert int(median) <= int(p90) + 1 and int(p90) <= int(largest) + 1 and int(failed) == 0
        assert int(index) in (0, 1)  # tasks 0 and 1 of nominal, 0 of aggressive


def test_three_independent_qp_solvers_agree_with_mjtraj_on_the_optimal_planners_qp(scenario):
    from mjtraj.bench import QP_SOLVERS, bench_qp

    rows = bench_qp(scenario, repeats=1)
    assert [row["solver"] for row in rows[1:]] == list(QP_SOLVERS)  # the test extra installs them: none skipped
    for row in rows:
        assert row["seconds"] > 0 and row["max_diff"] < 1e-6, row


@pytest.mark.slow
def test_render_ratio_is_fast_ur5_over_reacher_in_one_run(monkeypatch):
    """Two rounds over fast UR5Track-v0, high and Reacher-v5 (present: a missing Reacher would leave the clock short):
    each rate is frames over its best round's span."""
    clock = scripted(monkeypatch, bench, [0.5, 2.0, 0.125,   # round 1: fast, high, Reacher-v5
                                          0.25, 4.0, 0.375])  # round 2
    (row,) = bench.bench_render(((64, 48),), frames=2, rounds=2)
    assert clock.done
    assert row["size"] == "64x48"
    assert (row["fast_fps"], row["high_fps"], row["reacher_fps"]) == (8.0, 1.0, 16.0)
    assert (row["ratio"], row["high_ratio"]) == (0.5, 0.0625)


def test_env_ratios_are_env_rate_over_each_raw_rate(monkeypatch):
    """bench_env: a warm-up (raw, then one span per episode of the env), then per round raw (one span), replay and env
    (one span per episode each); only the rounds count. bench_vector_env: per round raw, replay and env, one
    episode and its autoreset step each."""
    episodes = 2
    warm_up = [99.0, 99.0, 99.0]
    rounds = [[1.0, 0.5, 1.5, 2.0, 2.0],  # raw; replay's two episodes (2 s); env's two (4 s)
              [3.0, 1.0, 1.0, 1.0, 5.0],  # raw 3; replay 2; env 6
              [2.0, 2.0, 1.0, 3.0, 2.0]]  # raw 2; replay 3; env 5
    clock = scripted(monkeypatch, bench, warm_up + [span for spans in rounds for span in spans])
    row = bench.bench_env(episodes=episodes, rounds=3)
    assert clock.done
    steps = episodes * PAPER_STEPS
    assert row == {"raw_steps_per_s": steps / 2.0, "replay_steps_per_s": steps / 2.0, "env_steps_per_s": steps / 5.0,
                   "ratio": pytest.approx(0.4, rel=1e-15), "ratio_replay": pytest.approx(0.4, rel=1e-15)}

    clock = scripted(monkeypatch, bench, [1.0, 4.0, 10.0,  # raw, replay, env
                                          2.0, 3.0, 8.0,
                                          3.0, 2.0, 12.0])
    (row,) = bench.bench_vector_env((4,), rounds=3)
    assert clock.done
    steps = 4 * (PAPER_STEPS + 1)
    assert row == {"envs": 4, "raw_steps_per_s": steps / 2.0, "replay_steps_per_s": steps / 3.0,
                   "env_steps_per_s": steps / 10.0, "ratio": pytest.approx(0.2, rel=1e-15),
                   "ratio_replay": pytest.approx(0.3, rel=1e-15)}


def test_the_replay_anchor_steps_the_envs_own_motions():
    """What the bench's replay pass relies on: raw mujoco.batch stepping of the recorded start states under the
    recorded torques reproduces the vector env's episode bit for bit."""
    import gymnasium as gym
    from mujoco.batch import Batch

    env = gym.make_vec("UR5Track-v0", num_envs=3, vectorization_mode="vector_entry_point")
    env.reset(seed=4)
    unwrapped = env.unwrapped
    for _ in range(unwrapped.settings.steps):
        env.step(np.zeros((3, 3), dtype=np.float32))
    played = unwrapped.loop.rollout()
    raw = Batch(unwrapped.settings.model, 3)
    raw.bind("qpos")[:], raw.bind("qvel")[:] = played.q[:, 0], played.qd[:, 0]
    for k in range(played.dtau.shape[1]):
        raw.bind("ctrl")[:] = played.dtau[:, k]
        raw.step()
    assert np.array_equal(raw.bind("qpos"), played.q_final) and np.array_equal(raw.bind("qvel"), played.qd_final)
    env.close()


def test_the_synthetic_store_is_a_complete_sweep_with_the_real_schema(tmp_path):
    """What bench store measures is what a sweep writes: export and the audit take it as a finished sweep."""
    from mjtraj.bench import synthetic_store
    from mjtraj.study.export import export
    from mjtraj.study.store import read_rows
    from mjtraj.study.sweep import SweepSettings, columns

    path = tmp_path / "s.sqlite"
    assert synthetic_store(str(path), 1010) == 1012  # 253 scenarios x 4 planners, two units
    rows = read_rows(path)
    assert list(rows[0]) == columns(SweepSettings(families=("nominal",), scenarios=253, batch=250))
    assert sorted({int(r["scenario"]) for r in rows}) == list(range(253))
    assert export(path, tmp_path / "s.csv") == 1012


def test_bench_store_times_the_stages_asked_for(capsys):
    from mjtraj.bench import bench_store

    store = bench_store(400, ["audit --no-tasks"])
    assert store["rows"] == 400 and list(store["stages"]) == ["audit --no-tasks"]
    assert store["stages"]["audit --no-tasks"]["wall_s"] > 0 and store["stages"]["audit --no-tasks"]["peak_mb"] > 0
    assert main(["bench", "store", "--rows", "400", "--stages", "csv,xml"]) == 2
    assert capsys.readouterr().err.strip().endswith("got 'csv,xml'")


def test_busy_bench_reports_quiet_and_busy_times_of_the_public_api(monkeypatch):
    """bench busy: one row per timed call, the ratio busy over quiet, the child's environment without the thread
    counts the CLI set for itself (and with those the user set)."""
    import mjtraj.bench_busy as busy

    calls = iter([{"optimal": 1e-3, "env.step": 5e-5}, {"optimal": 1.5e-3, "env.step": 5e-5}])
    monkeypatch.setattr(busy, "_child", lambda: next(calls))
    rows = busy.bench_busy()
    assert [(r["call"], r["ratio"]) for r in rows] == [("optimal", pytest.approx(1.5)), ("env.step", 1.0)]
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")
    monkeypatch.setenv("MKL_NUM_THREADS", "4")
    monkeypatch.setenv("MJTRAJ_SET_THREADS", "OPENBLAS_NUM_THREADS")
    env = busy.user_environment()
    assert "OPENBLAS_NUM_THREADS" not in env and env["MKL_NUM_THREADS"] == "4"


@pytest.mark.slow
def test_api_timings_time_every_planner_and_the_env(monkeypatch):
    """`repeats` timed plans of the linear planner, `slow_repeats` of each nonlinear one, five passes of `env_steps`
    steps: the medians of the scripted spans, per plan and per step."""
    import mjtraj.bench_busy as busy

    clock = scripted(monkeypatch, busy, [3.0, 1.0, 2.0,  # optimal
                                         7.0, 5.0,  # nonlinear_min_effort
                                         11.0, 13.0,  # nonlinear_optimal
                                         1.0, 0.5, 2.5, 0.25, 4.0])  # five env passes of 5 steps
    times = busy.api_timings(repeats=3, slow_repeats=2, env_steps=5)
    assert clock.done
    assert busy.PLANNERS == ("optimal", "nonlinear_min_effort", "nonlinear_optimal")
    assert times == {"optimal": 2.0, "nonlinear_min_effort": 6.0, "nonlinear_optimal": 12.0, "env.step": 0.2}


def test_bench_json_prints_the_measurements_alone(capsys):
    """bench --json: stdout is one JSON object holding what the tables show (here the loop's rows)."""
    assert main(["bench", "loop", "--sizes", "1,2", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert [row["scenarios"] for row in record["loop"]] == [1, 2]
    for row in record["loop"]:
        assert row["ratio"] == pytest.approx(row["loop_steps_per_s"] / row["raw_steps_per_s"], rel=1e-12)


def test_the_docs_say_what_a_bare_bench_runs():
    """docs/cli.md: a bare `mjtraj bench` runs every stage but the ones it names. Oracle: the command's source, each
    stage's block run for "all" or only when named."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    source = (root / "mjtraj" / "cli" / "bench.py").read_text()
    with_all = set(re.findall(r'if args\.what in \("(\w+)", "all"\):', source))
    named_only = set(re.findall(r'if args\.what == "(\w+)":', source)) - {"all"}
    assert with_all and named_only and not with_all & named_only
    stated = re.search(r"A bare `mjtraj bench` runs all but ((?:`\w+`(?:, | and )?)+)", (root / "docs" / "cli.md")
                       .read_text())
    assert stated is not None and set(re.findall(r"`(\w+)`", stated[1])) == named_only
