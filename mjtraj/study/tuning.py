"""Tuning every planner's free parameters with an equal, held-out budget, by the scenario's fixed score.

Rules (stated once, recorded in every tuned scenario file):
- the free parameters (PARAMETERS): the optimal planner's alpha (log-uniform in [1e-6, 1e2]) and split ([0, 1]);
  the trapezoid's cruise_factor ((1, 2]); the S-curve's acceleration_factor ((4, 16]) and jerk_factor (log-uniform
  in [30, 1000]); cubic and quintic have none;
- the optimiser is the same for every planner: a scrambled Sobol sequence of `budget` points over the parameter box
  (scipy.stats.qmc.Sobol, seeded), every point evaluated, the best kept. Every tunable planner gets the same
  number of evaluations;
- the objective is the mean J_exec over the training scenarios, J_exec scored by Bryson's rule per task (as sweeps
  score) with the scenario's controller; a point with any failed scenario (plan failed, diverged) scores +inf;
- held out: training scenarios follow the family's rules but come from the stream [seed, TRAIN_STREAM + family id,
  i], which no evaluation (sweeps, rl eval) draws from. The oracle mode (`on_task`) tunes on the scenario's own
  task instead, is labelled so, and never stands for a held-out result.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mjtraj.checks import positive_int
from mjtraj.core.controller import PIDGains
from mjtraj.core.planners import Planner, check_name, make, plan_all
from mjtraj.core.reference import Reference
from mjtraj.core.scoring import Scoring
from mjtraj.domain.families import FAMILIES, FAMILY_ID, FamilyScenario, draw_scenario, perturbed_plant
from mjtraj.domain.pipeline import Job, execute
from mjtraj.domain.scenario import Scenario
from mjtraj.exceptions import InvalidInputError
from mjtraj.versions import versions

TRAIN_STREAM = 32
"""Training scenarios of family F come from stream TRAIN_STREAM + FAMILY_ID[F]; evaluations use 0-2 (families)
and 16-17 (RL)."""
PARAMETERS: dict[str, dict[str, tuple[str, float, float]]] = {
    "optimal": {"alpha": ("log", 1e-6, 1e2), "split": ("linear", 0.0, 1.0)},
    "trapezoidal": {"cruise_factor": ("linear", 1.0, 2.0)},
    "scurve": {"acceleration_factor": ("linear", 4.0, 16.0), "jerk_factor": ("log", 30.0, 1000.0)},
    "cubic": {},
    "quintic": {},
}
"""Planner -> parameter -> (scale, low, high). A linear parameter is drawn in (low, high]."""
GAIN_PARAMETERS: dict[str, tuple[str, float, float]] = {"kp_scale": ("log", 0.25, 4.0), "ki_scale": ("log", 0.25, 4.0),
                                                        "kd_scale": ("log", 0.25, 4.0)}
"""The PID gains' free parameters (`tune_gains`): factors on the stated rule's kp, ki and kd (every joint alike)."""
ADAPTATION_PARAMETERS: dict[str, tuple[str, float, float]] = {"adaptation_rate": ("log", 1e-4, 1.0)}
"""The adaptive law's free parameter (`tune_gains`): its adaptation rate gamma, 1/(N m rad)."""
LAW_PARAMETERS = {"pid": GAIN_PARAMETERS, "adaptive_computed_torque": ADAPTATION_PARAMETERS}
"""Each tunable control law's free parameters."""
OPTIMISER = "scrambled Sobol sequence over the parameter box (scipy.stats.qmc.Sobol), best point kept"
OBJECTIVE = "mean J_exec over the training scenarios (Bryson's rule per task; +inf if any failed)"


@dataclass(frozen=True)
class Trial:
    """One evaluated point: its parameters, objective and failed scenarios."""

    parameters: dict[str, float]
    objective: float
    failed: int


@dataclass(frozen=True)
class PlannerTuning:
    """A planner's tuning: every trial in order, and the best."""

    planner: str
    trials: list[Trial]

    @property
    def best(self) -> Trial:
        return min(self.trials, key=lambda t: (t.objective, len(t.parameters)))


def training_stream(family: str) -> int:
    """The stream the training scenarios of `family` are drawn from (never an evaluation stream)."""
    stream = TRAIN_STREAM + FAMILY_ID[family]
    evaluation = {f"{name} family": i for name, i in FAMILY_ID.items()} | {"RL training": 16, "RL validation": 17}
    clash = [name for name, i in evaluation.items() if i == stream]
    if clash:
        raise InvalidInputError(f"stream: the training stream {stream} is the {clash[0]}'s evaluation stream")
    return stream


def points(parameters: dict[str, tuple[str, float, float]], budget: int, seed: int) -> list[dict[str, float]]:
    """`budget` points of the parameter box from a scrambled Sobol sequence (one point, {}, without parameters)."""
    if not parameters:
        return [{}]
    from scipy.stats import qmc

    unit = qmc.Sobol(d=len(parameters), scramble=True, seed=seed).random(budget)
    out = []
    for row in unit:
        point = {}
        for u, (name, (scale, low, high)) in zip(row, parameters.items(), strict=True):
            if scale == "log":
                point[name] = float(10 ** (math.log10(low) + u * (math.log10(high) - math.log10(low))))
            else:
                point[name] = float(high - u * (high - low))  # (low, high]: u in [0, 1)
        out.append(point)
    return out


def planner_with(scenario: Scenario, name: str, parameters: dict[str, float]) -> Planner:
    """The scenario's planner `name` with `parameters`; the optimal planner takes Bryson's weights per task."""
    options = dict(scenario.planner_options.get(name, {}))
    if name == "optimal":
        for key in ("state_weight", "input_weight"):
            options.pop(key, None)
    return make(name, **{**options, **parameters})


def objective(scenario: Scenario, planner: Planner, draws: Sequence[FamilyScenario], scoring: Scoring,
              family: str | None) -> tuple[float, int]:
    """(mean J_exec, failed scenarios) of `planner` on `draws` with the scenario's controller."""
    model = scenario.model
    tasks = [d.task for d in draws]
    refs = plan_all(planner, tasks, model)
    jobs = [Job(ref, scoring.weights(d.task, scenario.torque_limit), d.perturbation)
            for ref, d in zip(refs, draws, strict=True) if isinstance(ref, Reference)]
    plant = (perturbed_plant(model, scenario.model_path, scenario.model_torque_limit) if family == "mismatch"
             else None)
    outcomes = execute(model, scenario.loop, jobs, plant=plant) if jobs else []
    failed = len(draws) - len(jobs) + sum(o.status != "ok" for o in outcomes)
    if failed:
        return math.inf, failed
    return float(np.mean([o.metrics["cost"] for o in outcomes])), 0


def tune(scenario: Scenario, *, planners: Sequence[str] = ("optimal", "trapezoidal", "scurve"),
         family: str = "nominal",
         scenarios: int = 50, seed: int = 0, budget: int = 32, on_task: bool = False,
         progress: Callable[[int, int], None] | None = None) -> tuple[Scenario, list[PlannerTuning]]:
    """Tune `planners` (see the module rules); the scenario with the tuned options and its tuning record;
    `progress(done, total)` is called after every evaluated point.

    Raises:
      InvalidInputError: an unknown planner or family, a budget or scenario count below 1.
    """
    positive_int("budget", budget)
    for name in planners:
        check_name("planners", name)
    if family not in FAMILIES:
        raise InvalidInputError(f"family: unknown value {family!r}; valid: {', '.join(FAMILIES)}")
    if on_task:
        draws = [FamilyScenario("task", 0, scenario.task, None, 0)]
        scoring, stream, where = scenario.scoring, None, None
    else:
        stream = training_stream(family)
        draws = training_draws(scenario, family, scenarios, seed)
        scoring, where = Scoring(), family
    results = []
    options = {k: dict(v) for k, v in scenario.planner_options.items()}
    grids = {name: points(PARAMETERS.get(name, {}), budget, seed) for name in planners}
    total, done = sum(len(g) for g in grids.values()), 0
    for name in planners:
        trials = []
        for point in grids[name]:
            value, failed = objective(scenario, planner_with(scenario, name, point), draws, scoring, where)
            trials.append(Trial(point, value, failed))
            done += 1
            if progress is not None:
                progress(done, total)
        tuning = PlannerTuning(name, trials)
        results.append(tuning)
        if PARAMETERS.get(name):
            mine = dict(options.get(name, {}))
            if name == "optimal":
                mine.pop("state_weight", None)
                mine.pop("input_weight", None)
            options[name] = {**mine, **tuning.best.parameters}
    record = {
        "mode": "oracle: tuned on the evaluation task itself" if on_task else "held out",
        "family": "the scenario's task" if on_task else family, "scenarios": len(draws), "seed": seed,
        "stream": "the scenario's task" if on_task else f"[seed, {stream}, i]", "budget": budget,
        "optimiser": OPTIMISER, "objective": OBJECTIVE if not on_task else "J_exec on the task (the scenario's score)",
        "parameters": {name: {k: list(v) for k, v in PARAMETERS.get(name, {}).items()} for name in planners},
        "result": {t.planner: {**t.best.parameters, "objective": t.best.objective, "evaluations": len(t.trials)}
                   for t in results},
        "base": scenario.name, "versions": versions(),
    }
    suffix = "_oracle" if on_task else "_tuned"
    tuned = dataclasses.replace(scenario, name=scenario.name + suffix, planner_options=options, tuning=record,
                                source="")
    return tuned, results


def training_draws(scenario: Scenario, family: str, scenarios: int, seed: int) -> list[FamilyScenario]:
    """The `scenarios` training scenarios of `family` under `seed`, from its training stream (`training_stream`).

    Raises:
      InvalidInputError: a scenario count below 1.
    """
    positive_int("scenarios", scenarios)
    stream = training_stream(family)
    return [draw_scenario(family, seed, i, scenario.model, scenario.task.dt, stream=stream) for i in range(scenarios)]


def scaled_gains(scenario: Scenario, factors: dict[str, float]) -> PIDGains:
    """The scenario's PID gains times GAIN_PARAMETERS' factors (kp_scale, ki_scale, kd_scale)."""
    g = scenario.loop.gains
    return dataclasses.replace(g, kp=g.kp * factors["kp_scale"], ki=g.ki * factors["ki_scale"],
                               kd=g.kd * factors["kd_scale"])


def with_law_parameters(scenario: Scenario, point: dict[str, float]) -> Scenario:
    """The scenario with LAW_PARAMETERS' `point` of its control law: PID gain factors or the adaptation rate."""
    if scenario.loop.controller == "pid":
        return scenario.replace(loop={"gains": scaled_gains(scenario, point)})
    return scenario.replace(loop=point)


def tune_gains(scenario: Scenario, *, family: str = "mismatch", scenarios: int = 50, seed: int = 0,
               budget: int = 32, progress: Callable[[int, int], None] | None = None
               ) -> tuple[Scenario, PlannerTuning]:
    """Tune the control law's free parameters (LAW_PARAMETERS: the PID gains' factors on kp, ki, kd, or the
    adaptive law's adaptation rate) by the module's rules, with the cubic planner's references: a Sobol sequence of
    `budget` points, each scored by the mean J_exec over the training scenarios of `family`; the scenario with the
    best point and its record.

    Raises:
      InvalidInputError: an unknown family, a budget or scenario count below 1, or a scenario whose law has no
        tunable parameters (computed torque's gains follow a rule).
    """
    positive_int("budget", budget)
    if family not in FAMILIES:
        raise InvalidInputError(f"family: unknown value {family!r}; valid: {', '.join(FAMILIES)}")
    law = scenario.loop.controller
    if law not in LAW_PARAMETERS:
        raise InvalidInputError(f"gains: expected a scenario whose control law has free parameters "
                                f"({', '.join(LAW_PARAMETERS)}), got {law!r}")
    parameters = LAW_PARAMETERS[law]
    stream = training_stream(family)
    draws = training_draws(scenario, family, scenarios, seed)
    trials = []
    cubic = make("cubic")
    for point in points(parameters, budget, seed):
        value, failed = objective(with_law_parameters(scenario, point), cubic, draws, Scoring(), family)
        trials.append(Trial(point, value, failed))
        if progress is not None:
            progress(len(trials), budget)
    label = "pid_gains" if law == "pid" else f"{law}_parameters"
    tuning = PlannerTuning(label, trials)
    best = tuning.best.parameters
    what = ("PID gains (factors on the stated rule's kp, ki, kd)" if law == "pid" else
            f"{law}'s {', '.join(parameters)}")
    record = {"mode": "held out", "what": what, "family": family,
              "scenarios": scenarios, "seed": seed, "stream": f"[seed, {stream}, i]", "budget": budget,
              "optimiser": OPTIMISER, "objective": OBJECTIVE + ", cubic references",
              "parameters": {k: list(v) for k, v in parameters.items()},
              "result": {label: {**best, "objective": tuning.best.objective, "evaluations": len(trials)}},
              "base": scenario.name, "versions": versions()}
    tuned = dataclasses.replace(with_law_parameters(scenario, best), name=scenario.name + "_tuned_gains",
                                tuning=record, source="")
    return tuned, tuning
