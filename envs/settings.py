"""UR5Track-v0's keyword arguments, validated once and resolved against the paper scenario."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj._validate import choice, frozen, positive, vector
from mjtraj.closed_loop import LoopConfig
from mjtraj.exceptions import InvalidInputError
from mjtraj.model import JointInfo, load_model
from mjtraj.planners import Planner, available
from mjtraj.planners.optimal import bryson_weights
from mjtraj.render import check_render_options
from mjtraj.scenario import Scenario, load_scenario
from mjtraj.task import Task, random_task

ACTION_MODES = ("pid", "residual", "torque")
TASKS = ("paper", "random", "explicit")
RENDER_MODES = ("rgb_array",)

@dataclass(frozen=True)
class TrackSettings:
    """Everything an env instance needs, validated. Weights are diagonals: Q_exec (2n,), R_exec (n,); None for
    Bryson's rule on each episode's task (`weights`)."""

    model: mujoco.MjModel
    planner: Planner
    planner_name: str
    action_mode: str
    task_mode: str
    fixed_task: Task | None
    """The task of every episode ('paper', 'explicit'); None for 'random'."""
    max_displacement: float
    duration: float
    dt: float
    loop: LoopConfig
    preview: int
    Q_exec: NDArray[np.float64] | None
    R_exec: NDArray[np.float64] | None
    render_mode: str | None
    width: int
    height: int
    camera: str

    @property
    def n(self) -> int:
        """Number of joints."""
        return int(self.model.nv)

    @property
    def steps(self) -> int:
        """N, control periods per episode."""
        return round(self.duration / self.dt)

    @property
    def obs_size(self) -> int:
        """6n + 1 + 2n preview."""
        return 6 * self.n + 1 + 2 * self.n * self.preview

    def weights(self, task: Task) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """diag(Q_exec) (2n,) and diag(R_exec) (n,) that score an episode of `task`: the given ones, else Bryson's
        rule for the task (`mjtraj.planners.optimal.bryson_weights`), the rule sweeps score every scenario by. For
        the paper task Bryson's rule gives the paper scenario's weights."""
        q_rule, r_rule = bryson_weights(task, self.torque_limit)
        return (q_rule if self.Q_exec is None else self.Q_exec), (r_rule if self.R_exec is None else self.R_exec)

    @property
    def torque_limit(self) -> NDArray[np.float64]:
        """The corrective-torque saturation, shape (n,), N m."""
        return JointInfo.of(self.model).torque_limit

    def sample_task(self, rng: np.random.Generator) -> Task:
        """The next episode's task: the fixed one, or for 'random' a start uniform in the joint ranges and a goal
        uniform in the ranges within +-max_displacement of it (two draws of n uniforms from `rng`)."""
        if self.fixed_task is not None:
            return self.fixed_task
        return random_task(rng, self.model, max_displacement=self.max_displacement, duration=self.duration,
                           dt=self.dt)


def _count(name: str, value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InvalidInputError(f"{name}: expected a whole number >= 0, got {value!r}")
    return int(value)


def _weights(name: str, value: npt.ArrayLike | None, size: int) -> NDArray[np.float64] | None:
    if value is None:
        return None
    weights = vector(name, value, size)
    if np.any(weights < 0):
        raise InvalidInputError(f"{name}: expected {size} non-negative weights (a diagonal), got {weights.tolist()}")
    return frozen(weights)


def resolve(*, planner: str | Planner = "cubic", action_mode: str = "pid", task: str = "paper",
            q0: npt.ArrayLike | None = None, qg: npt.ArrayLike | None = None, max_displacement: float = 1.5,
            duration: float = 2.0, dt: float = 0.02, feedforward: str = "inverse", ff_accel: str = "sample",
            gravity_comp: str = "native", anti_windup: str = "none", preview: int = 0,
            Q_exec: npt.ArrayLike | None = None, R_exec: npt.ArrayLike | None = None,
            render_mode: str | None = None, width: int = 640, height: int = 480, camera: str = "front",
            scenario: Scenario | None = None) -> TrackSettings:
    """Validate the env's arguments (see UR5TrackEnv) and fill in the paper scenario's controller."""
    paper = scenario if scenario is not None else load_scenario()
    if isinstance(planner, str):
        if planner not in available():
            raise InvalidInputError(f"planner: unknown planner {planner!r}; valid: {', '.join(available())}")
        planner_name, planner_obj = planner, paper.planner(planner)
    elif callable(getattr(planner, "plan", None)):
        planner_name, planner_obj = type(planner).__name__, planner
    else:
        raise InvalidInputError(f"planner: expected a registered name ({', '.join(available())}) or an object "
                                f"with plan(task, model), got {planner!r}")
    choice("action_mode", action_mode, ACTION_MODES)
    choice("task", task, TASKS)
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise InvalidInputError(f"render_mode: unsupported mode {render_mode!r}; valid: None, "
                                f"{', '.join(RENDER_MODES)}")
    model = load_model(dt=positive("dt", dt))
    n = model.nv
    if task == "explicit":
        if q0 is None or qg is None:
            raise InvalidInputError("task: 'explicit' needs both q0 and qg (rad)")
    elif q0 is not None or qg is not None:
        raise InvalidInputError(f"q0, qg: only used with task='explicit', got task={task!r}")
    if task == "paper":
        fixed: Task | None = Task.create(paper.task.q0, paper.task.qg, duration, dt, model=model)
    elif task == "explicit":
        fixed = Task.create(q0, qg, duration, dt, model=model)  # type: ignore[arg-type]
    else:
        Task.create(np.zeros(n), np.zeros(n), duration, dt)  # validates the time grid now
        fixed = None
    loop = dataclasses.replace(paper.loop, feedforward=feedforward, ff_accel=ff_accel, gravity_comp=gravity_comp,
                               anti_windup=anti_windup)
    return TrackSettings(
        model=model, planner=planner_obj, planner_name=planner_name, action_mode=action_mode, task_mode=task,
        fixed_task=fixed, max_displacement=positive("max_displacement", max_displacement),
        duration=float(duration), dt=float(dt), loop=loop,
        preview=_count("preview", preview),
        Q_exec=_weights("Q_exec", Q_exec, 2 * n), R_exec=_weights("R_exec", R_exec, n),
        render_mode=render_mode, **dict(zip(("width", "height", "camera"),
                                            check_render_options(model, width, height, camera), strict=True)))
