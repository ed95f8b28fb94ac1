"""The paper's study: plan with every planner, execute through one batched closed loop, score."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from mjtraj.core.gains import GAIN_RULE
from mjtraj.core.metrics import GOAL_TOLERANCE, Metrics
from mjtraj.core.planners import check_name, default_names
from mjtraj.core.reference import Reference
from mjtraj.core.stability import spectral_radii
from mjtraj.domain.comparison import Comparison
from mjtraj.domain.pipeline import Job, execute_batch, goal_checked, one_line
from mjtraj.domain.scenario import Scenario
from mjtraj.exceptions import InfeasibleError, InvalidInputError, MjtrajError, SolverError
from mjtraj.study.paper import PAPER_TABLE
from mjtraj.versions import versions

PAPER_ORDER = ("optimal", "cubic", "quintic", "trapezoidal")


def default_planners() -> tuple[str, ...]:
    """Every registered planner but those run on request (the nonlinear bounds), the paper's four first in the
    paper's order."""
    names = default_names()
    return tuple([p for p in PAPER_ORDER if p in names] + [p for p in names if p not in PAPER_ORDER])


def compare(scenario: Scenario, planners: Sequence[str] | None = None, *,
            progress: Callable[[str], None] | None = None) -> Comparison:
    """Plan `scenario.task` with each planner (default: all registered, paper order first) and execute all
    references together through the evaluation pipeline with the scenario's controller and scoring.

    Args:
      progress: called with a short label before each stage (for a progress bar).

    A planner that cannot plan the task (InfeasibleError, SolverError) is left out with its reason (`failed`);
    the others run.

    Raises:
      InvalidInputError: no planner, an unknown or repeated one, or a task outside the joint ranges.
      InfeasibleError, SolverError: no planner could plan the task (the first one's error).
    """
    names = tuple(planners) if planners is not None else default_planners()
    if not names:
        raise InvalidInputError("planners: expected at least one planner, got none")
    for name in names:
        check_name("planners", name)
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise InvalidInputError(f"planners: expected distinct planners, got {', '.join(repeated)} more than once")
    model = scenario.model
    scenario.task.check_limits(model)
    references: dict[str, Reference] = {}
    failed: dict[str, str] = {}
    errors: list[MjtrajError] = []
    for name in names:
        if progress:
            progress(f"plan {name}")
        try:
            references[name] = scenario.planner(name).plan(scenario.task, model)
        except (InfeasibleError, SolverError) as e:  # that planner has no row; the others run
            failed[name] = one_line(e)
            errors.append(e)
    if not references:
        raise errors[0]
    names = tuple(name for name in names if name in references)
    if progress:
        progress("execute")
    weights = (scenario.Q_exec, scenario.R_exec)
    rollout, outcomes = execute_batch(model, scenario.loop, [Job(references[n], weights) for n in names], nthread=0,
                                      total_torque=True)
    if progress:
        progress("stability check")
    move = float(np.max(np.abs(scenario.task.displacement)))
    checked = {name: goal_checked(result, move) for name, result in zip(names, outcomes, strict=True)}
    scored = {name: Metrics(**result.metrics) if result.metrics else Metrics.nan() for name, result in checked.items()}
    return Comparison(scenario=scenario, planners=names, references=references, rollout=rollout, metrics=scored,
                      stability=stability(scenario, names, references), failed=failed, outcomes=checked)


def stability(scenario: Scenario, names: tuple[str, ...], references: dict[str, Reference]) -> dict[str, float]:
    """The spectral radii of `mjtraj.core.stability.spectral_radii` along the planners' references, computed once
    per scenario and set of planners; NaN for a law other than pid (the check models feedforward + PID)."""
    if scenario.loop.controller != "pid":  # the check linearises feedforward + PID with diagonal gains
        return {"at_rest": float("nan"), "moving": float("nan")}
    key = ("stability", names)
    if key not in scenario.memo:
        scenario.memo[key] = spectral_radii(scenario.model, scenario.loop.gains, [references[n] for n in names])
    return dict(scenario.memo[key])


def comparison_record(result: Comparison) -> dict[str, Any]:
    """Everything about a comparison as JSON-ready data (results.json)."""
    planners = {}
    for name in result.planners:
        ref = result.references[name]
        planners[name] = {
            "metrics": result.metrics[name].as_dict(),
            "reduction_pct": {"int_dtau": result.reduction(name, "int_dtau"), "cost": result.reduction(name, "cost"),
                              "rms_dtau": result.reduction(name, "rms_dtau"),
                              "rms_err": result.reduction(name, "rms_err")} if name != "optimal" else None,
            "diverged_step": int(result.rollout.diverged_step[result.planners.index(name)]),
            "status": result.outcomes[name].status if name in result.outcomes else "ok",
            "reason": result.outcomes[name].reason if name in result.outcomes else "",
            "plan": {k: v for k, v in ref.info.items()},
        }
    return {"scenario": result.scenario.as_dict(), "scenario_file": result.scenario.source,
            "gain_rule": GAIN_RULE, "stability": result.stability, "versions": versions(), "planners": planners,
            "not_planned": dict(result.failed), "goal_tolerance": GOAL_TOLERANCE,
            **({"paper_table_i": PAPER_TABLE} if result.scenario.model_path is None else {})}
