"""Sweeps: every planner on thousands of seeded scenarios through the one batched closed loop.

The work is cut into units (a family's scenarios [u * batch, (u + 1) * batch)). `run_unit` computes one unit's
rows from the settings alone, so any backend (this process, a process pool, a Ray cluster) gives the same rows,
bit for bit. Rows are one per scenario, controller variant (ff_accel x gravity_comp) and planner.

Rules shared by every scenario (stated once here, recorded with every row):
- the controller is the base scenario's (default: the shipped paper.toml): its gains, feedforward mode,
  anti-windup and substeps, for every task and planner;
- the optimal planner's Q, R and the execution cost's Q_exec, R_exec follow Bryson's rule per task
  (`mjtraj.core.scoring.bryson_weights`), the rule paper.toml states for its own task;
- the planners' other options are the base scenario's.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import choice, positive_int, seed_value
from mjtraj.core.arm import normalized_limit
from mjtraj.core.closed_loop import ClosedLoop, LoopConfig
from mjtraj.core.controller import PIDGains
from mjtraj.core.options import choices, option_names
from mjtraj.core.planners import Planner, available, make, plan_all
from mjtraj.core.reference import Reference
from mjtraj.core.scoring import Scoring
from mjtraj.core.settle import window_steps, with_window
from mjtraj.domain.families import FAMILIES, FamilyScenario, draw_scenario, measurement_noise, perturbed_plant
from mjtraj.domain.pipeline import Actor, Job, Outcome, execute, goal_checked, one_line, plan_failure
from mjtraj.domain.scenario import Scenario, load_scenario, scenario_for_model
from mjtraj.exceptions import InvalidInputError, MjtrajError
from mjtraj.study.rows import Row
from mjtraj.versions import provenance

DEFAULT_PLANNERS = ("optimal", "cubic", "quintic", "trapezoidal")
SHIPPED_CONFIG = "paper.toml (shipped)"
"""The config column of a sweep on the shipped paper scenario."""
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "optimal_start": ("optimal", {"linearization": "start"}),
    "min_effort": ("optimal", {"alpha": 0.0}),
}
"""Planner variants a sweep can name besides the registered planners: the optimal planner linearised at the
start pose (claim 6 of the audit), and with Q = 0, the minimum-effort reference of the linear model."""
SWEPT = ("ff_accel", "gravity_comp")
"""The controller options a sweep runs every value of (its controller variants)."""
SCORING = Scoring()
"""Sweeps score every scenario by Bryson's rule on its task."""


def planner_names() -> tuple[str, ...]:
    """Every name a sweep accepts in `planners`."""
    return tuple(available()) + tuple(VARIANTS)


@dataclass(frozen=True)
class SweepSettings:
    """Everything that determines a sweep's rows (all of it is written into every row).

    Attributes:
      families: scenario families (see mjtraj.domain.families).
      scenarios: scenarios per family.
      seed: the sweep's seed.
      planners: registered planners and VARIANTS.
      ff_accel, gravity_comp: the controller variants; every combination runs on every scenario.
      batch: scenarios per unit of work (rows depend on it only through floating-point summation order).
      sensor_noise: std of the position measurement noise in mismatch scenarios, rad (0: none).
      delay: actuation delay of mismatch scenarios, control periods (0 or 1).
      model_error: also measure the linear model's prediction error of optimal-type planners.
      config: the base scenario file (None: the shipped paper.toml).
      model: an MJCF arm instead (its scenario by the arm rules, `scenario_for_model`); not with `config`.
      torque_limit: with `model`, the corrective saturation, N m: one value for every joint, or one per joint
        (None: from the model).
      floors: also each row's clairvoyant floor (`mjtraj.domain.floor.floors_of`: its planner's reference on its
        plant under its controller variant) and the row's score over it, columns FLOOR_COLUMNS (NaN where the
        variant's gravity compensation is not native, which the floor does not model, or the floor failed); with a
        settle window, protocol v2's floor (J_settle, at rest at the goal).
      settle: the settle window, s (protocol v2, `mjtraj.core.settle`): every execution goes on after its motion
        for this long, the reference holding the goal, and is scored over the whole episode (J_settle) and held to
        the at-rest rule; 0 (the default, the paper's study): the motion alone, J_exec.
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
    model: str | None = None
    torque_limit: float | tuple[float, ...] | None = None
    floors: bool = False
    settle: float = 0.0
    base: Scenario = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name, values, valid in (("family", self.families, FAMILIES), ("planner", self.planners, planner_names()),
                                    *((axis, getattr(self, axis), choices(LoopConfig, axis)) for axis in SWEPT)):
            if not values:
                raise InvalidInputError(f"{name}: expected at least one value, got none")
            for value in values:
                choice(name, value, valid)
            if len(set(values)) != len(values):
                raise InvalidInputError(f"{name}: expected distinct values, got {', '.join(values)}")
        positive_int("scenarios", self.scenarios)
        positive_int("batch", self.batch)
        seed_value("seed", self.seed)
        if not (np.isfinite(self.sensor_noise) and self.sensor_noise >= 0):
            raise InvalidInputError(f"sensor_noise: expected a number >= 0 (rad), got {self.sensor_noise!r}")
        object.__setattr__(self, "torque_limit", normalized_limit(self.torque_limit))
        if self.torque_limit is not None and self.model is None:
            raise InvalidInputError("torque_limit: only with model (a scenario file sets torque_limit beside model)")
        if self.model is not None:
            if self.config is not None:
                raise InvalidInputError("model, config: give one (a scenario file names its arm with model = "
                                        "\"PATH\")")
        object.__setattr__(self, "base", load_scenario(self.config) if self.model is None else
                           scenario_for_model(self.model, torque_limit=self.torque_limit, workspace=True))
        self.loop_config(self.ff_accel[0], self.gravity_comp[0], mismatch=True)  # validates delay
        window_steps(self.settle, self.base.task.dt)  # validates the window

    @property
    def settle_steps(self) -> int:
        """The settle window in control periods (0: none)."""
        return window_steps(self.settle, self.base.task.dt)

    def units(self) -> list[tuple[str, int]]:
        """(family, unit index) of every unit of work, in output order."""
        per_family = -(-self.scenarios // self.batch)
        return [(family, u) for family in self.families for u in range(per_family)]

    def unit_rows(self, unit: tuple[str, int]) -> int:
        """Rows unit `unit` writes."""
        _, u = unit
        count = min(self.batch, self.scenarios - u * self.batch)
        return count * len(self.planners) * len(self.ff_accel) * len(self.gravity_comp)

    def loop_config(self, ff_accel: str, gravity_comp: str, *, mismatch: bool) -> LoopConfig:
        """The base scenario's controller in one controller variant (the delay applies to mismatch scenarios)."""
        return dataclasses.replace(self.base.loop, ff_accel=ff_accel, gravity_comp=gravity_comp,
                                   delay=self.delay if mismatch else 0)

    def record(self) -> dict[str, Any]:
        """The settings as row columns (each a str, int or float): the sweep's own, then the base scenario's
        controller options that are not swept, dt and the gains."""
        g = self.base.loop.gains
        base = json.dumps(self.base.as_dict(), sort_keys=True)
        return {"sweep_families": "+".join(self.families), "sweep_scenarios": self.scenarios,
                "sweep_seed": self.seed, "sweep_planners": "+".join(self.planners),
                **{f"sweep_{axis}": "+".join(getattr(self, axis)) for axis in SWEPT},
                "sweep_batch": self.batch, "sensor_noise": self.sensor_noise, "delay": self.delay,
                "model_error_measured": int(self.model_error),
                "config": self.config or SHIPPED_CONFIG, "model": self.model or "",
                "torque_limit": "" if self.torque_limit is None else
                "+".join(repr(v) for v in self.torque_limit) if isinstance(self.torque_limit, tuple) else
                self.torque_limit,
                "config_sha256": hashlib.sha256(base.encode()).hexdigest()[:16],
                **({"sweep_floors": 1} if self.floors else {}),
                **({"settle": self.settle} if self.settle else {}),
                **{name: getattr(self.base.loop, name) for name in option_names(LoopConfig) if name not in SWEPT},
                "dt": self.base.task.dt,
                **{f"{name}_{j}": float(v) for name in ("kp", "ki", "kd") for j, v in enumerate(getattr(g, name))}}

    @classmethod
    def from_record(cls, row: dict[str, str]) -> SweepSettings:
        """The settings a results row records (`record`), rebuilt; the base scenario is loaded again from the
        recorded config (compare `record()["config_sha256"]` with the row's to know it is unchanged).

        Raises:
          InvalidInputError: a setting column is missing or malformed, or the config cannot be loaded.
        """
        try:
            config = row["config"]
            return cls(families=tuple(row["sweep_families"].split("+")), scenarios=int(row["sweep_scenarios"]),
                       seed=int(row["sweep_seed"]), planners=tuple(row["sweep_planners"].split("+")),
                       **{axis: tuple(row[f"sweep_{axis}"].split("+")) for axis in SWEPT},
                       batch=int(row["sweep_batch"]), sensor_noise=float(row["sensor_noise"]),
                       delay=int(row["delay"]), model_error=bool(int(row["model_error_measured"])),
                       config=None if config == SHIPPED_CONFIG else config, model=row.get("model") or None,
                       torque_limit=normalized_limit([float(v) for v in row["torque_limit"].split("+")])
                       if row.get("torque_limit") else None, floors=bool(int(row.get("sweep_floors") or 0)),
                       settle=float(row.get("settle") or 0.0))
        except (KeyError, ValueError) as e:
            raise InvalidInputError(f"sweep: a row's settings are malformed ({e}); not a sweep results file") from e

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready settings (for a worker on another machine)."""
        out = asdict(self)
        out.pop("base", None)
        return out


@dataclass(frozen=True)
class ActorSpec:
    """An actor evaluated beside the planners (`mjtraj rl eval`'s policies): its rows carry `label` in the planner
    column and `columns` after the settings; it tracks `planner`'s references in the sweep's first controller
    variant."""

    label: str
    planner: str
    actor: Actor
    columns: dict[str, Any] = field(default_factory=dict)
    stop_on: tuple[type[Exception], ...] = ()
    """Errors of the actor that end the run (raised from `run_unit`) instead of becoming its rows' error status."""


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


def plan_scenarios(settings: SweepSettings, scenarios: Sequence[FamilyScenario],
                   planners: Sequence[str] | None = None) -> dict[str, list[Reference | MjtrajError]]:
    """Each planner's reference for each scenario, or the MjtrajError its planning raised (`planners`: default
    the settings' own)."""
    tasks = [s.task for s in scenarios]
    return {name: plan_all(planner_for(settings, name), tasks, settings.base.model)
            for name in (settings.planners if planners is None else planners)}


def _model_errors(model: mujoco.MjModel, refs: list[Reference]) -> NDArray[np.float64]:
    """RMS of q_pred - q of each reference's u_plan applied open loop to the nominal nonlinear plant, rad."""
    n = model.nv
    zero = PIDGains.create(np.zeros(n), np.zeros(n), np.zeros(n), n)
    loop = ClosedLoop(model, LoopConfig(zero, feedforward="planned", divergence_bound=100.0), nsim=len(refs),
                      nthread=1)
    rollout = loop.run(refs)
    out = np.sqrt(np.mean(np.square(rollout.e), axis=(1, 2)))
    return np.where(rollout.diverged, np.inf, out)


def unit_scenarios(settings: SweepSettings, unit: tuple[str, int]) -> list[FamilyScenario]:
    """The scenarios of unit `unit` = (family, index): [index * batch, (index + 1) * batch) of the family."""
    family, u = unit
    first = u * settings.batch
    return [draw_scenario(family, settings.seed, i, settings.base.model, settings.base.task.dt)
            for i in range(first, min(first + settings.batch, settings.scenarios))]


def scoring_weights(settings: SweepSettings, scenarios: Sequence[FamilyScenario]
                    ) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """diag(Q_exec) (2n,) and diag(R_exec) (n,) of each scenario: Bryson's rule for its task."""
    limit = settings.base.torque_limit
    return [SCORING.weights(s.task, limit) for s in scenarios]


def jobs_for(settings: SweepSettings, scenarios: Sequence[FamilyScenario], references: Sequence[Reference],
             weights: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]]) -> list[Job]:
    """The pipeline's jobs of scenarios[b] tracking references[b]: their perturbation, for mismatch scenarios under
    sensor noise their measurement noise (declared to the control law), and with a settle window the reference
    holding the task's goal for it (the noise drawn for the whole episode: its first N periods are the motion's
    draw)."""
    model = settings.base.model
    window = settings.settle_steps
    out = []
    for s, ref, w in zip(scenarios, references, weights, strict=True):
        ref, settle = with_window(s.task, ref, window)
        noise, sensor = None, 0.0
        if s.perturbation is not None and settings.sensor_noise > 0:
            noise = measurement_noise([s], ref.steps, model.nv, settings.sensor_noise, model.opt.timestep)[:, 0]
            sensor = settings.sensor_noise
        out.append(Job(ref, w, s.perturbation, noise, settle, sensor))
    return out


def run_unit(settings: SweepSettings, unit: tuple[str, int], *, actors: Sequence[ActorSpec] = ()) -> UnitResult:
    """Compute unit `unit` = (family, index): plan, execute, score; then each of `actors` on the same scenarios,
    plans and plants. Never raises for a scenario's failure: a failed plan, a divergence or an unexpected error
    becomes that row's status and reason."""
    seconds = {"sample": 0.0, "plan": 0.0, "execute": 0.0, "metrics": 0.0}
    clock = time.perf_counter()
    family, u = unit
    scenarios = unit_scenarios(settings, unit)
    weights = scoring_weights(settings, scenarios)
    seconds["sample"] += time.perf_counter() - clock
    try:
        rows = scenario_rows(settings, unit, scenarios, weights, seconds, actors)
    except tuple(kind for spec in actors for kind in spec.stop_on):
        raise
    except Exception as e:  # noqa: BLE001 - recorded, and the sweep goes on
        fixed = fixed_columns(settings)
        failed = Outcome("error", one_line(e))
        rows = [Row(family=family, scenario=s.index, unit=u, planner=planner, ff_accel=ff, gravity_comp=gc,
                    outcome=failed, task=s.task, perturbation=s.perturbation, settings=fixed,
                    settle=bool(settings.settle)).columns()
                for s in scenarios
                for ff in settings.ff_accel for gc in settings.gravity_comp for planner in settings.planners]
    return UnitResult(unit, rows, seconds)


def scenario_rows(settings: SweepSettings, unit: tuple[str, int], scenarios: list[FamilyScenario],
                  weights: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
                  seconds: dict[str, float] | None = None, actors: Sequence[ActorSpec] = ()) -> list[dict[str, Any]]:
    """The rows of `scenarios` (unit `unit` = (family, index) of the rows), scored with `weights`; `seconds` per
    stage are added to (see run_unit). Raises what planning or execution raise (run_unit records it). The stages:
    plan (with each plan's extra columns), execute every planner under every controller variant (and the floors),
    then the planners' rows and each actor's."""
    seconds = {"sample": 0.0, "plan": 0.0, "execute": 0.0, "metrics": 0.0} if seconds is None else seconds
    family, _ = unit
    base = settings.base
    clock = time.perf_counter()
    plans = plan_scenarios(settings, scenarios)
    extras = _plan_extras(settings, plans)
    seconds["plan"] += time.perf_counter() - clock
    plant = perturbed_plant(base.model, base.model_path, base.model_torque_limit) if family == "mismatch" else None
    outcomes, floors = _executions(settings, family, scenarios, plans, weights, plant, seconds)
    rows = _planner_rows(settings, unit, scenarios, plans, extras, outcomes, floors)
    for spec in actors:
        rows += _actor_rows(settings, unit, scenarios, plans, weights, plant, spec)
    return rows


_Key = tuple[int, str, str, str]
"""(scenario position in the unit, planner, ff_accel, gravity_comp): one execution of a unit."""


def _plan_extras(settings: SweepSettings, plans: dict[str, list[Reference | MjtrajError]]
                 ) -> dict[tuple[int, str], dict[str, float]]:
    """(scenario position, planner) -> the plan's own columns: its planned effort (rms of u_plan, N m) where it has
    one, and with `model_error` the linear model's open-loop prediction error."""
    extras: dict[tuple[int, str], dict[str, float]] = {}
    for name, refs in plans.items():
        for b, ref in enumerate(refs):
            if isinstance(ref, Reference) and ref.u_plan is not None:
                extras[(b, name)] = {"plan_effort": float(np.sqrt(np.mean(np.square(ref.u_plan))))}
    if settings.model_error:
        keyed = [(key, ref) for key in extras if isinstance(ref := plans[key[1]][key[0]], Reference)]
        for steps in sorted({ref.steps for _, ref in keyed}):
            group = [(key, ref) for key, ref in keyed if ref.steps == steps]
            errors = _model_errors(settings.base.model, [ref for _, ref in group])
            for (key, _), value in zip(group, errors, strict=True):
                extras[key]["model_error"] = float(value)
    return extras


def _executions(settings: SweepSettings, family: str, scenarios: list[FamilyScenario],
                plans: dict[str, list[Reference | MjtrajError]],
                weights: list[tuple[NDArray[np.float64], NDArray[np.float64]]], plant: mujoco.MjModel | None,
                seconds: dict[str, float]) -> tuple[dict[_Key, Outcome], dict[_Key, float]]:
    """Every planned reference executed under every controller variant, and with `floors` each execution's floor
    (NaN where it failed)."""
    model = settings.base.model
    mismatch = family == "mismatch"
    live = [(b, name) for b in range(len(scenarios)) for name in settings.planners
            if isinstance(plans[name][b], Reference)]
    references = [ref for b, name in live if isinstance(ref := plans[name][b], Reference)]
    jobs = jobs_for(settings, [scenarios[b] for b, _ in live], references, [weights[b] for b, _ in live])
    outcomes: dict[_Key, Outcome] = {}
    floors: dict[_Key, float] = {}
    for ff in settings.ff_accel:
        for gc in settings.gravity_comp:
            config = settings.loop_config(ff, gc, mismatch=mismatch)
            for (b, name), result in zip(live, execute(model, config, jobs, plant=plant, seconds=seconds),
                                         strict=True):
                outcomes[(b, name, ff, gc)] = result
            if settings.floors and gc == "native" and config.substeps == 1:
                from mjtraj.domain.floor import Floor, floors_of

                clock = time.perf_counter()
                moves = [float(np.max(np.abs(scenarios[b].task.displacement))) for b, _ in live]
                for (b, name), found in zip(live, floors_of(model, config, jobs, plant=plant, displacements=moves),
                                            strict=True):
                    floors[(b, name, ff, gc)] = found.cost if isinstance(found, Floor) else float("nan")
                seconds["floor"] = seconds.get("floor", 0.0) + time.perf_counter() - clock
    return outcomes, floors


def _planner_rows(settings: SweepSettings, unit: tuple[str, int], scenarios: list[FamilyScenario],
                  plans: dict[str, list[Reference | MjtrajError]], extras: dict[tuple[int, str], dict[str, float]],
                  outcomes: dict[_Key, Outcome], floors: dict[_Key, float]) -> list[dict[str, Any]]:
    """One row per scenario, controller variant and planner, in that order (a failed plan's row says why)."""
    family, u = unit
    rows = []
    fixed = fixed_columns(settings)
    for b, s in enumerate(scenarios):
        for ff in settings.ff_accel:
            for gc in settings.gravity_comp:
                for name in settings.planners:
                    plan = plans[name][b]
                    if isinstance(plan, MjtrajError):
                        result, extra, solver = plan_failure(plan), {}, ""
                    else:
                        result, extra, solver = outcomes[(b, name, ff, gc)], extras.get((b, name), {}), \
                            str(plan.info.get("solver", ""))
                    result = goal_checked(result, float(np.max(np.abs(s.task.displacement))))
                    more = floor_columns(result, floors.get((b, name, ff, gc), float("nan"))) if settings.floors \
                        else {}
                    rows.append(Row(family=family, scenario=s.index, unit=u, planner=name, ff_accel=ff,
                                    gravity_comp=gc, outcome=result, extras=extra, solver=solver, task=s.task,
                                    perturbation=s.perturbation, settings=fixed, more=more,
                                    settle=bool(settings.settle)).columns())
    return rows


def _actor_rows(settings: SweepSettings, unit: tuple[str, int], scenarios: list[FamilyScenario],
                plans: dict[str, list[Reference | MjtrajError]],
                weights: list[tuple[NDArray[np.float64], NDArray[np.float64]]], plant: mujoco.MjModel | None,
                spec: ActorSpec) -> list[dict[str, Any]]:
    """An actor's rows on its planner's references under the first controller variant (an error other than
    `spec.stop_on` becomes every row's status, and the evaluation goes on)."""
    family, u = unit
    ff, gc = settings.ff_accel[0], settings.gravity_comp[0]
    config = settings.loop_config(ff, gc, mismatch=family == "mismatch")
    refs = plans[spec.planner]
    ids = [b for b, ref in enumerate(refs) if isinstance(ref, Reference)]
    try:
        mine = jobs_for(settings, [scenarios[b] for b in ids], [r for r in refs if isinstance(r, Reference)],
                        [weights[b] for b in ids])
        done = dict(zip(ids, execute(settings.base.model, config, mine, plant=plant, actor=spec.actor), strict=True))
    except spec.stop_on:
        raise
    except Exception as e:  # noqa: BLE001 - recorded, and the evaluation goes on
        done = {b: Outcome("error", one_line(e)) for b in range(len(scenarios))}
    rows = []
    fixed = fixed_columns(settings)
    for b, s in enumerate(scenarios):
        plan = refs[b]
        result = done[b] if b in done else plan_failure(plan) if isinstance(plan, MjtrajError) else \
            Outcome("error", "not executed")
        result = goal_checked(result, float(np.max(np.abs(s.task.displacement))))
        rows.append(Row(family=family, scenario=s.index, unit=u, planner=spec.label, ff_accel=ff,
                        gravity_comp=gc, outcome=result, task=s.task, perturbation=s.perturbation,
                        settings=fixed, more=spec.columns, settle=bool(settings.settle)).columns())
    return rows


FLOOR_COLUMNS = ("floor", "cost_over_floor")
"""A sweep's floor columns (`SweepSettings.floors`): the row's clairvoyant floor and its J_exec over it (NaN where the
row has no J_exec or no floor)."""


def floor_columns(result: Outcome, floor: float) -> dict[str, float]:
    """FLOOR_COLUMNS of a row whose execution had `result` and whose floor is `floor` (NaN: none)."""
    cost = result.metrics.get("cost", float("nan")) if result.status == "ok" else float("nan")
    return {"floor": floor, "cost_over_floor": cost / floor if np.isfinite(floor) and floor > 0 else float("nan")}


def fixed_columns(settings: SweepSettings) -> dict[str, Any]:
    """The columns every row of a sweep shares: its settings and the provenance of the process that computes it
    (`mjtraj.versions.provenance`: versions, BLAS, CPU, commit)."""
    return {**settings.record(), **provenance()}


def columns(settings: SweepSettings) -> list[str]:
    """The header of a results file for `settings` (a mismatch row carries every column)."""
    probe = draw_scenario("mismatch", settings.seed, 0, settings.base.model, settings.base.task.dt)
    row = Row(family="mismatch", scenario=0, unit=0, planner=settings.planners[0], ff_accel=settings.ff_accel[0],
              gravity_comp=settings.gravity_comp[0], outcome=Outcome("ok"), task=probe.task,
              perturbation=probe.perturbation, settings=fixed_columns(settings),
              more=floor_columns(Outcome("ok"), float("nan")) if settings.floors else {}, settle=bool(settings.settle))
    return list(row.columns())
