"""Scenarios: every setting of a comparison (model, task, controller, planner options, scoring) in one place.

A scenario file (TOML) has the layout of `Scenario.as_dict`:

    name = "paper"
    model = "path/to/arm.xml"          # optional; the shipped UR5 3-DoF model when absent
    torque_limit = 40.0                # optional, with model: every joint's corrective saturation, N m
    [task]        q0, qg (lists, rad), duration, dt (s)
    [controller]  kp, ki, kd (lists) and the loop options declared in mjtraj.core.closed_loop.LoopConfig
    [planners.<name>]  keyword options of each registered planner
    [cost]        Q_exec, R_exec (lists: fixed diagonal weights), or rule = "bryson" (Bryson's rule per task)
    [tuning]      optional: the record of `mjtraj tune` that chose the planner options (kept, not interpreted)

Types are enforced: a number where a list is expected (or `true` where a number is) is an error naming the key.
"""

from __future__ import annotations

import dataclasses
import os
import re
import sys
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.core.arm import TorqueLimit, normalized_limit
from mjtraj.core.closed_loop import LoopConfig
from mjtraj.core.controller import PIDGains
from mjtraj.core.model import JointInfo, load_model
from mjtraj.core.options import from_mapping, option_names
from mjtraj.core.planners import Planner, available, make
from mjtraj.core.scoring import Scoring
from mjtraj.core.task import Task
from mjtraj.exceptions import InvalidInputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TASK_KEYS = ("q0", "qg", "duration", "dt")
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
"""A scenario name: it names output files, so it is never a path."""
GAIN_KEYS = ("kp", "ki", "kd")
SECTIONS = ("name", "model", "torque_limit", "task", "controller", "planners", "cost", "tuning")


@dataclass(frozen=True)
class Scenario:
    """A comparison's settings.

    Attributes:
      name: a label for outputs (a name, not a path).
      task: the motion.
      loop: the controller, identical for every planner.
      planner_options: planner name -> keyword options.
      scoring: how executions are scored (J_exec's weights), independent of any planner's own weights.
      model_path: the MJCF plant model; None for the shipped UR5 3-DoF model.
      model_torque_limit: with model_path, the corrective saturation, N m: one value for every joint or one per
        joint (None: from the model).
      source: the file it was read from ('' in memory).
      tuning: the record of the tuning that chose the planner options (`mjtraj tune`), or None.
    """

    name: str
    task: Task
    loop: LoopConfig
    planner_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    scoring: Scoring = field(default_factory=Scoring)
    model_path: str | None = None
    model_torque_limit: float | tuple[float, ...] | None = None
    source: str = ""
    tuning: dict[str, Any] | None = None
    memo: dict[Any, Any] = field(default_factory=dict, init=False, repr=False, compare=False)
    """Results computed once per scenario (the model's stability check); a replaced scenario starts empty."""

    @cached_property
    def model(self) -> mujoco.MjModel:
        """The nominal plant model at the task's control period, loaded once per scenario."""
        return load_model(self.model_path, dt=self.task.dt, torque_limit=self.model_torque_limit)

    @property
    def torque_limit(self) -> NDArray[np.float64]:
        """The corrective-torque saturation of the model, shape (n,), N m."""
        return JointInfo.of(self.model).torque_limit

    @property
    def Q_exec(self) -> NDArray[np.float64]:
        """diag(Q_exec) that scores this scenario's task, shape (2n,)."""
        return self.scoring.weights(self.task, self.torque_limit)[0]

    @property
    def R_exec(self) -> NDArray[np.float64]:
        """diag(R_exec) that scores this scenario's task, shape (n,)."""
        return self.scoring.weights(self.task, self.torque_limit)[1]

    def planner(self, name: str) -> Planner:
        """The registered planner `name` with this scenario's options for it."""
        return make(name, **self.planner_options.get(name, {}))

    def replace(self, *, task: dict[str, Any] | None = None, loop: dict[str, Any] | None = None,
                **changes: Any) -> Scenario:
        """A copy with fields changed; `task` and `loop` dicts edit fields of the task or the loop configuration."""
        new_task = self.task
        if task:
            values = {"q0": self.task.q0, "qg": self.task.qg, "duration": self.task.duration, "dt": self.task.dt,
                      **task}
            new_task = Task.create(**values, n=self.task.n)
        new_loop = dataclasses.replace(self.loop, **loop) if loop else self.loop
        return dataclasses.replace(self, task=new_task, loop=new_loop, **changes)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready settings, laid out as the scenario file."""
        g = self.loop.gains
        out: dict[str, Any] = {"name": self.name}
        if self.model_path is not None:
            out["model"] = self.model_path
        if self.model_torque_limit is not None:
            limit = self.model_torque_limit
            out["torque_limit"] = list(limit) if isinstance(limit, tuple) else limit
        out["task"] = {"q0": self.task.q0.tolist(), "qg": self.task.qg.tolist(), "duration": self.task.duration,
                       "dt": self.task.dt}
        out["controller"] = {"kp": g.kp.tolist(), "ki": g.ki.tolist(), "kd": g.kd.tolist(),
                             **{name: getattr(self.loop, name) for name in option_names(LoopConfig)}}
        out["planners"] = {k: dict(v) for k, v in self.planner_options.items()}
        out["cost"] = self.scoring.as_dict()
        if self.tuning is not None:
            out["tuning"] = self.tuning
        return out


def scenario_text(scenario: Scenario, header: str = "") -> str:
    """A scenario as the TOML text of a scenario file (`header` as comments); `load_scenario` reads it back."""
    from mjtraj.domain.toml_text import dumps

    return dumps(scenario.as_dict(), header=header)


def default_scenario_path() -> Path:
    """The shipped `paper.toml`."""
    return Path(str(resources.files("mjtraj.domain.scenarios").joinpath("paper.toml")))


def shipped_scenarios() -> tuple[str, ...]:
    """Names of the scenario files shipped with mjtraj (`load_scenario` takes them by name)."""
    return tuple(sorted(p.stem for p in default_scenario_path().parent.glob("*.toml")))


def load_scenario(path: str | os.PathLike[str] | None = None) -> Scenario:
    """Read a scenario file (TOML), or a shipped scenario by name (`shipped_scenarios`); None for the paper one.

    Raises:
      InvalidInputError: missing or unreadable file, TOML syntax, unknown or missing keys (valid ones are listed),
        values of the wrong type, bad values.
    """
    file = default_scenario_path() if path is None else Path(path)
    if not file.is_file() and path is not None and str(path) in shipped_scenarios():
        file = default_scenario_path().with_name(f"{path}.toml")
    if not file.is_file():
        raise InvalidInputError(f"config: scenario file not found: {file} (shipped scenarios, by name: "
                                f"{', '.join(shipped_scenarios())})")
    try:
        text = file.read_bytes().decode("utf-8")
        data = tomllib.loads(text)
    except UnicodeDecodeError as e:
        raise InvalidInputError(f"config: {file} is not a text file (not UTF-8 at byte {e.start})") from e
    except tomllib.TOMLDecodeError as e:
        raise InvalidInputError(f"config: {file} is not valid TOML: {e}") from e
    except OSError as e:
        raise InvalidInputError(f"config: cannot read {file}: {e.strerror or e}") from e
    return scenario_from_dict(data, source=str(file))


def _section(data: dict[str, Any], name: str, *, required: bool = True) -> dict[str, Any]:
    section = data.get(name, None if required else {})
    if section is None:
        raise InvalidInputError(f"config: missing section [{name}]")
    if not isinstance(section, dict):
        raise InvalidInputError(f"config: [{name}] must be a table, got {section!r}")
    return section


def _require(section: dict[str, Any], name: str, key: str) -> Any:
    if key not in section:
        raise InvalidInputError(f"config: missing key {key!r} in [{name}]")
    return section[key]


def _numbers(section: dict[str, Any], name: str, key: str) -> list[float]:
    """A list of numbers (not a scalar, not booleans)."""
    value = _require(section, name, key)
    if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                              for v in value):
        raise InvalidInputError(f"config: {key} in [{name}]: expected a list of numbers, got {value!r}")
    return value


def _number(section: dict[str, Any], name: str, key: str) -> float:
    value = _require(section, name, key)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidInputError(f"config: {key} in [{name}]: expected a number, got {value!r}")
    return float(value)


def _only(section: dict[str, Any], name: str, valid: tuple[str, ...]) -> None:
    for key in section:
        if key not in valid:
            raise InvalidInputError(f"config: unknown key {key!r} in [{name}]; valid: {', '.join(valid)}")


def scenario_from_dict(data: dict[str, Any], *, source: str = "") -> Scenario:
    """Build a Scenario from the scenario file's layout (see `Scenario.as_dict` and the module docstring)."""
    for key in data:
        if key not in SECTIONS:
            raise InvalidInputError(f"config: unknown key {key!r}; valid: {', '.join(SECTIONS)}")
    name = data.get("name", "scenario")
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise InvalidInputError(f"config: name: expected a name of letters, digits, '_', '-' and '.' (not a path), "
                                f"got {name!r}")
    model_path, torque_limit = _model_and_limit(data)
    task = _task(data)
    loop = _loop(data, task.n)
    planners = _planner_options(data)
    scoring = _scoring(data, task.n)
    tuning = data.get("tuning")
    if tuning is not None and not isinstance(tuning, dict):
        raise InvalidInputError(f"config: [tuning] must be a table, got {tuning!r}")
    return Scenario(name=name, task=task, loop=loop, planner_options=planners, scoring=scoring,
                    model_path=model_path, model_torque_limit=torque_limit, source=source, tuning=tuning)


def _model_and_limit(data: dict[str, Any]) -> tuple[str | None, TorqueLimit]:
    """The file's `model` (a path, or None for the shipped UR5) and its `torque_limit` (N m, only with a model)."""
    model_path = data.get("model")
    if model_path is not None and not isinstance(model_path, str):
        raise InvalidInputError(f"config: model: expected a file path (a string), got {model_path!r}")
    torque_limit = data.get("torque_limit")
    if torque_limit is not None:
        if model_path is None:
            raise InvalidInputError("config: torque_limit: only with model = \"PATH\" (the shipped UR5's "
                                    "saturation is its motors' 60 N m)")
        values = torque_limit if isinstance(torque_limit, list) else [torque_limit]
        if not values or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not (np.isfinite(v) and v > 0)
                             for v in values):
            raise InvalidInputError(f"config: torque_limit: expected a positive number (N m) or a list of them (one "
                                    f"per joint), got {torque_limit!r}")
        torque_limit = normalized_limit(values)
    return model_path, torque_limit


def _task(data: dict[str, Any]) -> Task:
    """The file's [task]: q0, qg (rad), duration and dt (s)."""
    t = _section(data, "task")
    _only(t, "task", TASK_KEYS)
    return Task.create(_numbers(t, "task", "q0"), _numbers(t, "task", "qg"), _number(t, "task", "duration"),
                       _number(t, "task", "dt"))


def _loop(data: dict[str, Any], n: int) -> LoopConfig:
    """The file's [controller]: the PID gains (n joints each) and the loop's options."""
    c = _section(data, "controller")
    _only(c, "controller", GAIN_KEYS + option_names(LoopConfig))
    kp, ki, kd = (_numbers(c, "controller", k) for k in GAIN_KEYS)
    gains = PIDGains.create(kp, ki, kd, n=n)
    return LoopConfig(gains, **from_mapping(LoopConfig, {k: v for k, v in c.items() if k not in GAIN_KEYS},
                                            where=" in [controller]"))


def _planner_options(data: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The file's [planners.NAME] tables: each planner's options (lists as tuples), checked by making it."""
    planners: dict[str, dict[str, Any]] = {}
    for planner, options in _section(data, "planners", required=False).items():
        if planner not in available():
            raise InvalidInputError(f"config: unknown planner [planners.{planner}]; valid: {', '.join(available())}")
        if not isinstance(options, dict):
            raise InvalidInputError(f"config: [planners.{planner}] must be a table of options, got {options!r}")
        planners[planner] = {k: tuple(v) if isinstance(v, list) else v for k, v in options.items()}
        try:
            make(planner, **planners[planner])  # validates the options now
        except TypeError as e:
            raise InvalidInputError(f"config: [planners.{planner}]: {e}") from e
    return planners


def _scoring(data: dict[str, Any], n: int) -> Scoring:
    """The file's [cost]: Bryson's rule (rule = "bryson"), or the fixed Q_exec (2n,) and R_exec (n,)."""
    cost = _section(data, "cost")
    if "rule" in cost:
        _only(cost, "cost", ("rule",))
        if cost["rule"] != "bryson":
            raise InvalidInputError(f"config: rule in [cost]: unknown value {cost['rule']!r}; valid: bryson (or give "
                                    f"Q_exec and R_exec)")
        return Scoring()
    _only(cost, "cost", ("Q_exec", "R_exec", "rule"))
    return Scoring.fixed(_numbers(cost, "cost", "Q_exec"), _numbers(cost, "cost", "R_exec"), n)


MOVE = 0.5
"""rad: in the default task of a user's arm, every joint moves this far from the home pose (see ARM_TASK_RULE)."""
ARM_TASK_RULE = (
    "start at the model's keyframe 'home' (else its qpos0), clipped into the joint ranges; every joint moves 0.5 rad, "
    "upward unless that leaves less than 0.05 rad to its range's end, then downward; a joint whose range has not "
    "0.5 rad of room on either side moves to 0.05 rad short of the end with more room; T = 2 s at dt = 0.02 s. "
    "Gains by the PID gain rule along that move, the optimal planner's weights and the score by Bryson's rule on the "
    "task, the other planners at their defaults. Integrator steps per period: the fewest that keep every joint's "
    "passive damping rate (damping over the least inertia the joint presents along the move) times the step at or "
    "below 1 (RK4 is unstable beyond about 2.8: MuJoCo Menagerie's UR5e damps its wrists at 15 N m s/rad on 0.1 kg "
    "m^2 of armature)")


def scenario_for_model(path: str | os.PathLike[str], *, q0: Any = None, qg: Any = None, duration: float = 2.0,
                       dt: float = 0.02, torque_limit: float | tuple[float, ...] | list[float] | None = None,
                       workspace: bool = False) -> Scenario:
    """The study's scenario for the MJCF arm at `path` (prepared by `mjtraj.core.arm.ARM_RULES`): the move `q0` ->
    `qg` (rad, shape (n,)), or ARM_TASK_RULE's for what is not given; `torque_limit` (N m) is every joint's
    corrective saturation (None: from the model). With `workspace` (drawn tasks: sweeps, tune, the env's random
    tasks) the gains and the integrator steps follow `mjtraj.core.gains.WORKSPACE_RULE`. Under RK4 the loop takes
    ceil(damping x dt / inertia) integrator steps per period on its lightest, most damped joint; an arm prepared
    with implicitfast (damping too stiff for RK4 at one step, ARM_RULES) takes one.

    Raises:
      ModelError: the model cannot be prepared (names the element). InvalidInputError: a bad task.
    """
    from mjtraj.core.arm import home_pose, prepare_arm
    from mjtraj.core.gains import free_inertia, free_inertia_at, gain_rule, workspace_poses

    torque_limit = normalized_limit(torque_limit)
    model = prepare_arm(path, dt=dt, torque_limit=torque_limit)
    start = home_pose(model) if q0 is None else np.asarray(q0, dtype=np.float64)
    if qg is None:
        limited = model.jnt_limited.astype(bool)
        room_up = np.where(limited, model.jnt_range[:, 1] - start - 0.05, np.inf)
        room_down = np.where(limited, start - model.jnt_range[:, 0] - 0.05, np.inf)
        step = np.where(room_up >= MOVE, MOVE, np.where(room_down >= MOVE, -MOVE,
                        np.where(room_up >= room_down, np.maximum(room_up, 0.0), -np.maximum(room_down, 0.0))))
        qg = start + step
    task = Task.create(start, qg, duration, dt, model=model)
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(path).stem) or "arm"
    lightest, _ = (free_inertia_at(model, workspace_poses(model, task.q0, task.qg)) if workspace
                   else free_inertia(model, task.q0, task.qg))
    rate = float(np.max(model.dof_damping / lightest)) * dt
    rk4 = model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4  # else implicit in the damping: one step is stable
    loop = LoopConfig(gain_rule(model, task.q0, task.qg, dt, workspace=workspace),
                      substeps=max(1, int(np.ceil(rate - 1e-12))) if rk4 else 1)
    where = Path(path)  # a file by its absolute path (a scenario file written from it works from any folder); a
    return Scenario(name=name, task=task, loop=loop, scoring=Scoring(),  # shipped arm by its name
                    model_path=str(where.resolve()) if where.is_file() else str(path),
                    model_torque_limit=torque_limit)
