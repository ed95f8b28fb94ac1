"""The paper's own motion and its reverse as audit conditions, beside the sweep's random families.

A sweep samples motions; the paper shows one. The audit therefore also runs each sweep's planners, controller
variants and scenario file on two fixed motions: the scenario's task ("paper task": q0 to qg in T) and the same move
backwards ("reverse task": qg to q0), on the nominal plant, scored by Bryson's rule on the task as sweeps score it.
They go through the sweep's own unit code, so their rows are exactly what a sweep would write for them. A fixed
motion is one measurement, not a sample: the audit compares its values directly rather than by bootstrap.
"""

from __future__ import annotations

import csv
import io

from mjtraj.core.task import Task
from mjtraj.domain.families import FamilyScenario
from mjtraj.exceptions import MjtrajError
from mjtraj.study.store import csv_text
from mjtraj.study.sweep import SweepSettings, columns, plan_scenarios, scenario_rows, scoring_weights

TASKS = ("paper task", "reverse task")
"""The fixed motions' family names in rows and audit conditions."""


def fixed_scenarios(settings: SweepSettings) -> list[tuple[str, FamilyScenario]]:
    """(family name, scenario) of the base scenario's task and its reverse, on the nominal plant."""
    task = settings.base.task
    reverse = Task.create(task.qg, task.q0, task.duration, task.dt, model=settings.base.model)
    return [(name, FamilyScenario(name, 0, t, None, 0)) for name, t in zip(TASKS, (task, reverse), strict=True)]


def task_rows(record: dict[str, str]) -> tuple[list[dict[str, str]], str]:
    """The rows, as a results file holds them (strings), of the sweep that wrote `record` (any of its rows) on the
    two fixed motions; or no rows and why they cannot be computed (the scenario file is gone or has changed)."""
    try:
        settings = SweepSettings.from_record(record)
    except MjtrajError as e:
        return [], f"cannot rebuild the sweep's settings ({e})"
    if settings.record()["config_sha256"] != record.get("config_sha256"):
        return [], (f"its scenario ({record.get('config')}) now differs from the one the sweep ran (an edited file, "
                    f"or a sweep written by another mjtraj version)")
    rows = []
    for name, scenario in fixed_scenarios(settings):
        rows += scenario_rows(settings, (name, 0), [scenario], scoring_weights(settings, [scenario]))
    header = columns(settings)
    return list(csv.DictReader(io.StringIO(csv_text(header, rows)))), ""


def task_floors(record: dict[str, str]) -> tuple[list[dict[str, object]], str]:
    """On the two fixed motions, each planner of the sweep that wrote `record`: its execution's J_exec under the
    sweep's controller (first controller variant) and the clairvoyant floor of its reference (`mjtraj.domain.floor`):
    how well each reference can be executed at best. Or no records and why they cannot be computed."""
    import dataclasses

    import numpy as np

    from mjtraj.domain.floor import floor_of
    from mjtraj.domain.pipeline import Job, execute_batch

    try:
        settings = SweepSettings.from_record(record)
    except MjtrajError as e:
        return [], f"cannot rebuild the sweep's settings ({e})"
    base = settings.base
    config = dataclasses.replace(settings.loop_config(settings.ff_accel[0], settings.gravity_comp[0],
                                                      mismatch=False), gravity_comp="native")
    out: list[dict[str, object]] = []
    for name, scenario in fixed_scenarios(settings):
        weights = scoring_weights(settings, [scenario])[0]
        move = float(np.max(np.abs(scenario.task.displacement)))
        plans = plan_scenarios(settings, [scenario])  # the sweep's own planners and variants
        for planner in settings.planners:
            record_out: dict[str, object] = {"task": name, "planner": planner}
            reference = plans[planner][0]
            try:
                if isinstance(reference, MjtrajError):
                    raise reference
                job = Job(reference, weights)
                _, outcomes = execute_batch(base.model, config, [job])
                found = floor_of(base.model, config, job, displacement=move)
            except MjtrajError as e:
                out.append({**record_out, "error": str(e)})
                continue
            out.append({**record_out, "cost": outcomes[0].metrics.get("cost", float("nan")),
                        "status": outcomes[0].status, "floor": found.cost})
    return out, ""
