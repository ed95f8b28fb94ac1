"""Randomised contracts (Hypothesis, seeded): random tasks through every planner, the loop and the metrics; random
mutations of a scenario file; random bad command lines. A small budget here, a large one in the slow tier."""

from __future__ import annotations

import contextlib
import io
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st
from oracles import same_outcome

from mjtraj.cli import main
from mjtraj.core.model import JointInfo, load_model
from mjtraj.core.planners import default_names, make
from mjtraj.core.reference import Reference
from mjtraj.core.task import Task
from mjtraj.domain.pipeline import STATUSES, Job, execute
from mjtraj.domain.scenario import default_scenario_path, load_scenario
from mjtraj.exceptions import InfeasibleError, MjtrajError

MODEL = load_model()
JOINTS = JointInfo.of(MODEL)
SCENARIO = load_scenario()
FAST = settings(max_examples=20, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
SLOW = settings(max_examples=300, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@st.composite
def tasks(draw: st.DrawFn, *, moderate: bool = False) -> Task:
    """A move inside the joint ranges, T from 0.2 to 3 s on the 0.02 s grid. `moderate`: every joint moves at most
    min(T, T^2) rad (T in s; MODERATE), a move every planner must plan."""
    unit = st.floats(0.0, 1.0)
    low, high = np.maximum(JOINTS.lower, -4.0), np.minimum(JOINTS.upper, 4.0)
    q0 = low + np.array([draw(unit) for _ in range(3)]) * (high - low)
    steps = draw(st.integers(10, 150))
    if moderate:
        T = steps * 0.02
        move = (2 * np.array([draw(unit) for _ in range(3)]) - 1) * min(T, T**2)
        qg = np.clip(q0 + move, low, high)
    else:
        qg = low + np.array([draw(unit) for _ in range(3)]) * (high - low)
    return Task.create(q0, qg, steps * 0.02, 0.02, model=MODEL)


MODERATE = ("a mean speed |dq|/T of at most 1 rad/s and a mean acceleration |dq|/T^2 of at most 1 rad/s^2 on every "
            "joint: under half of what the limits allow (scurve's joint speed limit pi rad/s, the optimal planner's "
            "60 N m torque bound; on 1,500 seeded random tasks the first refusals came at twice these)")
"""The tasks that no planner may refuse."""

MAY_REFUSE = {"optimal": "x_N = 0 out of reach within the torque bounds",
              "scurve": "the speed, acceleration and jerk limits need more than T"}
"""The planners with limits, which refuse a task beyond them with InfeasibleError (and why); every other planner
plans every task."""


def check_planned_and_executed(task: Task, name: str, *, moderate: bool = False) -> None:
    """Plan `task` with `name` and execute the plan; a refusal is allowed only as InfeasibleError, from a planner of
    MAY_REFUSE, on a task beyond MODERATE: anything else fails the test."""
    try:
        ref = make(name, **SCENARIO.planner_options.get(name, {})).plan(task, MODEL)
    except InfeasibleError as e:
        if moderate or name not in MAY_REFUSE:
            raise AssertionError(f"{name} refused a task it must plan ({task.q0} -> {task.qg} in {task.duration} "
                                 f"s): {e}") from e
        assert "\n" not in str(e) and str(e).startswith(f"{name}: ")
        return
    assert isinstance(ref, Reference) and ref.steps == task.steps
    np.testing.assert_array_equal(ref.q[0], task.q0)
    assert np.allclose(ref.q[-1], task.qg, atol=1e-6) and np.allclose(ref.qd[[0, -1]], 0.0, atol=1e-6)
    weights = SCENARIO.scoring.weights(task, SCENARIO.torque_limit)
    together = execute(MODEL, SCENARIO.loop, [Job(ref, weights), Job(ref, weights)])
    alone = execute(MODEL, SCENARIO.loop, [Job(ref, weights)])
    assert same_outcome(together[0], together[1]) and same_outcome(together[0], alone[0])  # batch equals single
    outcome = alone[0]
    assert outcome.status in STATUSES
    if outcome.status == "ok":
        assert all(math.isfinite(v) for k, v in outcome.metrics.items() if k != "rms_tau_total")
    else:
        assert outcome.reason


def test_the_planners_that_may_refuse_are_registered():
    assert set(MAY_REFUSE) <= set(default_names())


@pytest.mark.parametrize("name", default_names())
@FAST
@seed(20261122)
@given(task=tasks(moderate=True))
def test_random_tasks_through_every_planner(name: str, task: Task) -> None:
    """Each planner gets its own examples, all of which it must plan (MODERATE): none is skipped."""
    check_planned_and_executed(task, name, moderate=True)


@FAST
@seed(20261122)
@given(task=tasks(), name=st.sampled_from(default_names()))
def test_random_tasks_anywhere_are_planned_or_refused_as_infeasible(task: Task, name: str) -> None:
    check_planned_and_executed(task, name)


@pytest.mark.slow
@SLOW
@seed(20261122)
@given(task=tasks(), name=st.sampled_from(default_names()))
def test_random_tasks_through_every_planner_at_length(task: Task, name: str) -> None:
    check_planned_and_executed(task, name)


@pytest.mark.slow
@SLOW
@seed(20261122)
@given(task=tasks(moderate=True), name=st.sampled_from(default_names()))
def test_moderate_tasks_through_every_planner_at_length(task: Task, name: str) -> None:
    check_planned_and_executed(task, name, moderate=True)


VALUES = st.one_of(st.booleans(), st.integers(-5, 5), st.floats(allow_nan=False, allow_infinity=False),
                   st.text(max_size=6), st.lists(st.floats(-10, 10), max_size=7), st.just("{}"))


def toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if value == "{}":
        return "{}"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(repr(v) for v in value) + "]"
    return repr(value)


def check_mutated(tmp_path_factory: pytest.TempPathFactory, line: int, value: object) -> None:
    lines = default_scenario_path().read_text().splitlines()
    assignments = [i for i, text in enumerate(lines) if "=" in text and not text.lstrip().startswith("#")]
    i = assignments[line % len(assignments)]
    key = lines[i].split("=", 1)[0]
    lines[i] = f"{key}= {toml_value(value)}"
    path = tmp_path_factory.mktemp("mutated") / "s.toml"
    path.write_text("\n".join(lines) + "\n")
    try:
        load_scenario(path)
    except MjtrajError as e:
        assert "\n" not in str(e)


@pytest.mark.slow
@FAST
@seed(20261122)
@given(line=st.integers(0, 100), value=VALUES)
def test_mutated_scenario_files_load_or_fail_in_one_line(tmp_path_factory, line, value):
    check_mutated(tmp_path_factory, line, value)


@pytest.mark.slow
@SLOW
@seed(20261122)
@given(line=st.integers(0, 100), value=VALUES)
def test_mutated_scenario_files_at_length(tmp_path_factory, line, value):
    check_mutated(tmp_path_factory, line, value)


BAD = {
    "compare": [("--dt", ["0", "-1", "x", "1e-9", "0.03"]), ("--q0", ["a", "1,2", "9,9,9", "nan,0,0"]),
                ("--ff", ["model", ""]), ("--planners", ["spline", "cubic,cubic", ","]), ("--substeps", ["0", "x"]),
                ("--config", ["/nonexistent.toml", "/dev/null"])],
    "frontier": [("--alphas", ["-1", "x", "1,1"]), ("--splits", ["2", "-0.5"]), ("--family", ["hard"]),
                 ("--scenarios", ["1", "x", "50"]), ("--seed", ["3"])],
    "tune": [("--budget", ["0", "-3", "x"]), ("--family", ["hard"]), ("--planners", ["spline"]),
             ("--scenarios", ["0"])],
    "sweep": [("--family", ["hard", ""]), ("--seed", ["-1", "x"]), ("--batch", ["0"]), ("--scenarios", ["0"]),
              ("--planners", ["spline"]), ("--ff-accel", ["mean"]), ("--delay", ["2"]), ("--backend", ["gpu"]),
              ("--sensor-noise", ["-1", "nan"])],
    "render": [("--width", ["0", "5000", "x"]), ("--camera", ["back"]), ("--format", ["avi"]), ("--every", ["0"])],
    "bench": [("--sizes", ["0", "x", "-1"])],
    "audit": [("", ["/nonexistent.csv"])],
}


@st.composite
def bad_argv(draw: st.DrawFn) -> list[str]:
    command = draw(st.sampled_from(sorted(BAD)))
    flag, values = draw(st.sampled_from(BAD[command]))
    value = draw(st.sampled_from(values))
    junk = draw(st.lists(st.sampled_from(["--bogus", "-x", "--", "%", "--json"]), max_size=1))
    argv = [command, *([flag] if flag else []), value, *junk]
    return argv


def check_argv(argv: list[str], tmp_path_factory: pytest.TempPathFactory) -> None:
    out = tmp_path_factory.mktemp("out")
    if argv[0] in ("compare", "frontier", "render", "sweep", "tune"):
        argv = [*argv, "--out", str(out / ("o.toml" if argv[0] == "tune" else "o.csv" if argv[0] == "sweep"
                                          else "o"))]
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exit_:
            code = exit_.code
    assert code == 2, (argv, code, err.getvalue())
    message = err.getvalue()
    assert "Traceback" not in message and message.count("\n") == 1 and message.startswith("mjtraj: "), (argv, message)


@FAST
@seed(20261122)
@given(argv=bad_argv())
def test_bad_command_lines_end_in_one_line(argv, tmp_path_factory):
    check_argv(argv, tmp_path_factory)


@pytest.mark.slow
@SLOW
@seed(20261122)
@given(argv=bad_argv())
def test_bad_command_lines_at_length(argv, tmp_path_factory):
    check_argv(argv, tmp_path_factory)
