"""mjtraj: how the choice of joint-space trajectory planner changes closed-loop execution on a MuJoCo arm.

The package is layered (docs/design.md, "Layers"): `mjtraj.core` (plant, planners, closed loop, metrics, scoring),
`mjtraj.study` (scenarios, comparisons, sweeps, statistics, audit), `mjtraj.media` (rendering, videos),
`mjtraj.envs` (Gymnasium environments), `mjtraj.rl` (RL tracking policies) and the `mjtraj` command on top.
Importing `mjtraj` imports none of them: the names below load on first use.

`gym.make("UR5Track-v0")` works after `import mjtraj` (which imports Gymnasium only when something else does), and
`gym.make("mjtraj:UR5Track-v0")` without any import.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from mjtraj import _checkout, _registration
from mjtraj._lazy import lazy_exports
from mjtraj.exceptions import (
    BackendError,
    InfeasibleError,
    InvalidInputError,
    MissingExtraError,
    MjtrajError,
    ModelError,
    RenderError,
    SolverError,
)
from mjtraj.versions import __version__

_checkout.install(Path(__file__).resolve().parent)

_EXPORTS = {
    "ENV_ID": "mjtraj.envs",
    "ClosedLoop": "mjtraj.core.closed_loop",
    "LoopConfig": "mjtraj.core.closed_loop",
    "PIDGains": "mjtraj.core.controller",
    "control_law": "mjtraj.core.controller",
    "Metrics": "mjtraj.core.metrics",
    "metrics": "mjtraj.core.metrics",
    "load_model": "mjtraj.core.model",
    "Planner": "mjtraj.core.planners",
    "available": "mjtraj.core.planners",
    "make": "mjtraj.core.planners",
    "Reference": "mjtraj.core.reference",
    "Rollout": "mjtraj.core.rollout",
    "Scoring": "mjtraj.core.scoring",
    "Task": "mjtraj.core.task",
    "Comparison": "mjtraj.domain.comparison",
    "compare": "mjtraj.study.comparison",
    "Scenario": "mjtraj.domain.scenario",
    "load_scenario": "mjtraj.domain.scenario",
    "SweepSettings": "mjtraj.study.sweep",
    "run_sweep": "mjtraj.study.runner",
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from mjtraj.core.closed_loop import ClosedLoop, LoopConfig
    from mjtraj.core.controller import PIDGains, control_law
    from mjtraj.core.metrics import Metrics, metrics
    from mjtraj.core.model import load_model
    from mjtraj.core.planners import Planner, available, make
    from mjtraj.core.reference import Reference
    from mjtraj.core.rollout import Rollout
    from mjtraj.core.scoring import Scoring
    from mjtraj.core.task import Task
    from mjtraj.domain.comparison import Comparison
    from mjtraj.domain.scenario import Scenario, load_scenario
    from mjtraj.envs import ENV_ID
    from mjtraj.study.comparison import compare
    from mjtraj.study.runner import run_sweep
    from mjtraj.study.sweep import SweepSettings

_registration.register()  # gym.make("UR5Track-v0") after `import mjtraj`, whichever is imported first

__all__ = [
    "ENV_ID", "BackendError", "ClosedLoop", "Comparison", "InfeasibleError", "InvalidInputError", "LoopConfig",
    "Metrics", "MissingExtraError", "MjtrajError", "ModelError", "PIDGains", "Planner", "Reference", "RenderError",
    "Rollout", "Scenario", "Scoring", "SolverError", "SweepSettings", "Task", "__version__", "available", "compare",
    "control_law", "load_model", "load_scenario", "make", "metrics", "run_sweep",
]
