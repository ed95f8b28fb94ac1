"""Scenario files: every setting of a comparison (task, controller, planner options, cost weights) in one place."""

from __future__ import annotations

import dataclasses
import os
import sys
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj._validate import frozen, vector
from mjtraj.closed_loop import LoopConfig
from mjtraj.controller import PIDGains
from mjtraj.exceptions import InvalidInputError
from mjtraj.planners import Planner, available, make
from mjtraj.task import Task

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SECTIONS = {
    "name": None,
    "task": ("q0", "qg", "duration", "dt"),
    "controller": ("kp", "ki", "kd", "feedforward", "ff_accel", "gravity_comp", "anti_windup", "substeps"),
    "planners": None,
    "cost": ("Q_exec", "R_exec"),
}


@dataclass(frozen=True)
class Scenario:
    """A comparison's settings. `planner_options` maps planner name -> keyword options."""

    name: str
    task: Task
    loop: LoopConfig
    planner_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    Q_exec: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    """diag(Q_exec), shape (2n,)."""
    R_exec: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    """diag(R_exec), shape (n,)."""
    source: str = ""

    def planner(self, name: str) -> Planner:
        """The registered planner `name` with this scenario's options for it."""
        return make(name, **self.planner_options.get(name, {}))

    def replace(self, **changes: Any) -> Scenario:
        """A copy with fields changed; `task_changes` / `loop_changes` dicts edit the task or loop config."""
        task_changes = changes.pop("task_changes", {})
        loop_changes = changes.pop("loop_changes", {})
        task = self.task
        if task_changes:
            values = {"q0": task.q0, "qg": task.qg, "duration": task.duration, "dt": task.dt, **task_changes}
            task = Task.create(**values, n=task.n)
        loop = dataclasses.replace(self.loop, **loop_changes) if loop_changes else self.loop
        return dataclasses.replace(self, task=task, loop=loop, **changes)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready settings, laid out as the scenario file."""
        g = self.loop.gains
        return {
            "name": self.name,
            "task": {"q0": self.task.q0.tolist(), "qg": self.task.qg.tolist(), "duration": self.task.duration,
                     "dt": self.task.dt},
            "controller": {"kp": g.kp.tolist(), "ki": g.ki.tolist(), "kd": g.kd.tolist(),
                           "feedforward": self.loop.feedforward, "ff_accel": self.loop.ff_accel,
                           "gravity_comp": self.loop.gravity_comp, "anti_windup": self.loop.anti_windup,
                           "substeps": self.loop.substeps},
            "planners": {k: dict(v) for k, v in self.planner_options.items()},
            "cost": {"Q_exec": self.Q_exec.tolist(), "R_exec": self.R_exec.tolist()},
        }


def default_scenario_path() -> Path:
    """The shipped `paper.toml`."""
    return Path(str(resources.files("mjtraj.scenarios").joinpath("paper.toml")))


def load_scenario(path: str | os.PathLike[str] | None = None) -> Scenario:
    """Read a scenario file (TOML); None for the shipped paper scenario.

    Raises:
      InvalidInputError: missing file, TOML syntax, unknown or missing keys (valid ones are listed), bad values.
    """
    file = default_scenario_path() if path is None else Path(path)
    if not file.is_file():
        raise InvalidInputError(f"config: scenario file not found: {file}")
    try:
        data = tomllib.loads(file.read_text())
    except tomllib.TOMLDecodeError as e:
        raise InvalidInputError(f"config: {file} is not valid TOML: {e}") from e
    return scenario_from_dict(data, source=str(file))


def _section(data: dict[str, Any], name: str) -> dict[str, Any]:
    section = data.get(name)
    if not isinstance(section, dict):
        raise InvalidInputError(f"config: missing section [{name}]")
    valid = SECTIONS[name]
    assert valid is not None
    for key in section:
        if key not in valid:
            raise InvalidInputError(f"config: unknown key {key!r} in [{name}]; valid: {', '.join(valid)}")
    return section


def _require(section: dict[str, Any], name: str, key: str) -> Any:
    if key not in section:
        raise InvalidInputError(f"config: missing key {key!r} in [{name}]")
    return section[key]


def scenario_from_dict(data: dict[str, Any], *, source: str = "") -> Scenario:
    """Build a Scenario from the scenario file's layout (see `Scenario.as_dict`)."""
    for key in data:
        if key not in SECTIONS:
            raise InvalidInputError(f"config: unknown key {key!r}; valid: {', '.join(SECTIONS)}")
    t = _section(data, "task")
    task = Task.create(*(_require(t, "task", k) for k in ("q0", "qg", "duration", "dt")))
    c = _section(data, "controller")
    gains = PIDGains.create(*(_require(c, "controller", k) for k in ("kp", "ki", "kd")), n=task.n)
    loop = LoopConfig(gains, **{k: v for k, v in c.items() if k not in ("kp", "ki", "kd")})
    planners = data.get("planners", {})
    for name, options in planners.items():
        if name not in available():
            raise InvalidInputError(f"config: unknown planner [planners.{name}]; valid: {', '.join(available())}")
        for key, value in options.items():
            if isinstance(value, list):
                options[key] = tuple(value)
        make(name, **options)  # validates the options now
    cost = _section(data, "cost")
    Q = frozen(vector("Q_exec", _require(cost, "cost", "Q_exec"), 2 * task.n))
    R = frozen(vector("R_exec", _require(cost, "cost", "R_exec"), task.n))
    if np.any(Q < 0) or np.any(R < 0):
        raise InvalidInputError(f"config: Q_exec and R_exec must be >= 0, got {Q.tolist()} and {R.tolist()}")
    return Scenario(name=str(data.get("name", "scenario")), task=task, loop=loop, planner_options=planners,
                    Q_exec=Q, R_exec=R, source=source)
