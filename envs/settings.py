"""The env's keyword arguments: declared once (`EnvOptions` plus the loop options of LoopConfig), validated once,
and resolved against the paper scenario's controller."""

from __future__ import annotations

import dataclasses
import inspect
import os
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.core import (
    FILTER,
    JointInfo,
    LoopConfig,
    Planner,
    Scoring,
    Task,
    available,
    check_name,
    check_options,
    controller_names,
    declared_options,
    load_model,
    option,
    random_task,
    window_steps,
)
from mjtraj.domain import (
    FAMILIES,
    FamilyScenario,
    Perturbation,
    Scenario,
    arm_scales,
    draw_family,
    draw_perturbation,
    draw_scenario,
    load_scenario,
    noise_scale,
)
from mjtraj.exceptions import InvalidInputError
from mjtraj.media import RENDER_QUALITIES, check_render_options

ACTION_MODES = ("pid", "residual", "torque")
TASKS = ("paper", "random", "explicit")
PREVIEW_FRAMES = ("absolute", "relative", "reference")
"""The env's `preview_frame` values: the preview's samples themselves, minus the observed state, or minus the
reference now."""
ENV_FAMILIES = ("none", *FAMILIES)
"""The env's `family` values: none (tasks by `task`), or a sweep family whose rules draw each episode."""
RENDER_MODES = ("rgb_array", "depth_array", "human")
"""The single env's; the vector env renders the first two (a window shows one env)."""
PLANT_RANDOMIZATIONS = ("none", "mismatch")
REWARD_BASELINES = ("none", "controller", "pid")
"""none; controller: the reward is the advantage over the configured control law alone (a shadow loop); pid: the
same, under its earlier name (it always ran the configured law, PID or another), kept so that earlier runs load."""
OBSERVE_PLANT = ("none", "true", "estimate")
"""What the observation says of the plant: nothing; its true payload, damping and friction (privileged: a teacher);
or the adaptive law's online estimate of them (deployable; needs controller='adaptive_computed_torque')."""
RESIDUAL_SCALE = 6.0
"""N m, the default authority of a residual action: the median per-joint RMS feedback torque of PID on the mismatch
family (cubic references, 1000 scenarios: 6.40 N m, see docs/design.md), rounded to one significant figure. The
residual is meant to supply what feedback supplies under model error, not the 60 N m saturation."""
ENV_OWN = ("planner", "q0", "qg", "Q_exec", "R_exec", "render_mode", "xml_file", "torque_limit")
"""Arguments that are not declared options (objects, vectors or None)."""


@dataclass(frozen=True)
class EnvOptions:
    """UR5Track-v0's own scalar arguments, declared once (the loop's follow from LoopConfig)."""

    action_mode: str = option("pid", "pid (the controller alone), residual (added to feedforward + PID) or torque "
                              "(the whole corrective torque)", choices=ACTION_MODES)
    residual_scale: float = option(RESIDUAL_SCALE, "N m per unit of action in residual mode (torque mode scales by "
                                   "the saturation)", positive=True)
    task: str = option("paper", "paper, random or explicit", choices=TASKS)
    family: str = option("none", "none, or a sweep family (nominal, aggressive, mismatch): each episode is drawn from "
                         "the reset's generator by that family's rules (task, duration, plant); needs task='random'",
                         choices=ENV_FAMILIES)
    max_displacement: float = option(1.5, "largest abs(qg - q0) per joint of task='random', rad", positive=True)
    duration: float = option(2.0, "T, s (a whole number of dt)", positive=True)
    dt: float = option(0.02, "control period, s", positive=True)
    preview: int = option(0, "future reference samples in the observation", minimum=0)
    preview_frame: str = option("absolute", "absolute (the preview's samples q_ref and qd_ref themselves) or relative "
                                "(each minus the observed q and qd: the error the arm would have if it stayed, the "
                                "same information in the frame a feedback law reads it in) or reference (each minus "
                                "q_ref and qd_ref now: the measurement enters through q, qd, e and ed alone)",
                                choices=PREVIEW_FRAMES)
    observe_control: bool = option(False, "append the PID integral and the next feedforward torque to the "
                                   "observation (both enter dtau and the reward)")
    observe_plant: str = option("none", "none; true = append the plant's payload, damping and friction over their "
                                "bounds (privileged: a teacher); estimate = append the adaptive law's online "
                                "estimate of them (deployable; controller='adaptive_computed_torque')",
                                choices=OBSERVE_PLANT)
    observe_disturbance: bool = option(False, "append the torque disturbance mpc's Kalman filter estimates (N m over "
                                       "the saturation, one per joint: mpc_filter shadowing the loop, the estimate "
                                       "mpc plans from; needs a settle window, where the filter runs)")
    observe_task: bool = option(False, "append the task's move (its largest joint displacement, rad: the score's "
                                "position scale) and the time to the motion's end (s, negative in the settle window)")
    observe_measured: bool = option(False, "q, qd, e and ed in the observation are what the control law measures "
                                    "(with measurement_noise, the noisy ones); False: the true state (privileged "
                                    "under noise)")
    settle: float = option(0.0, "settle window, s: the episode goes on this long after the motion, the reference "
                           "holding the goal, every period scored; its end reports info['settled'] (at rest at the "
                           "goal) and the settle metrics (protocol v2)", minimum=0.0)
    history: int = option(0, "previous observations appended to each observation, the latest first (an episode's "
                          "first observation fills them)", minimum=0)
    teacher: str = option("none", "none, or a control law that shadows the env's own on the same states: "
                          "env.unwrapped.loop.teach(teacher) gives its command of the step to come, and "
                          "loop.teach(controller) the env's law's own, without the action (imitation, DAgger); it "
                          "changes nothing the env does", choices=lambda: ("none", *controller_names()))
    plant_randomization: str = option("none", "none, or mismatch: each episode's plant drawn by the sweeps' mismatch "
                                      "rules (payload, link masses and inertias, damping, friction)",
                                      choices=PLANT_RANDOMIZATIONS)
    measurement_noise: float = option(0.0, "std of the noise on measured q, rad (sqrt(2) x / dt on qd), drawn per "
                                      "episode; 0 for exact measurements", minimum=0.0)
    reward_baseline: str = option("none", "none, or controller: the reward is the advantage over the configured "
                                  "control law alone, minus (step cost - the same episode's step cost under that law "
                                  "with no action, run in a shadow loop); metrics keep J_exec ('pid' is its earlier "
                                  "name)", choices=REWARD_BASELINES)
    floor: bool = option(False, "at each episode's end also compute its clairvoyant floor (the least score any "
                         "controller can reach on it; with a settle window at rest at the goal) into info['metrics'] "
                         "as floor and cost_over_floor (its cost: docs/floor.md)")
    width: int = option(640, "image width, px", minimum=1)
    height: int = option(480, "image height, px", minimum=1)
    camera: str = option("front", "a camera of the model (the UR5: front, side, top) or free (framed on the model); "
                         "front falls back to free on a model without it")
    render_quality: str = option("fast", "fast (no shadows or reflection, fewer facets) or high (the model's own "
                                 "scene, for publication frames)", choices=RENDER_QUALITIES)

    def __post_init__(self) -> None:
        check_options(self)


def argument_defaults() -> dict[str, Any]:
    """Every env argument and its default: the env's own, then the loop options (the paper scenario's values)."""
    paper = load_scenario()
    own = {f.name: f.default for f, _, _ in declared_options(EnvOptions)}
    loop = {f.name: getattr(paper.loop, f.name) for f, _, _ in declared_options(LoopConfig)}
    return {"planner": "cubic", **own, "q0": None, "qg": None, "Q_exec": None, "R_exec": None, "render_mode": None,
            "xml_file": None, "torque_limit": None, **loop}



def argument_parameters() -> list[inspect.Parameter]:
    """Every env argument as a keyword-only parameter with its default (`argument_defaults`) and its type: the
    declared options' types, `resolve`'s annotations for the others."""
    kinds = {f.name: kind for cls in (EnvOptions, LoopConfig) for f, _, kind in declared_options(cls)}
    own = inspect.signature(resolve).parameters
    return [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default,
                              annotation=kinds[name] if name in kinds else own[name].annotation)
            for name, default in argument_defaults().items()]


class ArgumentsSignature:
    """An env class's `__signature__`, for `help()`, `inspect.signature` and the editors that ask them: the class's
    own named parameters, then every env argument keyword-only with its default (`argument_parameters`), where its
    `__init__` takes them as `**kwargs` and passes them to `resolve`. Built when asked (it reads the paper
    scenario); a subclass with an `__init__` of its own gets that one's signature."""

    def __set_name__(self, owner: type, name: str) -> None:
        self._init = owner.__init__  # type: ignore[misc]

    def __get__(self, instance: object, owner: type) -> inspect.Signature | None:
        if owner.__init__ is not self._init:  # type: ignore[misc]
            return None  # inspect then reads the subclass's own __init__
        leading = [p for p in inspect.signature(self._init).parameters.values()
                   if p.name != "self" and p.kind is not inspect.Parameter.VAR_KEYWORD]
        return inspect.Signature([*leading, *argument_parameters()])


@dataclass(frozen=True)
class TrackSettings:
    """Everything an env instance needs, validated."""

    model: mujoco.MjModel
    model_path: str | None
    """The user's MJCF file the model was prepared from; None for the shipped UR5."""
    model_torque_limit: float | tuple[float, ...] | None
    """With model_path: every joint's corrective saturation given for it, N m."""
    planner: Planner
    planner_name: str
    action_mode: str
    residual_scale: float
    """N m per unit of action in residual mode."""
    task_mode: str
    fixed_task: Task | None
    """The task of every episode ('paper', 'explicit'); None for 'random'."""
    max_displacement: float
    duration: float
    dt: float
    loop: LoopConfig
    preview: int
    preview_frame: str
    """'absolute', 'relative' (the preview's samples minus the observed q and qd) or 'reference' (minus q_ref and
    qd_ref now)."""
    observe_control: bool
    """The observation ends with the PID integral and the next feedforward torque."""
    observe_plant: str
    """'none', 'true' (the plant's parameters, privileged) or 'estimate' (the adaptive law's estimate of them)."""
    observe_disturbance: bool
    """The observation also holds `mpc`'s filtered torque disturbance over the saturation (`mpc_filter`)."""
    history: int
    """Previous observations appended to each one."""
    teacher: str
    """'none', or the control law that shadows the env's own (`ClosedLoop.teach`)."""
    observe_task: bool
    """The observation ends with the move (rad) and the time to the motion's end (s)."""
    observe_measured: bool
    """The observation's state is the measured one (noisy under measurement noise)."""
    settle: float
    """The settle window, s (0: none)."""
    plant_randomization: str
    """'none' or 'mismatch' (`mjtraj.domain.families` rules, drawn per episode)."""
    family: str
    """'none', or the sweep family whose rules draw every episode's task and plant."""
    measurement_noise: float
    """Std of the noise on measured q, rad (0: exact)."""
    reward_baseline: str
    """'none', or 'pid': rewards are advantages over PID alone on the same episode."""
    floor: bool
    """Episode metrics also carry the episode's clairvoyant floor."""
    scoring: Scoring
    render_mode: str | None
    width: int
    height: int
    camera: str
    render_quality: str

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
        """(6n + 1 + 2n preview (+ 2n with observe_control) (+ 1 + 2n with observe_plant) (+ n with
        observe_disturbance) (+ 2 with observe_task)) (1 + history)."""
        one = (6 * self.n + 1 + 2 * self.n * self.preview + 2 * self.n * self.observe_control
               + (1 + 2 * self.n) * (self.observe_plant != "none") + self.n * self.observe_disturbance
               + 2 * self.observe_task)
        return one * (1 + self.history)

    def shadows(self) -> tuple[str, ...]:
        """The laws and estimators that shadow the env's loop (`ClosedLoop(teachers=...)`): the teacher and the env's
        own law (to label against it), and with observe_disturbance `mpc_filter`."""
        out = () if self.teacher == "none" else (self.teacher, self.loop.controller)
        return tuple(dict.fromkeys((*out, *((FILTER,) if self.observe_disturbance else ()))))

    @property
    def settle_steps(self) -> int:
        """The settle window in control periods (0: none)."""
        return window_steps(self.settle, self.dt)

    @property
    def torque_limit(self) -> NDArray[np.float64]:
        """The corrective-torque saturation, shape (n,), N m."""
        return JointInfo.of(self.model).torque_limit

    @property
    def action_scale(self) -> NDArray[np.float64]:
        """N m per unit of action, shape (n,): residual_scale in residual mode, else the saturation."""
        if self.action_mode == "residual":
            return np.full(self.n, self.residual_scale)
        return self.torque_limit

    @property
    def perturbs(self) -> bool:
        """Episodes run on perturbed plants (plant randomisation, or the mismatch family)."""
        return self.plant_randomization != "none" or self.family == "mismatch"

    def sample_episode(self, rng: np.random.Generator) -> tuple[Task, Perturbation | None]:
        """The next episode's task and plant (None: nominal), drawn from `rng`: by the family's rules, or the task
        (`sample_task`) then the plant (`sample_plant`)."""
        if self.family != "none":
            return draw_family(rng, self.family, self.model, self.dt)
        return self.sample_task(rng), self.sample_plant(rng)

    def scenario(self, spec: Any) -> FamilyScenario:
        """The held-out sweep scenario `spec` = {"family": F, "seed": S, "index": i} names (what
        `reset(options={"scenario": spec})` replays), drawn as sweeps draw it.

        Raises:
          InvalidInputError: a malformed spec, or a mismatch scenario in an env without perturbed plants.
        """
        keys = ("family", "seed", "index")
        if not isinstance(spec, dict) or set(spec) != set(keys):
            raise InvalidInputError(f"options: 'scenario' expects a dict with the keys {', '.join(keys)}, got {spec!r}")
        family = spec["family"]
        if family not in FAMILIES:
            raise InvalidInputError(f"options: scenario family {family!r} is unknown; valid: {', '.join(FAMILIES)}")
        for key in ("seed", "index"):
            if isinstance(spec[key], bool) or not isinstance(spec[key], (int, np.integer)) or spec[key] < 0:
                raise InvalidInputError(f"options: scenario {key} must be a whole number >= 0, got {spec[key]!r}")
        if family == "mismatch" and not self.perturbs:
            raise InvalidInputError("options: a mismatch scenario runs on a perturbed plant; make the env with "
                                    "family='mismatch' (UR5TrackMismatch-v1) or plant_randomization='mismatch'")
        if family != "mismatch" and self.measurement_noise > 0 and self.observe_measured:
            raise InvalidInputError(f"options: a {family} scenario is measured without noise (sweeps draw noise for "
                                    f"mismatched plants only); make the env with measurement_noise=0 to replay it, "
                                    f"got measurement_noise={self.measurement_noise}")
        return draw_scenario(family, int(spec["seed"]), int(spec["index"]), self.model, self.dt)

    def weights(self, task: Task) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """diag(Q_exec) (2n,) and diag(R_exec) (n,) that score an episode of `task` (`mjtraj.core.scoring`): the
        given ones, else Bryson's rule for the task, the rule sweeps score every scenario by. For the paper task
        Bryson's rule gives the paper scenario's weights."""
        return self.scoring.weights(task, self.torque_limit)

    def sample_plant(self, rng: np.random.Generator) -> Perturbation | None:
        """The next episode's plant: None for the nominal one, else (plant randomisation or the mismatch family) a
        mismatch plant drawn from `rng` (after the task) by the sweeps' mismatch rules."""
        return draw_perturbation(rng, self.n, arm_scales(self.model, self.dt)) if self.perturbs else None

    def sample_noise(self, rng: np.random.Generator, steps: int | None = None) -> NDArray[np.float64] | None:
        """The next episode's measurement noise on [q; qd], shape (steps, 2n) (its reference's N; None: the env's
        duration's), drawn from `rng` after the plant; None without noise."""
        if self.measurement_noise == 0.0:
            return None
        count = self.steps if steps is None else steps
        return rng.standard_normal((count, 2 * self.n)) * noise_scale(self.n, self.measurement_noise, self.dt)

    def sample_task(self, rng: np.random.Generator) -> Task:
        """The next episode's task: the fixed one, or for 'random' a start uniform in the joint ranges and a goal
        uniform in the ranges within +-max_displacement of it (two draws of n uniforms from `rng`)."""
        if self.fixed_task is not None:
            return self.fixed_task
        return random_task(rng, self.model, max_displacement=self.max_displacement, duration=self.duration,
                           dt=self.dt)


def _planner(planner: Any, paper: Scenario) -> tuple[str, Planner]:
    if isinstance(planner, str):
        return check_name("planner", planner), paper.planner(planner)
    if callable(getattr(planner, "plan", None)):
        return type(planner).__name__, planner
    raise InvalidInputError(f"planner: expected a registered name ({', '.join(available())}) or an object with "
                            f"plan(task, model), got {planner!r}")


def resolve(*, planner: str | Planner = "cubic", q0: npt.ArrayLike | None = None, qg: npt.ArrayLike | None = None,
            Q_exec: npt.ArrayLike | None = None, R_exec: npt.ArrayLike | None = None, render_mode: str | None = None,
            xml_file: str | os.PathLike[str] | None = None, torque_limit: float | list[float] | None = None,
            scenario: Scenario | None = None, **options: Any) -> TrackSettings:
    """Validate the env's arguments (see UR5TrackEnv; the declared ones are EnvOptions' and LoopConfig's) and fill
    in the paper scenario's controller.

    Raises:
      InvalidInputError: an unknown argument (the valid ones are listed) or a bad value.
    """
    scenario = _arm_scenario(xml_file, scenario, torque_limit, q0, qg, options)
    paper = scenario if scenario is not None else load_scenario()
    env_names = [f.name for f, _, _ in declared_options(EnvOptions)]
    loop_names = [f.name for f, _, _ in declared_options(LoopConfig)]
    own = _own_options(options, env_names, loop_names)
    loop = dataclasses.replace(paper.loop, **{k: v for k, v in options.items() if k in loop_names})
    _check_loop(own, loop)
    planner_name, planner_obj = _planner(planner, paper)
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise InvalidInputError(f"render_mode: unsupported mode {render_mode!r}; valid: None, "
                                f"{', '.join(RENDER_MODES)}")
    model = load_model(paper.model_path, dt=own.dt, torque_limit=paper.model_torque_limit)
    n = model.nv
    fixed = _fixed_task(own, paper, model, q0, qg)
    if (Q_exec is None) != (R_exec is None):
        raise InvalidInputError("Q_exec, R_exec: give both (diagonals of 2n and n weights), or neither for Bryson's "
                                "rule on each task")
    scoring = Scoring() if Q_exec is None else Scoring.fixed(Q_exec, R_exec, n)  # type: ignore[arg-type]
    width, height, camera = check_render_options(model, own.width, own.height, own.camera)
    return TrackSettings(model=model, model_path=paper.model_path, model_torque_limit=paper.model_torque_limit,
                         planner=planner_obj, planner_name=planner_name, action_mode=own.action_mode,
                         residual_scale=float(own.residual_scale), task_mode=own.task, fixed_task=fixed,
                         max_displacement=own.max_displacement,
                         duration=own.duration, dt=own.dt, loop=loop, preview=own.preview,
                         preview_frame=own.preview_frame,
                         observe_control=own.observe_control, observe_plant=own.observe_plant,
                         observe_disturbance=own.observe_disturbance, history=own.history, teacher=own.teacher,
                         observe_task=own.observe_task,
                         observe_measured=own.observe_measured, settle=own.settle,
                         plant_randomization=own.plant_randomization,
                         family=own.family,
                         measurement_noise=own.measurement_noise, reward_baseline=own.reward_baseline,
                         floor=own.floor, scoring=scoring,
                         render_mode=render_mode, width=width, height=height, camera=camera,
                         render_quality=own.render_quality)


def _arm_scenario(xml_file: str | os.PathLike[str] | None, scenario: Scenario | None,
                  torque_limit: float | list[float] | None, q0: npt.ArrayLike | None, qg: npt.ArrayLike | None,
                  options: dict[str, Any]) -> Scenario | None:
    """The scenario of the user's arm `xml_file` (its gains for every drawn task where the env draws tasks), else
    `scenario`; a torque limit only with an arm of one's own."""
    if xml_file is not None:
        from mjtraj.domain import scenario_for_model

        if scenario is not None:
            raise InvalidInputError("xml_file, scenario: give one")
        dt = options.get("dt", 0.02)
        drawn = options.get("task") == "random" or options.get("family", "none") != "none"
        scenario = scenario_for_model(xml_file, dt=dt if isinstance(dt, (int, float)) else 0.02,
                                      torque_limit=torque_limit, workspace=drawn,  # gains for every drawn task
                                      q0=q0 if options.get("task") == "explicit" else None,
                                      qg=qg if options.get("task") == "explicit" else None)
    elif torque_limit is not None:
        raise InvalidInputError(f"torque_limit: only with xml_file (your own arm), got {torque_limit!r} for the "
                                f"UR5, whose saturation is its motors' 60 N m")
    return scenario


def _own_options(options: dict[str, Any], env_names: list[str], loop_names: list[str]) -> EnvOptions:
    """The env's own options (EnvOptions) from `options`, after refusing an unknown name and a family combined with
    a task or plant rule of its own."""
    unknown = sorted(set(options) - set(env_names) - set(loop_names))
    if unknown:
        raise InvalidInputError(f"{unknown[0]}: unknown argument; valid: "
                                f"{', '.join([*ENV_OWN, *env_names, *loop_names])}")
    own = EnvOptions(**{k: v for k, v in options.items() if k in env_names})
    if own.family != "none" and own.task != "random":
        raise InvalidInputError(f"family: {own.family!r} draws every episode's task; use task='random', got "
                                f"task={own.task!r}")
    if own.family != "none" and own.plant_randomization != "none":
        raise InvalidInputError(f"plant_randomization: with family={own.family!r} the family's rules draw the plant; "
                                "use family='mismatch' for perturbed plants")
    return own


def _check_loop(own: EnvOptions, loop: LoopConfig) -> None:
    """Refuse what the loop cannot give the env's options: the adaptive law's estimate observed without that law,
    a settle window of a fraction of a period, and the floor with a settle window or another plant step."""
    if own.observe_plant == "estimate" and loop.controller != "adaptive_computed_torque":
        raise InvalidInputError(f"observe_plant: 'estimate' observes the adaptive law's estimate; expected "
                                f"controller='adaptive_computed_torque', got {loop.controller!r}")
    window_steps(own.settle, own.dt)  # a whole number of periods
    if own.floor and own.settle:
        raise InvalidInputError(f"floor: the clairvoyant floor is derived for episodes without a settle window; got "
                                f"settle={own.settle}")
    if own.floor and (loop.gravity_comp != "native" or loop.substeps != 1):
        raise InvalidInputError(f"floor: the floor models native gravity compensation at one integrator step per "
                                f"period; got gravity_comp={loop.gravity_comp!r}, substeps={loop.substeps}")


def _fixed_task(own: EnvOptions, paper: Scenario, model: mujoco.MjModel, q0: npt.ArrayLike | None,
                qg: npt.ArrayLike | None) -> Task | None:
    """Every episode's task for task='paper' or 'explicit' (q0 -> qg, rad, given only then), else None (drawn per
    episode; its time grid checked now)."""
    if own.task == "explicit":
        if q0 is None or qg is None:
            raise InvalidInputError("task: 'explicit' needs both q0 and qg (rad)")
    elif q0 is not None or qg is not None:
        raise InvalidInputError(f"q0, qg: only used with task='explicit', got task={own.task!r}")
    fixed: Task | None = None
    if own.task == "paper":
        fixed = Task.create(paper.task.q0, paper.task.qg, own.duration, own.dt, model=model)
    elif own.task == "explicit":
        fixed = Task.create(q0, qg, own.duration, own.dt, model=model)  # type: ignore[arg-type]
    else:
        Task.create(np.zeros(model.nv), np.zeros(model.nv), own.duration, own.dt)  # validates the time grid now
    return fixed
