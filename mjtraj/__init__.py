"""mjtraj: how the choice of joint-space trajectory planner changes closed-loop execution on a MuJoCo UR5."""

from mjtraj.gl import select_backend as _select_backend

_select_backend()  # before mujoco is imported: MuJoCo reads MUJOCO_GL once

from mjtraj.closed_loop import ClosedLoop, LoopConfig
from mjtraj.compare import Comparison, compare
from mjtraj.controller import PIDGains, control_law
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
from mjtraj.metrics import Metrics, metrics
from mjtraj.model import load_model
from mjtraj.planners import Planner, available, make
from mjtraj.reference import Reference
from mjtraj.rollout import Rollout
from mjtraj.scenario import Scenario, load_scenario
from mjtraj.sweep import SweepSettings
from mjtraj.sweep_runner import run_sweep
from mjtraj.task import Task
from mjtraj.envs import ENV_ID, register_envs

register_envs()  # gym.make("UR5Track-v0") after `import mjtraj`

__version__ = "0.1.0"

__all__ = [
    "ENV_ID", "BackendError", "ClosedLoop", "Comparison", "InfeasibleError", "InvalidInputError", "LoopConfig",
    "Metrics", "MissingExtraError", "MjtrajError", "ModelError", "PIDGains", "Planner", "Reference", "RenderError",
    "Rollout", "Scenario", "SolverError", "SweepSettings", "Task", "__version__", "available", "compare",
    "control_law", "load_model", "load_scenario", "make", "metrics", "run_sweep",
]
