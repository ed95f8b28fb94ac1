"""The row schema: columns in the file's order, NaN where nothing was measured, settings and extra columns last."""

from __future__ import annotations

import math

from mjtraj.core.metrics import METRIC_NAMES
from mjtraj.domain.families import draw_scenario
from mjtraj.domain.pipeline import Outcome
from mjtraj.study.rows import EXTRA_METRICS, Row


def test_columns_in_order(model):
    s = draw_scenario("mismatch", 0, 3, model, 0.02)
    row = Row(family="mismatch", scenario=3, unit=0, planner="cubic", ff_accel="sample", gravity_comp="native",
              outcome=Outcome("ok", "", dict.fromkeys(METRIC_NAMES, 1.0)), extras={"plan_effort": 2.0},
              task=s.task, perturbation=s.perturbation, settings={"sweep_seed": 0}, more={"policy": ""}).columns()
    names = list(row)
    assert names[:8] == ["family", "scenario", "unit", "planner", "ff_accel", "gravity_comp", "status", "reason"]
    assert names[8:8 + len(METRIC_NAMES)] == list(METRIC_NAMES)
    assert names[8 + len(METRIC_NAMES):10 + len(METRIC_NAMES)] == list(EXTRA_METRICS)
    assert names[-2:] == ["sweep_seed", "policy"]
    assert row["plan_effort"] == 2.0 and math.isnan(row["model_error"])
    assert row["payload_kg"] == s.perturbation.payload and row["q0_2"] == s.task.q0[2]


def test_a_failed_row_has_nan_metrics_and_nominal_rows_nan_perturbations(model):
    s = draw_scenario("nominal", 0, 1, model, 0.02)
    row = Row(family="nominal", scenario=1, unit=0, planner="optimal", ff_accel="sample", gravity_comp="native",
              outcome=Outcome("infeasible", "InfeasibleError: x"), task=s.task, settings={}).columns()
    assert row["status"] == "infeasible" and all(math.isnan(row[m]) for m in METRIC_NAMES)
    assert math.isnan(row["payload_kg"]) and math.isnan(row["friction_2"])
