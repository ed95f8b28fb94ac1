"""The weight frontier: its alpha = 1 point is compare's optimal planner, alpha = 0 the minimum-effort plan, cubic
its own reference; family medians are the medians of the per-scenario values."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mjtraj.cli import main
from mjtraj.core.metrics import METRIC_NAMES
from mjtraj.core.scoring import Scoring
from mjtraj.exceptions import InvalidInputError
from mjtraj.study.comparison import compare
from mjtraj.study.frontier import frontier


def test_points_are_compares(scenario):
    result = frontier(scenario, alphas=(0.0, 1.0), splits=(0.5,))
    rows = {(r.planner, r.alpha): r for r in result.rows}
    bryson = compare(scenario, ("optimal", "cubic"))
    for metric in METRIC_NAMES:
        assert rows[("optimal", 1.0)].metrics[metric] == getattr(bryson.metrics["optimal"], metric)
        assert rows[("cubic", None)].metrics[metric] == getattr(bryson.metrics["cubic"], metric)
    options = dict(scenario.planner_options["optimal"], state_weight=(0.0,) * 6)
    least = compare(scenario.replace(planner_options={"optimal": options}), ("optimal",))
    assert rows[("optimal", 0.0)].metrics["cost"] == least.metrics["optimal"].cost
    assert rows[("cubic", None)].ratio["cost"].value == 1.0
    assert rows[("optimal", 1.0)].ratio["rms_dtau"].value == pytest.approx(
        bryson.metrics["optimal"].rms_dtau / bryson.metrics["cubic"].rms_dtau, rel=1e-15)


def test_split_moves_the_weight_between_positions_and_velocities(scenario):
    result = frontier(scenario, alphas=(0.01,), splits=(0.0, 0.5, 1.0))
    costs = [r.metrics["cost"] for r in result.rows if r.planner == "optimal"]
    assert len(set(costs)) == 3  # three different plans


def test_family_rows_are_medians(scenario):
    result = frontier(scenario, alphas=(1.0,), family="nominal", scenarios=5, seed=3)
    from mjtraj.domain.families import draw_scenario

    draws = [draw_scenario("nominal", 3, i, scenario.model, 0.02) for i in range(5)]
    costs = []
    for d in draws:
        one = compare(scenario.replace(task={"q0": d.task.q0, "qg": d.task.qg}, scoring=Scoring()), ("cubic",))
        costs.append(one.metrics["cubic"].cost)
    cubic = next(r for r in result.rows if r.planner == "cubic")
    assert cubic.metrics["cost"] == np.median(costs)
    assert result.setting["score"] == "Bryson's rule per task"


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"alphas": (-1.0,)}, r"^alphas: expected numbers in \[0, 1e\+12\], got -1.0$"),
    ({"alphas": (1.0, 1.0)}, r"^alphas: expected distinct values, got 1.0, 1.0$"),
    ({"splits": (1.5,)}, r"^splits: expected numbers in \[0, 1\], got 1.5$"),
    ({"family": "hard", "scenarios": 5}, r"^family: unknown value 'hard'; valid: nominal, aggressive, mismatch$"),
    ({"family": "nominal", "scenarios": 1}, r"^scenarios: expected a whole number >= 2 for a family, got 1$"),
])
def test_bad_arguments(scenario, kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        frontier(scenario, **kwargs)


def test_cli_writes_the_table_json_and_figure(tmp_path, capsys):
    assert main(["frontier", "--alphas", "0,0.01,1", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Weight frontier of the optimal planner: Q = alpha * Q_bryson")
    assert "score: the scenario's (fixed)" in out
    record = json.loads((tmp_path / "frontier.json").read_text())
    assert [r["alpha"] for r in record["rows"]] == [0.0, 0.01, 1.0, None, None, None, None]
    assert [r["planner"] for r in record["rows"]][3:] == ["cubic", "quintic", "trapezoidal", "scurve"]
    assert set(METRIC_NAMES) <= set(record["rows"][0])
    assert (tmp_path / "frontier.png").stat().st_size > 10_000
    assert main(["frontier", "--alphas", "-1", "--out", str(tmp_path / "x")]) == 2
    assert capsys.readouterr().err == "mjtraj: error: alphas: expected numbers in [0, 1e+12], got -1.0\n"
    assert not (tmp_path / "x").exists()
