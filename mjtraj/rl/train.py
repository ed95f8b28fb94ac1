"""Train an SB3 agent on the natively vectorised UR5Track env and record everything about the run.

Rules (stated once, recorded in run.json):
- hyperparameters are Stable-Baselines3's defaults for the algorithm (sb3-contrib's for RecurrentPPO, an LSTM
  policy whose memory spans an episode and is cleared at each episode start), with two additions SB3 leaves to
  the user: PPO collects SB3's default 2048 transitions per update (n_steps = 2048 / num_envs), and TD3 explores with
  Gaussian action noise of std 0.1 (the TD3 paper's; SB3 adds none). Nothing was tuned on evaluation scenarios.
  `overrides` (from `--hyperparameter NAME=VALUE` or a JSON file) replace them by name and are recorded as such;
- rewards are normalised by SB3's VecNormalize (running statistics); observations too (clip 10), or with
  observation_scaling="fixed" divided by fixed physical scales instead (`mjtraj.rl.scaling`, clip 10); saved
  policies carry the observation transform;
- sub-env i trains on the TRAIN_STREAM seed (seed, i) and continues its stream across episodes; the learning
  curve's validation tasks come from VALIDATION_STREAM (mjtraj.rl.streams), so neither is a sweep scenario;
- with plant randomisation every training episode runs on a plant drawn by the mismatch rules, and so does every
  validation task (its plant drawn after its task from the same stream);
- best.zip is the policy of the validation point with the lowest mean J_exec (the checkpoint selected on the
  validation tasks, never on evaluation scenarios); policy.zip is the final one.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import shutil
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from mjtraj.checks import choice, positive, positive_int
from mjtraj.core import LoopConfig, check_name, controller_names, option_names
from mjtraj.envs import (
    OBSERVE_PLANT,
    PLANT_RANDOMIZATIONS,
    RESIDUAL_SCALE,
    REWARD_BASELINES,
    TASKS,
    TrackSettings,
    resolve,
)
from mjtraj.exceptions import InvalidInputError
from mjtraj.files import write_text_atomic
from mjtraj.rl import ACTION_MODES, ALGORITHM_NAMES, ALGORITHMS
from mjtraj.rl.adapters import from_zip_policy
from mjtraj.rl.batched_policy import BATCHED_RUN
from mjtraj.rl.curve import CurveFile, plot_curve
from mjtraj.rl.episodes import run_episodes
from mjtraj.rl.extra import algorithm, policy_class, require_sb3, rl_versions
from mjtraj.rl.policy import Normalization, Policy
from mjtraj.rl.scaling import OBSERVATION_SCALINGS, fixed_normalization
from mjtraj.rl.streams import TRAIN_STREAM, VALIDATION_STREAM, check_seed, training_entropies
from mjtraj.study import Outcome

RUN_FORMAT = "mjtraj-rl-run/1"
DEFAULT_NUM_ENVS = {"sac": 4, "td3": 4, "ppo": 8, "recurrent_ppo": 8}
CLIP_OBS = 10.0
TD3_NOISE_STD = 0.1
RESUMED = ("returns", "diverged", "episodes", "next_eval", "next_save", "next_resume", "curve_rows", "best")
"""The training bookkeeping a resume point keeps (mjtraj.rl.resume)."""
THREADS_RULE = ("PyTorch runs on 1 CPU thread unless threads says otherwise (library and command line alike): the "
                "networks are small, so more threads only add synchronisation (12 steps/s with PyTorch's default "
                "threads against 345 with one, on a 2-core machine), and one thread each lets runs go side by side; "
                "run.json records the count used")


@dataclass(frozen=True)
class TrainSettings:
    """Everything that determines a training run (all of it is written into run.json).

    Attributes:
      algo: sac, ppo or td3.
      action_mode: residual (added to feedforward + PID) or torque (the whole corrective torque).
      residual_scale: N m per unit of action in residual mode (the env's default rule: RESIDUAL_SCALE).
      observe_control: the policy also observes the PID integral and the next feedforward torque.
      observe_plant: none, true (the plant's parameters: a privileged teacher) or estimate (the adaptive law's
        online estimate of them: deployable; needs controller adaptive_computed_torque).
      history: previous observations the policy also sees (memory without recurrence).
      observation_scaling: running (VecNormalize's statistics) or fixed (`mjtraj.rl.scaling`'s stated scales).
      plant_randomization: none, or mismatch (each training and validation episode on a plant drawn by the
        mismatch family's rules).
      reward_baseline: none, or controller (train on the advantage over the control law alone; 'pid' is its
        earlier name; validation and evaluation score J_exec).
      planner: the planner whose references the policy tracks.
      controller: the control law the residual acts on (pid, computed_torque or a plug-in law; LoopConfig's).
      task: paper (always the paper's move) or random (a new random move each episode).
      steps: environment steps to train for (PPO rounds up to whole rollouts).
      seed: the run's seed, in [0, 2^32).
      num_envs: sub-envs stepped together (None: DEFAULT_NUM_ENVS of the algorithm).
      checkpoints: policies saved along the run, evenly spaced; the last is the final policy (policy.zip).
      evaluations: validation points of the learning curve, evenly spaced, the last on the final policy (plus one
        before training).
      validation: validation tasks (task=random; the paper task is its own single validation task).
      threads: PyTorch CPU threads (THREADS_RULE: 1 unless given; None: PyTorch's default, every core).
      overrides: SB3 keyword arguments that replace the defaults above, name -> JSON value (see
        `overridable`).
    """

    algo: str = "sac"
    action_mode: str = "residual"
    residual_scale: float = RESIDUAL_SCALE
    observe_control: bool = False
    observe_plant: str = "none"
    history: int = 0
    observation_scaling: str = "running"
    plant_randomization: str = "none"
    reward_baseline: str = "none"
    planner: str = "cubic"
    controller: str = "pid"
    task: str = "random"
    steps: int = 100_000
    seed: int = 0
    num_envs: int | None = None
    checkpoints: int = 5
    evaluations: int = 20
    validation: int = 32
    threads: int | None = 1
    overrides: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        choice("algo", self.algo, ALGORITHMS)
        choice("action_mode", self.action_mode, ACTION_MODES)
        choice("plant_randomization", self.plant_randomization, PLANT_RANDOMIZATIONS)
        choice("reward_baseline", self.reward_baseline, REWARD_BASELINES)
        choice("observation_scaling", self.observation_scaling, OBSERVATION_SCALINGS)
        choice("observe_plant", self.observe_plant, OBSERVE_PLANT)
        if isinstance(self.history, bool) or not isinstance(self.history, int) or self.history < 0:
            raise InvalidInputError(f"history: expected a whole number >= 0, got {self.history!r}")
        object.__setattr__(self, "residual_scale", positive("residual_scale", self.residual_scale))
        check_name("planner", self.planner)
        choice("controller", self.controller, controller_names())
        choice("task", self.task, tuple(t for t in TASKS if t != "explicit"))
        positive_int("steps", self.steps)
        check_seed("seed", self.seed)
        object.__setattr__(self, "num_envs", positive_int(
            "num_envs", DEFAULT_NUM_ENVS[self.algo] if self.num_envs is None else self.num_envs))
        for name in ("checkpoints", "evaluations", "validation"):
            positive_int(name, getattr(self, name))
        if self.threads is not None:
            positive_int("threads", self.threads)
        if not isinstance(self.observe_control, bool):
            raise InvalidInputError(f"observe_control: expected true or false, got {self.observe_control!r}")
        check_overrides(self.algo, self.overrides)

    def env_kwargs(self) -> dict[str, Any]:
        """UR5Track-v0's arguments, every one that shapes the episodes (defaults written out)."""
        s = resolve(planner=self.planner, action_mode=self.action_mode, task=self.task,
                    residual_scale=self.residual_scale, observe_control=self.observe_control,
                    plant_randomization=self.plant_randomization, reward_baseline=self.reward_baseline,
                    controller=self.controller, observe_plant=self.observe_plant, history=self.history)
        return {"planner": self.planner, "action_mode": self.action_mode, "residual_scale": s.residual_scale,
                "task": self.task,
                "max_displacement": s.max_displacement, "duration": s.duration, "dt": s.dt,
                **{name: getattr(s.loop, name) for name in option_names(LoopConfig)}, "preview": s.preview,
                "observe_control": s.observe_control, "plant_randomization": s.plant_randomization,
                "reward_baseline": s.reward_baseline,
                **({"observe_plant": s.observe_plant} if s.observe_plant != "none" else {}),
                **({"history": s.history} if s.history else {})}

    def hyperparameters(self) -> dict[str, Any]:
        """The keyword arguments given to the SB3 algorithm besides SB3's defaults (JSON-ready): the rules'
        additions, then the overrides."""
        rules: dict[str, Any] = {}
        if self.algo == "ppo":
            rules = {"n_steps": max(1, 2048 // int(self.num_envs or 1))}
        if self.algo == "td3":
            rules = {"action_noise": {"type": "NormalActionNoise", "std": TD3_NOISE_STD}}
        return {**rules, **self.overrides}


NOT_OVERRIDABLE = frozenset({"self", "policy", "env", "verbose", "seed", "device", "_init_setup_model", "action_noise",
                             "replay_buffer_class", "rollout_buffer_class", "tensorboard_log"})
"""SB3 arguments that mjtraj sets itself (seed, device, env, ...) or that are not JSON values."""


def overridable(algo: str) -> list[str]:
    """The SB3 keyword arguments of `algo` that overrides may set (its constructor's, minus NOT_OVERRIDABLE)."""
    import inspect

    init = algorithm(algo).__init__
    return [name for name in inspect.signature(init).parameters if name not in NOT_OVERRIDABLE]


def check_overrides(algo: str, overrides: Any) -> None:
    """InvalidInputError unless `overrides` maps SB3 arguments of `algo` to JSON values (an unknown name lists the
    valid ones)."""
    if not isinstance(overrides, dict):
        raise InvalidInputError(f"overrides: expected a mapping of SB3 argument names to values, got {overrides!r}")
    if not overrides:
        return
    valid = overridable(algo)
    for name, value in overrides.items():
        if name not in valid:
            raise InvalidInputError(f"hyperparameter: unknown name {name!r} for {algo}; valid: {', '.join(valid)}")
        try:
            json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as e:
            raise InvalidInputError(f"hyperparameter: {name} must be a JSON value (number, string, bool, null, list "
                                    f"or object), got {value!r}") from e


@dataclass
class TrainReport:
    """Where a run wrote its files, how far it got, and its last validation."""

    out: Path
    policy: Path
    timesteps: int
    wall: float
    final: dict[str, float]


def validation_set(settings: TrainSettings, env: TrackSettings) -> tuple[list[Any], list[Any], list[Any] | None]:
    """The learning curve's validation references, weights and plants (None: nominal): the paper task, or
    `settings.validation` tasks drawn by the env's random-task rule from VALIDATION_STREAM; with plant
    randomisation each task's plant is drawn after it from the same stream (the paper task: one plant)."""
    count = 1 if env.fixed_task is not None else settings.validation
    rngs = [np.random.default_rng([settings.seed, VALIDATION_STREAM, i]) for i in range(count)]
    tasks = [env.sample_task(rng) for rng in rngs]
    plants = [env.sample_plant(rng) for rng in rngs]
    references = [env.planner.plan(task, env.model) for task in tasks]
    return references, [env.weights(task) for task in tasks], plants if env.plant_randomization != "none" else None


def _summary(outcomes: list[Outcome]) -> dict[str, float]:
    ok = [o for o in outcomes if o.status == "ok"]
    cost = np.array([o.metrics["cost"] for o in ok])
    err = np.array([o.metrics["rms_err"] for o in ok])
    nan = float("nan")
    return {"cost_mean": float(cost.mean()) if cost.size else nan,
            "cost_median": float(np.median(cost)) if cost.size else nan,
            "rms_err_mean": float(err.mean()) if err.size else nan, "diverged": len(outcomes) - len(ok)}


def train(settings: TrainSettings, out: str | Path, *, progress: bool = True,
          tensorboard: str | Path | None = None) -> TrainReport:
    """Train per `settings` into the folder `out` (which must not hold a run yet); with `tensorboard`, SB3's logger
    also writes TensorBoard event files there (its own training statistics, plus every validation point as
    validation/cost_mean, validation/cost_median, validation/rms_err_mean and validation/pid_cost_mean).

    Writes run.json (settings, env arguments, hyperparameters, seeds, versions, status), checkpoints/,
    policy.zip + policy.json (the final policy), learning_curve.csv and learning_curve.png, and at every
    checkpoint resume/ (`mjtraj.rl.resume`; removed when the run completes), from which `resume_training`
    continues an interrupted run.

    Raises:
      InvalidInputError: `out` already holds a run.
      MissingExtraError: the rl extra is not installed.
    """
    folder = Path(out)
    if (folder / "run.json").exists():
        raise InvalidInputError(f"out: {out} already holds a training run (run.json); choose another folder "
                                f"(or continue an interrupted one with --resume {out})")
    return _run(settings, folder, progress=progress, tensorboard=tensorboard, previous=None)


def resume_training(out: str | Path, *, progress: bool = True, tensorboard: str | Path | None = None
                    ) -> TrainReport:
    """Continue the interrupted run in `out` (process killed, machine restarted) from its last resume point, with
    the settings its run.json records; run.json's "resumed" lists where and when. On the same machine and thread
    count it ends with the policy bits the uninterrupted run would have.

    Raises:
      InvalidInputError: `out` holds no run, a complete one, or one without a resume point yet (it stopped
        before its first checkpoint: start it again).
      MissingExtraError: the rl extra is not installed.
    """
    from mjtraj.rl.resume import RESUME_DIR

    folder = Path(out)
    path = folder / "run.json"
    if not path.is_file():
        raise InvalidInputError(f"resume: {out} holds no training run (run.json); expected a folder written by "
                                f"mjtraj rl train")
    record = json.loads(path.read_text())
    if record.get("status") == "complete":
        raise InvalidInputError(f"resume: the run in {out} is complete; nothing to continue")
    if not (folder / RESUME_DIR / "state.pkl").is_file():
        raise InvalidInputError(f"resume: the run in {out} stopped before its first checkpoint, so there is no "
                                f"resume point; start it again in a new folder")
    return _run(TrainSettings(**record["settings"]), folder, progress=progress, tensorboard=tensorboard,
                previous=record)


def _run(settings: TrainSettings, folder: Path, *, progress: bool, tensorboard: str | Path | None,
         previous: dict[str, Any] | None) -> TrainReport:
    """`train`, or with `previous` (the interrupted run's record) `resume_training`."""
    require_sb3()
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.noise import NormalActionNoise
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from mjtraj.rl.resume import RESUME_DIR, load_state, restore_rngs, save_state
    from mjtraj.rl.sb3_env import SB3TrackVecEnv

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "checkpoints").mkdir(exist_ok=True)
    if settings.threads is not None:
        torch.set_num_threads(settings.threads)
    env_kwargs = settings.env_kwargs()
    env = resolve(**env_kwargs)
    fixed = fixed_normalization(env, CLIP_OBS) if settings.observation_scaling == "fixed" else None
    hyper = settings.hyperparameters()
    num_envs = int(settings.num_envs)  # type: ignore[arg-type]
    point = load_state(folder) if previous is not None else None
    record: dict[str, Any] = previous if previous is not None else {
        "format": RUN_FORMAT, "status": "running", "settings": dataclasses.asdict(settings), "env": env_kwargs,
        "hyperparameters": {"sb3_defaults_plus": hyper, "overrides": dict(settings.overrides)},
        "normalization": {"norm_obs": fixed is None, "norm_reward": True, "clip_obs": CLIP_OBS,
                          "observation_scaling": settings.observation_scaling},
        "streams": {"train": {"stream": TRAIN_STREAM, "gym_seeds": training_entropies(settings.seed, num_envs)},
                    "validation": {"stream": VALIDATION_STREAM,
                                   "count": 1 if env.fixed_task is not None else settings.validation}},
        "versions": rl_versions(), "torch_threads": torch.get_num_threads(),
        "started": datetime.now(timezone.utc).isoformat(timespec="seconds")}
    if point is not None:
        record.update(status="running")
        record.pop("error", None)
        record.setdefault("resumed", []).append({"timesteps": point.tracker["timesteps"],
                                                 "at": datetime.now(timezone.utc).isoformat(timespec="seconds")})
    _write_json(folder / "run.json", record)
    clock = time.perf_counter() - (0.0 if point is None else float(point.tracker["wall_s"]))
    started = False
    try:
        seen = None if fixed is None else spaces.Box(-CLIP_OBS, CLIP_OBS, (env.obs_size,), np.float32)
        algo = algorithm(settings.algo)
        if point is None:
            agent_env = SB3TrackVecEnv(num_envs, observe=fixed, observation_space=seen, **env_kwargs)
            monitor = VecMonitor(agent_env)
            venv = VecNormalize(monitor, norm_obs=fixed is None, clip_obs=CLIP_OBS)
            kwargs = copy.deepcopy(hyper)  # SB3 edits policy_kwargs in place; the record keeps what was given
            if settings.algo == "td3":
                n = env.n
                kwargs["action_noise"] = NormalActionNoise(np.zeros(n), np.full(n, TD3_NOISE_STD))
            try:
                model = algo(policy_class(settings.algo), venv, seed=settings.seed, device="cpu", verbose=0,
                             tensorboard_log=None if tensorboard is None else str(tensorboard), **kwargs)
            except (AssertionError, ValueError, TypeError) as e:  # SB3's own checks of its arguments
                raise InvalidInputError(f"hyperparameter: {settings.algo} refused {dict(settings.overrides)}: "
                                        f"{' '.join(str(e).split())}") from e
        else:  # the env chain as it was, then the algorithm on it, its _last_obs kept (force_reset=False)
            agent_env = point.env
            monitor = VecMonitor(agent_env)
            for name, value in point.monitor.items():
                setattr(monitor, name, value)
            venv = VecNormalize.load(str(point.folder / "normalizer.pkl"), monitor)
            venv.returns = point.returns
            model = algo.load(point.folder / "model.zip", env=venv, device="cpu", force_reset=False,
                              tensorboard_log=None if tensorboard is None else str(tensorboard))
            if (point.folder / "replay_buffer.pkl").is_file():
                model.load_replay_buffer(point.folder / "replay_buffer.pkl")
        started = True
        venv.gamma = model.gamma  # VecNormalize discounts rewards with the algorithm's gamma
        record["hyperparameters"]["resolved"] = _resolved(model)
        _write_json(folder / "run.json", record)
        references, weights, plants = validation_set(settings, env)
        pid = _summary(run_episodes(None, env, references, weights, plants))
        curve = (CurveFile(folder / "learning_curve.csv") if point is None else
                 CurveFile.resumed(folder / "learning_curve.csv", int(point.tracker["curve_rows"])))
        policy_record = {k: record[k] for k in ("format", "settings", "env", "hyperparameters", "normalization",
                                                "streams", "versions", "torch_threads")}

        def snapshot() -> Policy:
            return Policy(model, policy_record, fixed or Normalization.of(venv), int(model.num_timesteps))

        every_eval = max(num_envs, settings.steps // settings.evaluations)
        every_save = max(num_envs, settings.steps // settings.checkpoints)

        class Tracker(BaseCallback):  # type: ignore[misc]
            """Collects finished training episodes; validates, checkpoints and reports progress on schedule."""

            def _on_training_start(self) -> None:
                self.returns: list[float] = []
                self.diverged = 0
                self.episodes = 0
                self.next_eval = every_eval
                self.next_save = every_save
                self.next_resume = every_save
                self.curve_rows = 0
                self.bar = None
                self.best = float("inf")
                if point is not None:
                    for key in RESUMED:
                        setattr(self, key, point.tracker[key])
                if progress:
                    from tqdm import tqdm

                    self.bar = tqdm(total=settings.steps, initial=int(model.num_timesteps), unit="step",
                                    desc=f"train {settings.algo}", dynamic_ncols=True)
                if point is None:
                    self.validate()

            def _on_rollout_start(self) -> None:
                """Between two updates: the point a resumed run continues from (module mjtraj.rl.resume)."""
                t = int(model.num_timesteps)
                if self.next_resume <= t < settings.steps:
                    self.next_resume = t + every_save
                    state = {key: getattr(self, key) for key in RESUMED}
                    save_state(folder, model, agent_env, monitor, venv,
                               {**state, "timesteps": t, "wall_s": time.perf_counter() - clock,
                                "best_validation": record.get("best_validation")})

            def validate(self) -> dict[str, float]:
                policy = snapshot()
                scored = from_zip_policy(policy, source="validation")  # told where episodes start (recurrent)
                val = _summary(run_episodes(scored, env, references, weights, plants))
                if val["cost_mean"] < self.best and val["diverged"] == 0:  # NaN never wins
                    self.best = val["cost_mean"]
                    policy.save(folder / "best.zip")
                    record["best_validation"] = {"timesteps": policy.timesteps, **val}
                if tensorboard is not None:
                    for key in ("cost_mean", "cost_median", "rms_err_mean"):
                        model.logger.record(f"validation/{key}", val[key])
                    model.logger.record("validation/pid_cost_mean", pid["cost_mean"])
                    model.logger.dump(int(model.num_timesteps))
                self.curve_rows += 1
                curve.append({"timesteps": int(model.num_timesteps), "wall_s": time.perf_counter() - clock,
                              "episodes": self.episodes,
                              "train_return_mean": float(np.mean(self.returns)) if self.returns else float("nan"),
                              "train_diverged": self.diverged, "val_cost_mean": val["cost_mean"],
                              "val_cost_median": val["cost_median"], "val_rms_err_mean": val["rms_err_mean"],
                              "val_diverged": val["diverged"], "pid_cost_mean": pid["cost_mean"],
                              "pid_rms_err_mean": pid["rms_err_mean"]})
                self.returns, self.diverged = [], 0
                if self.bar is not None:
                    self.bar.set_postfix_str(f"val J {val['cost_mean']:.3g} (PID {pid['cost_mean']:.3g})")
                return val

            def _on_step(self) -> bool:
                for info in self.locals["infos"]:
                    if "episode" in info:
                        self.episodes += 1
                        self.returns.append(float(info["episode"]["r"]))
                        self.diverged += int(info.get("diverged", False))
                t = int(model.num_timesteps)
                if self.bar is not None:
                    self.bar.update(min(t, settings.steps) - self.bar.n)
                if t >= settings.steps:  # the last update is yet to come: the final policy is saved after it
                    return True
                if t >= self.next_save:
                    snapshot().save(folder / "checkpoints" / f"step_{t:09d}.zip")
                    self.next_save += every_save
                if t >= self.next_eval:
                    self.validate()
                    self.next_eval += every_eval
                return True

            def _on_training_end(self) -> None:
                if self.bar is not None:
                    self.bar.close()

        tracker = Tracker()
        if point is None:
            model.learn(total_timesteps=settings.steps, callback=tracker)
        else:
            record.pop("best_validation", None)  # the interrupted run may have validated past the resume point
            if point.tracker.get("best_validation") is not None:
                record["best_validation"] = point.tracker["best_validation"]
            restore_rngs(point.rng)
            model.learn(total_timesteps=settings.steps - int(model.num_timesteps), callback=tracker,
                        reset_num_timesteps=False)
        final = tracker.validate()
        policy_path = snapshot().save(folder / "policy.zip")
        plot_curve(folder / "learning_curve.csv", folder / "learning_curve.png", title=_title(settings))
    except BaseException as e:
        if not started and isinstance(e, InvalidInputError) and previous is None:  # refused: leave nothing behind
            (folder / "run.json").unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                (folder / "checkpoints").rmdir()
            raise
        record.update(status="failed", error=f"{type(e).__name__}: {e}", wall_s=time.perf_counter() - clock)
        _write_json(folder / "run.json", record)
        raise
    wall = time.perf_counter() - clock
    record.update(status="complete", timesteps=int(model.num_timesteps), wall_s=wall,
                  finished=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                  final_validation={"policy": final, "pid": pid})
    _write_json(folder / "run.json", record)
    shutil.rmtree(folder / RESUME_DIR, ignore_errors=True)
    return TrainReport(folder, policy_path, int(model.num_timesteps), wall, final)


def _title(settings: TrainSettings) -> str:
    scale = f" ({settings.residual_scale:g} N m)" if settings.action_mode == "residual" else ""
    plant = ", mismatch plants" if settings.plant_randomization != "none" else ""
    scaling = ", fixed observation scales" if settings.observation_scaling == "fixed" else ""
    return (f"{ALGORITHM_NAMES[settings.algo]} {settings.action_mode}{scale} on {settings.planner} references, "
            f"task={settings.task}{plant}{scaling}, seed {settings.seed}")


def plot_run(run: str | Path, *, formats: Sequence[str] = ("png",)) -> Path:
    """Redraw `run`/learning_curve.png from its CSV and run.json, in each of `formats` (png, pdf, svg); returns
    the first path."""
    run = Path(run)
    record, curve = run / "run.json", run / "learning_curve.csv"
    for path in (record, curve):
        if not path.is_file():
            raise InvalidInputError(f"run: {path} not found; expected a folder written by mjtraj rl train")
    recorded = json.loads(record.read_text())
    if recorded.get("format") == BATCHED_RUN:
        from mjtraj.rl.batched_policy import label
        from mjtraj.rl.curve import plot_batched_curve

        title = f"{label(recorded)}, seed {recorded['settings']['seed']}"
        return plot_batched_curve(curve, run / "learning_curve.png", title=title, formats=formats)
    settings = TrainSettings(**recorded["settings"])
    return plot_curve(curve, run / "learning_curve.png", title=_title(settings), formats=formats)


def _resolved(model: Any) -> dict[str, Any]:
    """The algorithm's effective hyperparameters (SB3 defaults included), as JSON-ready values."""
    names = ("learning_rate", "buffer_size", "learning_starts", "batch_size", "tau", "gamma", "train_freq",
             "gradient_steps", "ent_coef", "target_update_interval", "target_entropy", "policy_delay",
             "target_policy_noise", "target_noise_clip", "n_steps", "n_epochs", "gae_lambda", "clip_range",
             "clip_range_vf", "normalize_advantage", "vf_coef", "max_grad_norm", "use_sde")
    out: dict[str, Any] = {}
    for name in names:
        if hasattr(model, name):
            value = getattr(model, name)
            out[name] = value if isinstance(value, (int, float, str, bool, type(None))) else repr(value)
    out["policy"] = repr(model.policy).replace("\n", " ")
    return out


def _write_json(path: Path, body: dict[str, Any]) -> None:
    write_text_atomic(path, json.dumps(body, indent=1) + "\n")
