"""The one row schema of results files (sweeps, `mjtraj rl eval`): a row per scenario, controller variant and
planner (or policy), its outcome and metrics, the task and plant it ran on, and the settings and provenance."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mjtraj.core.metrics import METRIC_NAMES
from mjtraj.core.settle import SETTLE_METRICS
from mjtraj.core.task import Task
from mjtraj.domain.families import PERTURBATION_FIELDS, Perturbation
from mjtraj.domain.pipeline import Outcome

EXTRA_METRICS = ("model_error", "plan_effort")
"""model_error: RMS of q_pred - q over the open-loop nonlinear rollout of u_plan on the nominal plant (rad;
optimal-type planners, when measured); plan_effort: RMS of u_plan (N m; planners that publish one)."""


@dataclass(frozen=True, kw_only=True)
class Row:
    """One result row. `columns()` flattens it into the file's columns, in the file's order.

    Attributes:
      family, scenario, unit: which scenario (and the unit of work that computed it).
      planner: the planner, variant or policy label.
      ff_accel, gravity_comp: the controller variant.
      outcome: status, reason and metrics (`mjtraj.domain.pipeline.Outcome`).
      extras: EXTRA_METRICS values measured for this row.
      solver: the solver that planned the reference ('' for kinematic planners or failures).
      task: the motion; perturbation: how the plant differed from the nominal model (None: it did not).
      settings: the columns every row of the file shares (settings and provenance).
      more: columns appended after the settings (`mjtraj rl eval`'s policy columns).
      settle: a row of protocol v2 (an episode with a settle window): SETTLE_METRICS follow the metrics, which
        cover the whole episode.
    """

    family: str
    scenario: int
    unit: int
    planner: str
    ff_accel: str
    gravity_comp: str
    outcome: Outcome
    extras: Mapping[str, float] = field(default_factory=dict)
    solver: str = ""
    task: Task
    perturbation: Perturbation | None = None
    settings: Mapping[str, Any]
    more: Mapping[str, Any] = field(default_factory=dict)
    settle: bool = False

    def columns(self) -> dict[str, Any]:
        """Column name -> value (str, int or float; NaN where not measured)."""
        task = self.task
        row: dict[str, Any] = {"family": self.family, "scenario": self.scenario, "unit": self.unit,
                               "planner": self.planner, "ff_accel": self.ff_accel,
                               "gravity_comp": self.gravity_comp, "status": self.outcome.status,
                               "reason": self.outcome.reason}
        row.update({m: self.outcome.metrics.get(m, float("nan")) for m in METRIC_NAMES})
        if self.settle:
            row.update({m: self.outcome.metrics.get(m, float("nan")) for m in SETTLE_METRICS})
        row.update({m: float(self.extras.get(m, float("nan"))) for m in EXTRA_METRICS})
        row["solver"] = self.solver
        row.update({"duration": task.duration, "max_displacement": float(np.max(np.abs(task.displacement)))})
        row.update({f"q0_{j}": float(v) for j, v in enumerate(task.q0)})
        row.update({f"qg_{j}": float(v) for j, v in enumerate(task.qg)})
        if self.perturbation is not None:
            row.update(self.perturbation.as_dict())
        else:
            row["payload_kg"] = float("nan")
            row.update({f"{name}_{j}": float("nan") for name in PERTURBATION_FIELDS for j in range(task.n)})
        row.update(self.settings)
        row.update(self.more)
        return row
