"""Sweeps, their statistics and the audit: oracles (mj_inverse, OSQP, closed forms), determinism, resume, bad input."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from oracles import assert_provenance

from mjtraj.core.closed_loop import ClosedLoop, LoopConfig
from mjtraj.core.planners import make
from mjtraj.exceptions import InvalidInputError
from mjtraj.study.runner import run_sweep
from mjtraj.study.sweep import SweepSettings, run_unit

SMALL = dict(scenarios=6, batch=3, planners=("optimal", "cubic"))



@pytest.mark.slow
def test_unit_rows_are_deterministic_and_backend_independent(tmp_path):
    settings = SweepSettings(**SMALL)
    one, two = run_unit(settings, ("nominal", 1)), run_unit(settings, ("nominal", 1))
    assert one.rows == two.rows or all(
        all((a[k] == b[k]) or (a[k] != a[k] and b[k] != b[k]) for k in a)
        for a, b in zip(one.rows, two.rows, strict=True))
    run_sweep(settings, tmp_path / "a.csv", workers=1, progress=False)
    run_sweep(settings, tmp_path / "b.csv", workers=2, progress=False)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    rows = list(csv.DictReader(open(tmp_path / "a.csv")))
    assert len(rows) == 12 and {r["status"] for r in rows} == {"ok"}
    for row in rows:  # the workers' (b.csv's, the same bytes) and this process's: every field, from its source
        assert_provenance(row)
    assert {r["sweep_seed"] for r in rows} == {"0"} and {r["sweep_planners"] for r in rows} == {"optimal+cubic"}



def test_a_failed_scenario_is_recorded_and_the_sweep_goes_on(tmp_path):
    settings = SweepSettings(families=("aggressive",), scenarios=60, batch=30, planners=("optimal", "cubic"))
    report = run_sweep(settings, tmp_path / "s.csv", workers=1, progress=False)  # scenario 49 is infeasible
    rows = list(csv.DictReader(open(tmp_path / "s.csv")))
    assert len(rows) == 120 and report.statuses["infeasible"] >= 1 and report.statuses["ok"] >= 100
    bad = [r for r in rows if r["status"] == "infeasible"]
    assert all(r["planner"] == "optimal" and r["reason"].startswith("InfeasibleError: optimal: x_N = 0 cannot") and
               r["rms_err"] == "nan" for r in bad)



@pytest.mark.parametrize(("kwargs", "message"), [
    ({"families": ("nominl",)}, "family: unknown value 'nominl'; valid: nominal, aggressive, mismatch"),
    ({"planners": ("splines",)}, "planner: unknown value 'splines'; valid: cubic, optimal, "
                                 "nonlinear_optimal, nonlinear_min_effort, quintic, scurve, trapezoidal, "
                                 "optimal_start, min_effort"),
    ({"ff_accel": ("mean",)}, "ff_accel: unknown value 'mean'; valid: sample, step_average"),
    ({"delay": 2}, "delay: unknown value 2; valid: 0, 1"),
    ({"scenarios": 0}, "scenarios: expected a whole number >= 1, got 0"),
])
def test_bad_settings(kwargs, message):
    with pytest.raises(InvalidInputError) as info:
        SweepSettings(**kwargs)
    assert str(info.value) == message



def test_cli_reports_bad_family(capsys):
    from mjtraj.cli import main

    assert main(["sweep", "--family", "wild", "--out", "x.csv"]) == 2
    assert capsys.readouterr().err == ("mjtraj: error: family: unknown value 'wild'; valid: nominal, aggressive, "
                                       "mismatch\n")



def test_delay_and_noise(model, scenario):
    ref = make("cubic").plan(scenario.task, model)
    plain = ClosedLoop(model, scenario.loop).run([ref])
    silent = ClosedLoop(model, scenario.loop).run([ref], noise=np.zeros((100, 1, 6)))
    assert np.array_equal(plain.q, silent.q)
    delayed_cfg = LoopConfig(scenario.loop.gains, delay=1)
    delayed = ClosedLoop(model, delayed_cfg).run([ref])
    command = np.clip(delayed.tau_ff + delayed.tau_fb, -60, 60)
    assert np.all(delayed.dtau[0, 0] == 0.0)
    np.testing.assert_array_equal(delayed.dtau[0, 1:], command[0, :-1])



def test_variants_run_on_a_tuned_scenario():
    """min_effort (alpha = 0) and optimal_start keep working when the base scenario carries tuned alpha and split."""
    settings = SweepSettings(scenarios=2, batch=2, planners=("min_effort", "optimal_start", "optimal"),
                             config="paper_tuned")
    rows = run_unit(settings, ("nominal", 0)).rows
    assert {r["status"] for r in rows} == {"ok"} and len(rows) == 6


@pytest.mark.slow
@pytest.mark.parametrize("settle", [0.0, 0.5])
def test_a_sweep_with_floors_gives_each_row_its_floor_and_no_row_scores_below_it(model, settle):
    """Protocol v1's floor (J_exec, the goal reached) and, with a settle window, v2's (J_settle, at rest)."""
    from mjtraj.domain.families import perturbed_plant
    from mjtraj.domain.floor import floor_of
    from mjtraj.study.sweep import jobs_for, plan_scenarios, scoring_weights, unit_scenarios

    settings = SweepSettings(families=("mismatch",), scenarios=2, seed=4, planners=("cubic", "quintic"), floors=True,
                             settle=settle)
    rows = run_unit(settings, ("mismatch", 0)).rows
    assert len(rows) == 4 and all(r["sweep_floors"] == 1 for r in rows)
    for r in rows:
        assert np.isfinite(r["floor"]) and r["floor"] > 0
        if r["status"] == "ok":
            assert r["cost"] >= r["floor"]
            assert r["cost_over_floor"] == r["cost"] / r["floor"]
        else:
            assert np.isnan(r["cost_over_floor"])
    # the oracle: the floor of the same job computed alone
    scenarios = unit_scenarios(settings, ("mismatch", 0))
    plans = plan_scenarios(settings, scenarios)
    job = jobs_for(settings, scenarios[:1], [plans["quintic"][0]], scoring_weights(settings, scenarios[:1]))[0]
    alone = floor_of(model, settings.loop_config("sample", "native", mismatch=True), job, plant=perturbed_plant(model),
                     displacement=float(np.max(np.abs(scenarios[0].task.displacement))))
    row = next(r for r in rows if r["scenario"] == scenarios[0].index and r["planner"] == "quintic")
    assert row["floor"] == pytest.approx(alone.cost, rel=1e-9)
    # without floors the schema is what it was; the setting survives a results row
    plain = run_unit(SweepSettings(families=("nominal",), scenarios=1, seed=4, planners=("cubic",)), ("nominal", 0))
    assert "floor" not in plain.rows[0] and "sweep_floors" not in plain.rows[0]
    assert SweepSettings.from_record({k: str(v) for k, v in rows[0].items()}).floors
