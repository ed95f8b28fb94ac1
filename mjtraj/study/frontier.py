"""The optimal planner's weight frontier: its plans for Q = alpha Q_bryson (R = R_bryson fixed), alpha from 0 (the
minimum-effort plan of the linear model) to far above Bryson's 1, and for several position/velocity splits; every
plan executed through the one pipeline and scored by the scenario's fixed score, beside the other planners.

On one task (the scenario's) the table holds each alpha's metrics and their ratios to cubic. Over a family of
scenarios it holds medians over the scenarios, with 95 % bootstrap intervals of the median ratio to cubic.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mjtraj.checks import seed_value
from mjtraj.core.planners import Planner, make, plan_all
from mjtraj.core.reference import Reference
from mjtraj.core.scoring import Scoring
from mjtraj.domain.families import FAMILIES, FamilyScenario, draw_scenario, perturbed_plant
from mjtraj.domain.pipeline import Job, Outcome, execute, plan_failure
from mjtraj.domain.scenario import Scenario
from mjtraj.exceptions import InvalidInputError, MjtrajError
from mjtraj.study.comparison import default_planners
from mjtraj.study.stats import Median, median_interval

DEFAULT_ALPHAS = (0.0, *(float(a) for a in np.logspace(-6, 2, 33)))
"""0 and 33 values from 1e-6 to 1e2, four per decade (1 is among them)."""
DEFAULT_SPLITS = (0.5,)
"""Bryson's own balance of position and velocity weights."""
TABLE_METRICS = ("rms_dtau", "int_dtau", "rms_err", "peak_dtau", "cost")
REFERENCE = "cubic"
"""The planner every row is compared with (the minimum-effort plan of a constant-inertia arm)."""


@dataclass(frozen=True)
class FrontierRow:
    """One point: the optimal planner at (alpha, split), or another planner (alpha, split None).

    metrics: name -> value (one task) or median over the scenarios (a family); ratio: name -> its ratio to cubic
    (one task), or the median of the per-scenario ratios with its interval (a family); failed: scenarios without
    metrics (plan failed, diverged, unstable); reasons: the distinct one-line reasons of those failures.
    """

    planner: str
    alpha: float | None
    split: float | None
    metrics: dict[str, float]
    ratio: dict[str, Median]
    failed: int
    reasons: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {"planner": self.planner, "alpha": self.alpha, "split": self.split, **self.metrics,
                "ratio_to_cubic": {k: (m.value if m.count <= 1 else
                                       {"median": m.value, "low": m.low, "high": m.high, "count": m.count})
                                   for k, m in self.ratio.items()},
                "failed": self.failed, "failure_reasons": list(self.reasons)}


@dataclass(frozen=True)
class Frontier:
    """The rows, in table order (the optimal planner's by split then alpha, then the other planners), and how they
    were made."""

    rows: list[FrontierRow]
    setting: dict[str, Any] = field(default_factory=dict)


def _checked(name: str, values: Sequence[float], low: float, high: float) -> tuple[float, ...]:
    out = []
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (low <= v <= high) or not np.isfinite(v):
            raise InvalidInputError(f"{name}: expected numbers in [{low:g}, {high:g}], got {v!r}")
        out.append(float(v))
    if not out:
        raise InvalidInputError(f"{name}: expected at least one value, got none")
    if len(set(out)) != len(out):
        raise InvalidInputError(f"{name}: expected distinct values, got {', '.join(map(str, out))}")
    return tuple(out)


def optimal_at(scenario: Scenario, alpha: float, split: float) -> Planner:
    """The scenario's optimal planner with Bryson's weights for each task, Q scaled by alpha and split."""
    options = {k: v for k, v in scenario.planner_options.get("optimal", {}).items()
               if k not in ("state_weight", "input_weight", "alpha", "split")}
    return make("optimal", **options, alpha=alpha, split=split)


def frontier(scenario: Scenario, *, alphas: Sequence[float] = DEFAULT_ALPHAS,
             splits: Sequence[float] = DEFAULT_SPLITS, family: str | None = None, scenarios: int = 0,
             seed: int = 0, progress: Callable[[int, int], None] | None = None) -> Frontier:
    """The weight frontier on the scenario's task (family None) or on `scenarios` scenarios of `family`;
    `progress(done, total)` is called as planning and execution advance.

    The score is the scenario's on its own task, and Bryson's rule per task over a family (as sweeps score them);
    the controller is the scenario's throughout.
    """
    alphas = _checked("alphas", alphas, 0.0, 1e12)
    splits = _checked("splits", splits, 0.0, 1.0)
    model = scenario.model
    draws, scoring = _draws(scenario, family, scenarios, seed)
    tasks = [d.task for d in draws]
    weights = [scoring.weights(t, scenario.torque_limit) for t in tasks]
    planners, others = _planners(scenario, alphas, splits)
    plans = []
    for *_, p in planners:
        plans.append(plan_all(p, tasks, model))
        if progress is not None:
            progress(len(plans), len(planners) + 1)
    plant = (perturbed_plant(model, scenario.model_path, scenario.model_torque_limit) if family == "mismatch"
             else None)
    outcomes = _outcomes(scenario, plans, weights, draws, plant)
    if progress is not None:
        progress(len(planners) + 1, len(planners) + 1)
    cubic = outcomes[len(planners) - len(others) + others.index(REFERENCE)]
    rows = [_row(name, a, s, mine, cubic) for (name, a, s, _), mine in zip(planners, outcomes, strict=True)]
    setting = {"task": "scenario" if family is None else family, "scenarios": len(draws), "seed": seed,
               "score": "the scenario's (fixed)" if family is None else "Bryson's rule per task",
               "scenario": scenario.name, "controller": {k: v for k, v in scenario.as_dict()["controller"].items()}}
    return Frontier(rows, setting)


def _draws(scenario: Scenario, family: str | None, scenarios: int, seed: int
           ) -> tuple[list[FamilyScenario], Scoring]:
    """The frontier's tasks and their score: the scenario's own task and score (family None), or `scenarios`
    draws of `family` (checked) scored by Bryson's rule per task."""
    if family is None:
        return [FamilyScenario("task", 0, scenario.task, None, 0)], scenario.scoring
    if family not in FAMILIES:
        raise InvalidInputError(f"family: unknown value {family!r}; valid: {', '.join(FAMILIES)}")
    if isinstance(scenarios, bool) or not isinstance(scenarios, int) or scenarios < 2:
        raise InvalidInputError(f"scenarios: expected a whole number >= 2 for a family, got {scenarios!r}")
    draws = [draw_scenario(family, seed_value("seed", seed), i, scenario.model, scenario.task.dt)
             for i in range(scenarios)]
    return draws, Scoring()


def _planners(scenario: Scenario, alphas: tuple[float, ...], splits: tuple[float, ...]
              ) -> tuple[list[tuple[str, float | None, float | None, Planner]], tuple[str, ...]]:
    """The frontier's planners as (name, alpha, split, planner): the optimal planner at each split and alpha, then
    the other default planners (alpha and split None); and the names of those others."""
    planners: list[tuple[str, float | None, float | None, Planner]] = [
        ("optimal", a, s, optimal_at(scenario, a, s)) for s in splits for a in alphas]
    others = tuple(name for name in default_planners() if name != "optimal")
    planners += [(name, None, None, scenario.planner(name)) for name in others]
    return planners, others


def _outcomes(scenario: Scenario, plans: list[list[Reference | MjtrajError]], weights: list[Any],
              draws: list[FamilyScenario], plant: Any) -> list[list[Outcome]]:
    """Every plan executed through the one pipeline (a failed plan's outcome says why), per planner and task."""
    jobs, where = [], []
    for i, refs in enumerate(plans):
        for b, ref in enumerate(refs):
            if isinstance(ref, Reference):
                jobs.append(Job(ref, weights[b], draws[b].perturbation))
                where.append((i, b))
    outcomes: list[list[Outcome]] = [[plan_failure(ref) if isinstance(ref, MjtrajError) else Outcome("error")
                                      for ref in refs] for refs in plans]
    for (i, b), result in zip(where, execute(scenario.model, scenario.loop, jobs, plant=plant, total_torque=True),
                              strict=True):
        outcomes[i][b] = result
    return outcomes


def _values(outcomes: list[Outcome], metric: str) -> np.ndarray:
    return np.array([o.metrics.get(metric, np.nan) if o.status == "ok" else np.nan for o in outcomes])


def _row(name: str, alpha: float | None, split: float | None, mine: list[Outcome],
         cubic: list[Outcome]) -> FrontierRow:
    single = len(mine) == 1
    metrics, ratio = {}, {}
    for metric in (*TABLE_METRICS, "rms_fb", "saturated_frac", "max_err", "terminal_err", "rms_dtau_norm",
                   "rms_tau_total"):
        values = _values(mine, metric)
        metrics[metric] = float(values[0]) if single else median_interval(values).value
    for metric in TABLE_METRICS:
        r = _values(mine, metric) / _values(cubic, metric)
        ratio[metric] = Median(float(r[0]), float(r[0]), float(r[0]), 1) if single else median_interval(r)
    failed = sum(o.status != "ok" for o in mine)
    reasons = tuple(dict.fromkeys(f"{o.status}: {o.reason}" for o in mine if o.status != "ok"))
    return FrontierRow(name, alpha, split, metrics, ratio, failed, reasons)
