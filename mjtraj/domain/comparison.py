"""A comparison's result: each planner's reference, their batched execution and its metrics (what
`mjtraj.study.compare` returns, and `mjtraj.media` renders)."""

from __future__ import annotations

from dataclasses import dataclass, field

from mjtraj.core.metrics import Metrics
from mjtraj.core.reference import Reference
from mjtraj.core.rollout import Rollout
from mjtraj.domain.pipeline import Outcome
from mjtraj.domain.scenario import Scenario


@dataclass(frozen=True)
class Comparison:
    """Planners' references, the batched rollout (row b = planners[b]) and each planner's Metrics."""

    scenario: Scenario
    planners: tuple[str, ...]
    references: dict[str, Reference]
    rollout: Rollout
    metrics: dict[str, Metrics]
    stability: dict[str, float]
    """Frozen-time spectral radii of the linearised closed loop: 'at_rest' and 'moving' (see mjtraj.core.stability)."""
    failed: dict[str, str] = field(default_factory=dict)
    """Planners that could not plan the task -> the one-line reason (they have no row)."""
    outcomes: dict[str, Outcome] = field(default_factory=dict)
    """Each executed planner's outcome, the goal rule applied (status ok, missed_goal, diverged, unstable)."""

    def reduction(self, planner: str, metric: str) -> float:
        """100 (M_planner - M_optimal) / M_planner in %; NaN without an optimal row."""
        if "optimal" not in self.metrics:
            return float("nan")
        value = getattr(self.metrics[planner], metric)
        if value == 0.0:
            return float("nan")  # no reduction of nothing (a zero move)
        return 100.0 * (value - getattr(self.metrics["optimal"], metric)) / value
