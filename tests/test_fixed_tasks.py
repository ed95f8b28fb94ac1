"""The paper task and its reverse as audit conditions: their rows are what `compare` measures on those motions,
their comparisons are direct (one motion is a measurement), a changed scenario file is refused, and an oracle
scenario file is labelled as one."""

from __future__ import annotations

import pytest

from mjtraj.domain.scenario import default_scenario_path
from mjtraj.study.audit import weights_label, write_audit
from mjtraj.study.comparison import compare
from mjtraj.study.fixed_tasks import TASKS, task_rows
from mjtraj.study.runner import run_sweep
from mjtraj.study.store import read_rows
from mjtraj.study.sweep import SweepSettings

PLANNERS = ("optimal", "cubic", "quintic", "trapezoidal")


def test_settings_rebuild_from_a_row():
    settings = SweepSettings(families=("aggressive", "mismatch"), scenarios=7, seed=3, planners=("cubic", "min_effort"),
                             ff_accel=("step_average",), gravity_comp=("native", "zoh"), batch=4, sensor_noise=1e-4,
                             delay=1, model_error=True, config="paper_tuned")
    as_strings = {k: str(v) for k, v in settings.record().items()}
    assert SweepSettings.from_record(as_strings).as_dict() == settings.as_dict()


def test_task_rows_are_what_compare_measures_on_the_task_and_its_reverse(tmp_path):
    settings = SweepSettings(families=("nominal",), scenarios=2, batch=2, planners=("optimal", "cubic"),
                             gravity_comp=("native", "zoh"))
    run_sweep(settings, tmp_path / "s.csv", progress=False)
    rows, why = task_rows(read_rows(tmp_path / "s.csv")[0])
    assert why == "" and len(rows) == 2 * 2 * 2  # tasks x planners x gravity modes
    base = settings.base
    for family, (q0, qg) in zip(TASKS, ((base.task.q0, base.task.qg), (base.task.qg, base.task.q0)), strict=True):
        for gc in ("native", "zoh"):
            scenario = base.replace(task={"q0": q0, "qg": qg}, loop={"gravity_comp": gc})
            expected = compare(scenario, ("optimal", "cubic")).metrics
            for planner in ("optimal", "cubic"):
                row = next(r for r in rows if (r["family"], r["planner"], r["gravity_comp"]) == (family, planner, gc))
                for metric in ("rms_err", "rms_dtau", "int_dtau", "cost"):
                    assert float(row[metric]) == pytest.approx(getattr(expected[planner], metric), rel=1e-12)


def test_a_changed_scenario_file_gives_no_task_rows(tmp_path):
    config = tmp_path / "mine.toml"
    shipped = default_scenario_path().read_text()
    config.write_text(shipped)
    settings = SweepSettings(scenarios=2, batch=2, planners=("cubic",), config=str(config))
    run_sweep(settings, tmp_path / "s.csv", progress=False)
    record = read_rows(tmp_path / "s.csv")[0]
    assert task_rows(record)[1] == ""
    assert "duration = 2.0" in shipped
    config.write_text(shipped.replace("duration = 2.0", "duration = 2.5"))
    rows, why = task_rows(record)
    assert rows == [] and why == (f"its scenario ({config}) now differs from the one the sweep ran (an edited file, "
                                  f"or a sweep written by another mjtraj version)")


def test_an_oracle_scenario_file_is_labelled_and_bryson_named():
    assert weights_label("paper_oracle") == "paper_oracle (ORACLE: tuned on its own task)"
    assert weights_label("paper_tuned") == "paper_tuned"
    assert weights_label("paper.toml (shipped)") == "Bryson weights (paper.toml)"
    assert weights_label("no/such/file.toml") == "no/such/file.toml"


@pytest.mark.slow
def test_the_audit_draws_the_frontier_and_places_each_weight_set_on_it(tmp_path):
    for config, name in ((None, "b.csv"), ("paper_tuned", "t.csv")):
        run_sweep(SweepSettings(scenarios=2, batch=2, planners=PLANNERS, config=config), tmp_path / name,
                  progress=False)
    text = write_audit([tmp_path / "b.csv", tmp_path / "t.csv"], tmp_path / "A.md")
    section = text.split("## The weight frontier on the paper task", 1)[1].split("\n## ", 1)[0]
    assert (tmp_path / "A_figures" / "frontier_paper_task.png").stat().st_size > 10_000
    task = next(r for r in task_rows(read_rows(tmp_path / "b.csv")[0])[0]
                if r["family"] == "paper task" and r["planner"] == "optimal")
    assert f"optimal, Bryson weights (paper.toml): {float(task['rms_dtau']):.4g}, {float(task['rms_err']):.4g}" \
        in section
    assert "| paper_tuned: reverse task, ff_accel=sample, gravity_comp=native |" in text


@pytest.mark.slow
def test_each_planners_reference_on_the_fixed_motions_is_executed_above_its_floor():
    from mjtraj.study import SweepSettings, run_unit
    from mjtraj.study.fixed_tasks import task_floors

    settings = SweepSettings(families=("nominal",), scenarios=1, seed=0, planners=("optimal", "cubic"))
    record = {k: str(v) for k, v in run_unit(settings, ("nominal", 0)).rows[0].items()}
    rows, why = task_floors(record)
    assert why == "" and [(r["task"], r["planner"]) for r in rows] == [
        ("paper task", "optimal"), ("paper task", "cubic"), ("reverse task", "optimal"), ("reverse task", "cubic")]
    for r in rows:
        assert r["status"] == "ok" and 0 < r["floor"] <= r["cost"]
    paper = {r["planner"]: r for r in rows if r["task"] == "paper task"}
    assert paper["cubic"]["cost"] == pytest.approx(0.492, abs=5e-4)  # Table I's cubic row, the same execution
