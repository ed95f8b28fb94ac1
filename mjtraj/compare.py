"""The paper's study: plan with every planner, execute through one batched closed loop, score."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mjtraj.closed_loop import ClosedLoop
from mjtraj.exceptions import InvalidInputError
from mjtraj.gains import GAIN_RULE, spectral_radius_along
from mjtraj.metrics import Metrics, metrics
from mjtraj.model import load_model
from mjtraj.planners import available
from mjtraj.reference import Reference
from mjtraj.rollout import Rollout
from mjtraj.scenario import Scenario

PAPER_ORDER = ("optimal", "cubic", "quintic", "trapezoidal")


@dataclass(frozen=True)
class Comparison:
    """Planners' references, the batched rollout (row b = planners[b]) and each planner's Metrics."""

    scenario: Scenario
    planners: tuple[str, ...]
    references: dict[str, Reference]
    rollout: Rollout
    metrics: dict[str, Metrics]
    stability: dict[str, float]
    """Frozen-time spectral radii of the linearised closed loop: 'at_rest' and 'moving' (see gains)."""

    def reduction(self, planner: str, metric: str) -> float:
        """100 (M_planner - M_optimal) / M_planner in %; NaN without an optimal row."""
        if "optimal" not in self.metrics:
            return float("nan")
        value = getattr(self.metrics[planner], metric)
        return 100.0 * (value - getattr(self.metrics["optimal"], metric)) / value


def versions() -> dict[str, str]:
    """Versions of mjtraj and the libraries that shape its numbers."""
    import gymnasium
    import mujoco
    import osqp
    import scipy

    from mjtraj import __version__

    return {"mjtraj": __version__, "mujoco": mujoco.__version__, "numpy": np.__version__, "scipy": scipy.__version__,
            "osqp": osqp.__version__, "gymnasium": gymnasium.__version__}


def compare(scenario: Scenario, planners: Sequence[str] | None = None, *,
            progress: Callable[[str], None] | None = None) -> Comparison:
    """Plan `scenario.task` with each planner (default: all registered, paper order first) and execute all
    references together through one ClosedLoop with the scenario's controller.

    Args:
      progress: called with a short label before each stage (for a progress bar).
    """
    names = tuple(planners) if planners is not None else tuple(
        [p for p in PAPER_ORDER if p in available()] + [p for p in available() if p not in PAPER_ORDER])
    if not names:
        raise InvalidInputError("planners: expected at least one planner, got none")
    for name in names:
        if name not in available():
            raise InvalidInputError(f"planners: unknown planner {name!r}; valid: {', '.join(available())}")
    model = load_model(dt=scenario.task.dt)
    scenario.task.check_limits(model)
    references = {}
    for name in names:
        if progress:
            progress(f"plan {name}")
        references[name] = scenario.planner(name).plan(scenario.task, model)
    if progress:
        progress("execute")
    loop = ClosedLoop(model, scenario.loop, nsim=len(names))
    rollout = loop.run([references[n] for n in names])
    if progress:
        progress("stability check")
    refs = list(references.values())
    stability = {"at_rest": spectral_radius_along(model, scenario.loop.gains, refs, moving=False),
                 "moving": spectral_radius_along(model, scenario.loop.gains, refs, moving=True)}
    scored = metrics(rollout, scenario.Q_exec, scenario.R_exec)
    return Comparison(scenario=scenario, planners=names, references=references, rollout=rollout,
                      metrics=dict(zip(names, scored)), stability=stability)


def comparison_record(result: Comparison) -> dict[str, Any]:
    """Everything about a comparison as JSON-ready data (results.json)."""
    from mjtraj.report import PAPER_TABLE

    planners = {}
    for name in result.planners:
        ref = result.references[name]
        planners[name] = {
            "metrics": result.metrics[name].as_dict(),
            "reduction_pct": {"int_dtau": result.reduction(name, "int_dtau"), "cost": result.reduction(name, "cost"),
                              "rms_dtau": result.reduction(name, "rms_dtau"),
                              "rms_err": result.reduction(name, "rms_err")} if name != "optimal" else None,
            "diverged_step": int(result.rollout.diverged_step[result.planners.index(name)]),
            "plan": {k: v for k, v in ref.info.items()},
        }
    return {"scenario": result.scenario.as_dict(), "scenario_file": result.scenario.source,
            "gain_rule": GAIN_RULE, "stability": result.stability, "versions": versions(), "planners": planners,
            "paper_table_i": PAPER_TABLE}
