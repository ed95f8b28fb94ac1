"""Tuning: the same optimiser and budget for every planner, training scenarios disjoint from every evaluation
stream, the best trial kept, and a tuned scenario file that reads back and runs."""

from __future__ import annotations

import numpy as np
import pytest

from mjtraj.cli import main
from mjtraj.core.scoring import Scoring
from mjtraj.domain.families import FAMILIES, FAMILY_ID, draw_scenario
from mjtraj.domain.scenario import load_scenario
from mjtraj.exceptions import InvalidInputError
from mjtraj.study.tuning import PARAMETERS, TRAIN_STREAM, objective, planner_with, points, training_stream, tune

SMALL = {"scenarios": 3, "budget": 4}


def test_points_fill_the_box_deterministically():
    box = PARAMETERS["optimal"]
    a, b = points(box, 16, 1), points(box, 16, 1)
    assert a == b and len(a) == 16 and points(box, 16, 2) != a
    assert all(1e-6 <= p["alpha"] <= 1e2 and 0 <= p["split"] <= 1 for p in a)
    assert all(1.0 < p["cruise_factor"] <= 2.0 for p in points(PARAMETERS["trapezoidal"], 64, 0))
    assert points(PARAMETERS["cubic"], 16, 0) == [{}]


def test_equal_budget_and_the_best_trial_is_kept(scenario):
    tuned, results = tune(scenario, planners=("optimal", "trapezoidal", "cubic"), **SMALL)
    assert [len(r.trials) for r in results] == [4, 4, 1]
    for r in results:
        assert r.best.objective == min(t.objective for t in r.trials)
    optimal = results[0].best
    assert tuned.planner_options["optimal"]["alpha"] == optimal.parameters["alpha"]
    assert "state_weight" not in tuned.planner_options["optimal"]
    # the recorded objective is re-obtained from the parameters alone (the oracle: a fresh evaluation)
    draws = [draw_scenario("nominal", 0, i, scenario.model, 0.02, stream=training_stream("nominal"))
             for i in range(3)]
    again, failed = objective(scenario, planner_with(scenario, "optimal", optimal.parameters), draws, Scoring(),
                              "nominal")
    assert (again, failed) == (optimal.objective, 0)
    assert tuned.name == "paper_tuned" and tuned.tuning["mode"] == "held out"
    assert tuned.tuning["result"]["optimal"]["evaluations"] == 4


def test_training_scenarios_are_held_out(scenario):
    """Streams differ from every family's and RL's, and no training task is an evaluation task."""
    assert {training_stream(f) for f in FAMILIES}.isdisjoint(set(FAMILY_ID.values()) | {16, 17})
    assert TRAIN_STREAM == 32
    train = {tuple(draw_scenario("nominal", 0, i, scenario.model, 0.02, stream=training_stream("nominal")).task.q0)
             for i in range(200)}
    for family in FAMILIES:
        evaluation = {tuple(draw_scenario(family, 0, i, scenario.model, 0.02).task.q0) for i in range(200)}
        assert train.isdisjoint(evaluation)


def test_oracle_mode_is_labelled(scenario):
    tuned, results = tune(scenario, planners=("optimal",), budget=4, on_task=True)
    assert tuned.name == "paper_oracle" and tuned.tuning["mode"].startswith("oracle")
    assert tuned.tuning["scenarios"] == 1


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"budget": 0}, r"^budget: expected a whole number >= 1, got 0$"),
    ({"planners": ("spline",)}, r"^planners: unknown planner 'spline'; valid: cubic, optimal, "
                                r"nonlinear_optimal, nonlinear_min_effort, quintic, scurve, trapezoidal$"),
    ({"family": "hard"}, r"^family: unknown value 'hard'; valid: nominal, aggressive, mismatch$"),
    ({"scenarios": 0}, r"^scenarios: expected a whole number >= 1, got 0$"),
])
def test_bad_arguments(scenario, kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        tune(scenario, **{**SMALL, **kwargs})


def test_cli_writes_a_scenario_that_reads_back_and_runs(tmp_path, capsys):
    path = tmp_path / "tuned.toml"
    assert main(["tune", "--scenarios", "3", "--budget", "4", "--out", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("optimal: alpha = ") and out.rstrip().endswith("(held out)")
    tuned = load_scenario(path)
    assert tuned.name == "paper_tuned" and tuned.tuning["budget"] == 4
    assert set(tuned.planner_options["optimal"]) == {"linearization", "alpha", "split"}
    np.testing.assert_array_equal(tuned.loop.gains.kp, load_scenario().loop.gains.kp)
    assert main(["compare", "--config", str(path), "--no-figures", "--out", str(tmp_path / "r")]) == 0
    capsys.readouterr()
    path.write_text(path.read_text().replace("alpha = ", "alfa = "))
    assert main(["compare", "--config", str(path), "--out", str(tmp_path / "r")]) == 2
    assert "planner 'optimal': unknown option 'alfa'; valid:" in capsys.readouterr().err
    assert main(["tune", "--budget", "0", "--out", str(tmp_path / "x.toml")]) == 2
    assert capsys.readouterr().err == "mjtraj: error: budget: expected a whole number >= 1, got 0\n"
    assert not (tmp_path / "x.toml").exists()
