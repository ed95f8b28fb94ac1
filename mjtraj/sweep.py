"""Sweeps: every planner on thousands of seeded scenarios through the one batched closed loop.

The work is cut into units (a family's scenarios [u * batch, (u + 1) * batch)). `run_unit` computes one unit's
rows from the settings alone, so any backend (this process, a process pool, a Ray cluster) gives the same rows,
bit for bit. Rows are one per scenario, controller variant (ff_accel x gravity_comp) and planner.

Rules shared by every scenario (stated once here, recorded with every row):
- the controller is the base scenario's (default: the shipped paper.toml): its gains, feedforward mode,
  anti-windup and substeps, for every task and planner;
- the optimal planner's Q, R and the execution cost's Q_exec, R_exec follow Bryson's rule per task
  (`mjtraj.planners.optimal.bryson_weights`), the rule paper.toml states for its own task;
- the planners' other options are the base scenario's.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import mujoco
import numpy as np

from mjtraj._validate import choice, positive_int
from mjtraj.closed_loop import ClosedLoop, LoopConfig
from mjtraj.controller import PIDGains
from mjtraj.exceptions import InfeasibleError, InvalidInputError, MjtrajError
from mjtraj.families import (
    FAMILIES,
    FamilyScenario,
    measurement_noise,
    perturbed_plant,
    plant_fields,
    scenario,
)
from mjtraj.feedforward import FEEDFORWARD_ACCEL
from mjtraj.metrics import METRIC_NAMES, metrics_arrays
from mjtraj.model import JointInfo, load_model
from mjtraj.planners import Planner, available, make
from mjtraj.planners.optimal import bryson_weights
from mjtraj.plant import GRAVITY_COMP
from mjtraj.reference import Reference
from mjtraj.scenario import Scenario, load_scenario
from mjtraj.sweep_file import VERSION_COLUMNS

DEFAULT_PLANNERS = ("optimal", "cubic", "quintic", "trapezoidal")
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "optimal_start": ("optimal", {"linearization": "start"}),
    "min_effort": ("optimal", {"state_weight": (0.0,) * 6}),
}
"""Planner variants a sweep can name besides the registered planners: the optimal planner linearised at the
start pose (claim 6 of the audit), and with Q = 0, the minimum-effort reference of the linear model."""
STATUSES = ("ok", "infeasible", "solver_error", "diverged", "unstable", "error")
EXTRA_METRICS = ("model_error", "plan_effort")
"""model_error: RMS of q_pred - q over the open-loop nonlinear rollout of u_plan on the nominal plant (rad;
optimal-type planners, with `model_error`); plan_effort: RMS of u_plan (N m; optimal-type planners)."""


def planner_names() -> tuple[str, ...]:
    """Every name a sweep accepts in `planners`."""
    return tuple(available()) + tuple(VARIANTS)


@dataclass(frozen=True)
class SweepSettings:
    """Everything that determines a sweep's rows (all of it is written into every row).

    Attributes:
      families: scenario families (see mjtraj.families).
      scenarios: scenarios per family.
      seed: the sweep's seed.
      planners: registered planners and VARIANTS.
      ff_accel, gravity_comp: the controller variants; every combination runs on every scenario.
      batch: scenarios per unit of work (rows depend on it only through floating-point summation order).
      sensor_noise: std of the position measurement noise in mismatch scenarios, rad (0: none).
      delay: actuation delay of mismatch scenarios, control periods (0 or 1).
      model_error: also measure the linear model's prediction error of optimal-type planners.
      config: the base scenario file (None: the shipped paper.toml).
    """

    families: tuple[str, ...] = ("nominal",)
    scenarios: int = 1000
    seed: int = 0
    planners: tuple[str, ...] = DEFAULT_PLANNERS
    ff_accel: tuple[str, ...] = ("sample",)
    gravity_comp: tuple[str, ...] = ("native",)
    batch: int = 250
    sensor_noise: float = 0.0
    delay: int = 0
    model_error: bool = False
    config: str | None = None
    base: Scenario = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name, values, valid in (("family", self.families, FAMILIES), ("planner", self.planners, planner_names()),
                                    ("ff_accel", self.ff_accel, FEEDFORWARD_ACCEL),
                                    ("gravity_comp", self.gravity_comp, GRAVITY_COMP)):
            if not values:
                raise InvalidInputError(f"{name}: expected at least one value, got none")
            for value in values:
                choice(name, value, valid)
            if len(set(values)) != len(values):
                raise InvalidInputError(f"{name}: expected distinct values, got {', '.join(values)}")
        positive_int("scenarios", self.scenarios)
        positive_int("batch", self.batch)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidInputError(f"seed: expected a whole number >= 0, got {self.seed!r}")
        if not (np.isfinite(self.sensor_noise) and self.sensor_noise >= 0):
            raise InvalidInputError(f"sensor_noise: expected a number >= 0 (rad), got {self.sensor_noise!r}")
        object.__setattr__(self, "base", load_scenario(self.config))
        LoopConfig(self.base.loop.gains, delay=self.delay)  # validates delay

    def units(self) -> list[tuple[str, int]]:
        """(family, unit index) of every unit of work, in output order."""
        per_family = -(-self.scenarios // self.batch)
        return [(family, u) for family in self.families for u in range(per_family)]

    def unit_rows(self, unit: tuple[str, int]) -> int:
        """Rows unit `unit` writes."""
        _, u = unit
        count = min(self.batch, self.scenarios - u * self.batch)
        return count * len(self.planners) * len(self.ff_accel) * len(self.gravity_comp)

    def record(self) -> dict[str, Any]:
        """The settings as row columns (each a str, int or float)."""
        g = self.base.loop.gains
        base = json.dumps(self.base.as_dict(), sort_keys=True)
        return {"sweep_families": "+".join(self.families), "sweep_scenarios": self.scenarios,
                "sweep_seed": self.seed, "sweep_planners": "+".join(self.planners),
                "sweep_ff_accel": "+".join(self.ff_accel), "sweep_gravity_comp": "+".join(self.gravity_comp),
                "sweep_batch": self.batch, "sensor_noise": self.sensor_noise, "delay": self.delay,
                "model_error_measured": int(self.model_error),
                "config": self.config or "paper.toml (shipped)",
                "config_sha256": hashlib.sha256(base.encode()).hexdigest()[:16],
                "feedforward": self.base.loop.feedforward, "anti_windup": self.base.loop.anti_windup,
                "substeps": self.base.loop.substeps, "dt": self.base.task.dt,
                **{f"{name}_{j}": float(v) for name in ("kp", "ki", "kd") for j, v in enumerate(getattr(g, name))}}

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready settings (for a worker on another machine)."""
        out = asdict(self)
        out.pop("base", None)
        return out


def versions() -> dict[str, str]:
    """The versions every row records: mjtraj, mujoco and numpy of `mjtraj.compare.versions`."""
    from mjtraj.compare import versions as all_versions

    every = all_versions()
    return {name: every[name] for name in VERSION_COLUMNS}


@dataclass
class UnitResult:
    """One unit's rows (dicts with the same keys, in output order) and the seconds each stage took."""

    unit: tuple[str, int]
    rows: list[dict[str, Any]]
    seconds: dict[str, float]


def planner_for(settings: SweepSettings, name: str) -> Planner:
    """The planner (or variant) `name` with the base scenario's options and Bryson's rule for its weights."""
    registered, extra = VARIANTS.get(name, (name, {}))
    options = dict(settings.base.planner_options.get(registered, {}))
    if registered == "optimal":
        options.pop("state_weight", None)
        options.pop("input_weight", None)
    return make(registered, **{**options, **extra})


def plan_scenarios(settings: SweepSettings, scenarios: Sequence[FamilyScenario], model: mujoco.MjModel,
                   planners: Sequence[str] | None = None) -> dict[str, list[Reference | MjtrajError]]:
    """Each planner's reference for each scenario, or the MjtrajError its planning raised (`planners`: default
    the settings' own)."""
    plans: dict[str, list[Reference | MjtrajError]] = {}
    tasks = [s.task for s in scenarios]
    for name in settings.planners if planners is None else planners:
        planner = planner_for(settings, name)
        if hasattr(planner, "plan_many"):
            plans[name] = planner.plan_many(tasks, model)
            continue
        out: list[Reference | MjtrajError] = []
        for task in tasks:
            try:
                out.append(planner.plan(task, model))
            except MjtrajError as e:
                out.append(e)
        plans[name] = out
    return plans


def one_line(error: BaseException) -> str:
    """An error as one line: 'Type: message'."""
    return " ".join(f"{type(error).__name__}: {error}".split())


def _model_errors(model: mujoco.MjModel, refs: list[Reference]) -> np.ndarray:
    """RMS of q_pred - q of each reference's u_plan applied open loop to the nominal nonlinear plant, rad."""
    n = model.nv
    zero = PIDGains.create(np.zeros(n), np.zeros(n), np.zeros(n), n)
    loop = ClosedLoop(model, LoopConfig(zero, feedforward="planned", divergence_bound=100.0), nsim=len(refs),
                      nthread=1)
    rollout = loop.run(refs)
    out = np.sqrt(np.mean(np.square(rollout.e), axis=(1, 2)))
    return np.where(rollout.diverged, np.inf, out)


def unit_scenarios(settings: SweepSettings, unit: tuple[str, int], model: mujoco.MjModel) -> list[FamilyScenario]:
    """The scenarios of unit `unit` = (family, index): [index * batch, (index + 1) * batch) of the family."""
    family, u = unit
    first = u * settings.batch
    return [scenario(family, settings.seed, i, model, settings.base.task.dt)
            for i in range(first, min(first + settings.batch, settings.scenarios))]


def scoring_weights(scenarios: Sequence[FamilyScenario], model: mujoco.MjModel
                    ) -> list[tuple[np.ndarray, np.ndarray]]:
    """diag(Q_exec) (2n,) and diag(R_exec) (n,) of each scenario: Bryson's rule for its task."""
    limit = JointInfo.of(model).torque_limit
    return [bryson_weights(s.task, limit) for s in scenarios]


def run_unit(settings: SweepSettings, unit: tuple[str, int]) -> UnitResult:
    """Compute unit `unit` = (family, index): plan, execute, score. Never raises for a scenario's failure: a
    failed plan, a divergence or an unexpected error becomes that row's status and reason."""
    seconds = {"sample": 0.0, "plan": 0.0, "execute": 0.0, "metrics": 0.0}
    clock = time.perf_counter()
    family, u = unit
    model = load_model(dt=settings.base.task.dt)
    scenarios = unit_scenarios(settings, unit, model)
    weights = scoring_weights(scenarios, model)
    seconds["sample"] += time.perf_counter() - clock
    try:
        rows = _unit_rows(settings, unit, model, scenarios, weights, seconds)
    except Exception as e:  # noqa: BLE001 - recorded, and the sweep goes on
        fixed = fixed_columns(settings)
        rows = [make_row(fixed, family, u, s, planner, ff, gc, "error", one_line(e), {}, {})
                for s in scenarios
                for ff in settings.ff_accel for gc in settings.gravity_comp for planner in settings.planners]
    return UnitResult(unit, rows, seconds)


def _unit_rows(settings: SweepSettings, unit: tuple[str, int], model: mujoco.MjModel,
               scenarios: list[FamilyScenario], weights: list[tuple[np.ndarray, np.ndarray]],
               seconds: dict[str, float]) -> list[dict[str, Any]]:
    family, u = unit
    clock = time.perf_counter()
    plans = plan_scenarios(settings, scenarios, model)
    extras: dict[tuple[int, str], dict[str, float]] = {}
    for name, refs in plans.items():
        for b, ref in enumerate(refs):
            if isinstance(ref, Reference) and ref.u_plan is not None:
                extras[(b, name)] = {"plan_effort": float(np.sqrt(np.mean(np.square(ref.u_plan))))}
    if settings.model_error:
        for group in by_steps([(key, plans[key[1]][key[0]]) for key in extras]):
            errors = _model_errors(model, [ref for _, ref in group])
            for (key, _), value in zip(group, errors, strict=True):
                extras[key]["model_error"] = float(value)
    seconds["plan"] += time.perf_counter() - clock
    noisy = family == "mismatch" and settings.sensor_noise > 0
    mismatch = family == "mismatch"
    plant = perturbed_plant(model) if mismatch else None
    outcome: dict[tuple[int, str, str, str], tuple[str, str, dict[str, float]]] = {}
    live = [((b, name), plans[name][b]) for b in range(len(scenarios)) for name in settings.planners
            if isinstance(plans[name][b], Reference)]
    for ff in settings.ff_accel:
        for gc in settings.gravity_comp:
            config = LoopConfig(settings.base.loop.gains, feedforward=settings.base.loop.feedforward,
                                ff_accel=ff, gravity_comp=gc, anti_windup=settings.base.loop.anti_windup,
                                substeps=settings.base.loop.substeps, delay=settings.delay if mismatch else 0)
            for group in by_steps(live):
                clock = time.perf_counter()
                keys = [key for key, _ in group]
                refs = [ref for _, ref in group]
                fields = plant_fields(plant, [scenarios[b].perturbation for b, _ in keys]) if mismatch else None
                loop = ClosedLoop(model, config, nsim=len(refs), plant=plant, plant_fields=fields, nthread=1)
                noise = None
                if noisy:
                    noise = measurement_noise([scenarios[b] for b, _ in keys], refs[0].steps, model.nv,
                                              settings.sensor_noise, model.opt.timestep)
                rollout = loop.run(refs, noise=noise)
                unstable = loop.plant.unstable()
                seconds["execute"] += time.perf_counter() - clock
                clock = time.perf_counter()
                q_diag = np.array([weights[b][0] for b, _ in keys])
                r_diag = np.array([weights[b][1] for b, _ in keys])
                arrays = metrics_arrays(rollout, q_diag, r_diag, per_scenario=True)
                for j, (b, name) in enumerate(keys):
                    outcome[(b, name, ff, gc)] = episode_outcome(arrays, j, bool(unstable[j]),
                                                                 int(rollout.diverged_step[j]), config)
                seconds["metrics"] += time.perf_counter() - clock
    rows = []
    fixed = fixed_columns(settings)
    for b, s in enumerate(scenarios):
        for ff in settings.ff_accel:
            for gc in settings.gravity_comp:
                for name in settings.planners:
                    plan = plans[name][b]
                    if isinstance(plan, MjtrajError):
                        rows.append(make_row(fixed, family, u, s, name, ff, gc, *plan_failure(plan), {}, {}))
                        continue
                    status, reason, values = outcome[(b, name, ff, gc)]
                    rows.append(make_row(fixed, family, u, s, name, ff, gc, status, reason, values,
                                     {**extras.get((b, name), {}), "solver": plan.info.get("solver", "")}))
    return rows


def episode_outcome(arrays: dict[str, np.ndarray], j: int, unstable: bool, diverged_step: int, config: LoopConfig
                    ) -> tuple[str, str, dict[str, float]]:
    """(status, reason, metric values) of episode j of a batch: unstable, diverged (no values) or ok."""
    if unstable:
        return "unstable", "MuJoCo flagged the simulation numerically unstable (bad qacc/qpos/qvel)", {}
    if diverged_step >= 0:
        return "diverged", f"|e| > {config.divergence_bound:.4g} rad at step {diverged_step}", {}
    return "ok", "", {m: float(arrays[m][j]) for m in METRIC_NAMES}


def plan_failure(plan: MjtrajError) -> tuple[str, str]:
    """(status, reason) of a scenario whose planning failed."""
    return ("infeasible" if isinstance(plan, InfeasibleError) else "solver_error"), one_line(plan)


def by_steps(items: list[tuple[Any, Reference]]) -> Iterator[list[tuple[Any, Reference]]]:
    """Items grouped by their reference's N (one ClosedLoop runs references of one length)."""
    groups: dict[int, list[tuple[Any, Reference]]] = {}
    for key, ref in items:
        groups.setdefault(ref.steps, []).append((key, ref))
    for steps in sorted(groups):
        yield groups[steps]


COLUMNS: tuple[str, ...] = ()
"""Filled below: the columns of a results file, in order."""


def fixed_columns(settings: SweepSettings) -> dict[str, Any]:
    """The columns every row of a sweep shares: its settings and the versions."""
    return {**settings.record(), **versions()}


def make_row(fixed: dict[str, Any], family: str, unit: int, s: FamilyScenario, planner: str, ff: str, gc: str,
         status: str, reason: str, values: dict[str, float],
         extra: dict[str, Any]) -> dict[str, Any]:
    task = s.task
    row: dict[str, Any] = {"family": family, "scenario": s.index, "unit": unit, "planner": planner, "ff_accel": ff,
                           "gravity_comp": gc, "status": status, "reason": reason}
    row.update({m: values.get(m, float("nan")) for m in METRIC_NAMES})
    row.update({m: float(extra.get(m, float("nan"))) for m in EXTRA_METRICS})
    row["solver"] = extra.get("solver", "")
    row.update({"duration": task.duration, "max_displacement": float(np.max(np.abs(task.displacement)))})
    row.update({f"q0_{j}": float(v) for j, v in enumerate(task.q0)})
    row.update({f"qg_{j}": float(v) for j, v in enumerate(task.qg)})
    pert = {"payload_kg": float("nan"), **{f"{name}_{j}": float("nan") for name in
                                            ("mass_scale", "inertia_scale", "damping", "friction")
                                            for j in range(task.n)}}
    if s.perturbation is not None:
        pert = s.perturbation.as_dict()
    row.update(pert)
    row.update(fixed)
    return row
