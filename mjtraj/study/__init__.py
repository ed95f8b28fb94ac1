"""The study layer, the experiments: comparisons, sweeps and their store, backends, the floors of a family,
tuning, statistics, the audit, reports and plots. They build on the domain layer (scenarios, families, jobs and
their execution, the floor of a job), whose names are also exported here as before. It never imports envs or rl.
Every name below loads on first use."""

from __future__ import annotations

from typing import TYPE_CHECKING

from mjtraj._lazy import lazy_exports

_EXPORTS = {
    "FIGURE_FORMATS": "mjtraj.study.plots",
    "save_figure": "mjtraj.study.plots",
    "Scenario": "mjtraj.domain.scenario",
    "load_scenario": "mjtraj.domain.scenario",
    "scenario_text": "mjtraj.domain.scenario",
    "scenario_for_model": "mjtraj.domain.scenario",
    "scenario_from_dict": "mjtraj.domain.scenario",
    "default_scenario_path": "mjtraj.domain.scenario",
    "FAMILIES": "mjtraj.domain.families",
    "FAMILY_ID": "mjtraj.domain.families",
    "FamilyScenario": "mjtraj.domain.families",
    "PAYLOAD_MASS": "mjtraj.domain.families",
    "Perturbation": "mjtraj.domain.families",
    "draw_scenario": "mjtraj.domain.families",
    "draw_family": "mjtraj.domain.families",
    "arm_scales": "mjtraj.domain.families",
    "perturbed_plant": "mjtraj.domain.families",
    "plant_fields": "mjtraj.domain.families",
    "measurement_noise": "mjtraj.domain.families",
    "draw_perturbation": "mjtraj.domain.families",
    "no_perturbation": "mjtraj.domain.families",
    "noise_scale": "mjtraj.domain.families",
    "Actor": "mjtraj.domain.pipeline",
    "Floor": "mjtraj.domain.floor",
    "floor_of": "mjtraj.domain.floor",
    "floors_of": "mjtraj.domain.floor",
    "family_floors": "mjtraj.study.floor",
    "ORACLE_LABEL": "mjtraj.domain.oracle",
    "TrueParameters": "mjtraj.domain.oracle",
    "true_parameters": "mjtraj.domain.oracle",
    "Job": "mjtraj.domain.pipeline",
    "Outcome": "mjtraj.domain.pipeline",
    "execute": "mjtraj.domain.pipeline",
    "execute_batch": "mjtraj.domain.pipeline",
    "plan_failure": "mjtraj.domain.pipeline",
    "one_line": "mjtraj.domain.pipeline",
    "goal_checked": "mjtraj.domain.pipeline",
    "STATUSES": "mjtraj.domain.pipeline",
    "Row": "mjtraj.study.rows",
    "EXTRA_METRICS": "mjtraj.study.rows",
    "Comparison": "mjtraj.domain.comparison",
    "compare": "mjtraj.study.comparison",
    "comparison_record": "mjtraj.study.comparison",
    "SweepSettings": "mjtraj.study.sweep",
    "UnitResult": "mjtraj.study.sweep",
    "ActorSpec": "mjtraj.study.sweep",
    "run_unit": "mjtraj.study.sweep",
    "plan_scenarios": "mjtraj.study.sweep",
    "unit_scenarios": "mjtraj.study.sweep",
    "scoring_weights": "mjtraj.study.sweep",
    "jobs_for": "mjtraj.study.sweep",
    "fixed_columns": "mjtraj.study.sweep",
    "columns": "mjtraj.study.sweep",
    "planner_names": "mjtraj.study.sweep",
    "DEFAULT_PLANNERS": "mjtraj.study.sweep",
    "VARIANTS": "mjtraj.study.sweep",
    "SWEPT": "mjtraj.study.sweep",
    "ResultsFile": "mjtraj.study.store",
    "read_rows": "mjtraj.study.store",
    "numeric": "mjtraj.study.store",
    "csv_text": "mjtraj.study.store",
    "append_rows": "mjtraj.study.store",
    "VERSION_COLUMNS": "mjtraj.study.store",
    "SweepReport": "mjtraj.study.runner",
    "run_sweep": "mjtraj.study.runner",
    "BACKENDS": "mjtraj.study.backends",
    "PairedRatio": "mjtraj.study.stats",
    "paired_ratio": "mjtraj.study.stats",
    "ratio_of_means": "mjtraj.study.stats",
    "cvar": "mjtraj.study.stats",
    "Condition": "mjtraj.study.audit",
    "SweepData": "mjtraj.study.audit",
    "write_audit": "mjtraj.study.audit",
    "PAPER_TABLE": "mjtraj.study.paper",
    "format_report": "mjtraj.study.report",
    "results_csv": "mjtraj.study.report",
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from mjtraj.domain.comparison import Comparison
    from mjtraj.domain.families import (
        FAMILIES,
        FAMILY_ID,
        PAYLOAD_MASS,
        FamilyScenario,
        Perturbation,
        arm_scales,
        draw_family,
        draw_perturbation,
        draw_scenario,
        measurement_noise,
        no_perturbation,
        noise_scale,
        perturbed_plant,
        plant_fields,
    )
    from mjtraj.domain.floor import Floor, floor_of, floors_of
    from mjtraj.domain.oracle import ORACLE_LABEL, TrueParameters, true_parameters
    from mjtraj.domain.pipeline import (
        STATUSES,
        Actor,
        Job,
        Outcome,
        execute,
        execute_batch,
        goal_checked,
        one_line,
        plan_failure,
    )
    from mjtraj.domain.scenario import (
        Scenario,
        default_scenario_path,
        load_scenario,
        scenario_for_model,
        scenario_from_dict,
        scenario_text,
    )
    from mjtraj.study.audit import Condition, SweepData, write_audit
    from mjtraj.study.backends import BACKENDS
    from mjtraj.study.comparison import compare, comparison_record
    from mjtraj.study.floor import family_floors
    from mjtraj.study.paper import PAPER_TABLE
    from mjtraj.study.plots import FIGURE_FORMATS, save_figure
    from mjtraj.study.report import format_report, results_csv
    from mjtraj.study.rows import EXTRA_METRICS, Row
    from mjtraj.study.runner import SweepReport, run_sweep
    from mjtraj.study.stats import PairedRatio, cvar, paired_ratio, ratio_of_means
    from mjtraj.study.store import VERSION_COLUMNS, ResultsFile, append_rows, csv_text, numeric, read_rows
    from mjtraj.study.sweep import (
        DEFAULT_PLANNERS,
        SWEPT,
        VARIANTS,
        ActorSpec,
        SweepSettings,
        UnitResult,
        columns,
        fixed_columns,
        jobs_for,
        plan_scenarios,
        planner_names,
        run_unit,
        scoring_weights,
        unit_scenarios,
    )

__all__ = [
    "FIGURE_FORMATS", "Floor", "family_floors", "floor_of", "floors_of",
    "Actor", "ActorSpec", "BACKENDS", "Comparison", "Condition", "DEFAULT_PLANNERS", "EXTRA_METRICS", "FAMILIES",
    "FAMILY_ID", "FamilyScenario", "Job", "ORACLE_LABEL", "Outcome", "PAPER_TABLE", "PAYLOAD_MASS", "PairedRatio",
    "Perturbation", "ResultsFile", "Row", "STATUSES", "SWEPT", "Scenario", "SweepData", "SweepReport",
    "SweepSettings", "TrueParameters", "UnitResult", "VARIANTS", "VERSION_COLUMNS", "append_rows", "arm_scales",
    "columns", "compare", "comparison_record", "csv_text", "cvar", "default_scenario_path", "draw_family",
    "draw_perturbation", "draw_scenario", "execute", "execute_batch", "fixed_columns", "format_report",
    "goal_checked", "jobs_for", "load_scenario", "measurement_noise", "no_perturbation", "noise_scale", "numeric",
    "one_line", "paired_ratio", "perturbed_plant", "plan_failure", "plan_scenarios", "planner_names", "plant_fields",
    "ratio_of_means", "read_rows", "results_csv", "run_sweep", "run_unit", "save_figure", "scenario_for_model",
    "scenario_from_dict", "scenario_text", "scoring_weights", "true_parameters", "unit_scenarios", "write_audit",
]
