"""The learners' hyperparameter search: Optuna over the batched PPO recipe (mjtraj.rl.batched), as RL Zoo searches
SB3's, and over imitation (mjtraj.rl.distill) and imitation then PPO, on the training and validation streams only
(never an evaluation scenario).

Each trial trains one learner with sampled settings for `steps` env steps and scores it by the best validation
point's worst family (its mean J_exec over the law alone's on the validation tasks, the rule that chooses `best.pt`;
with a settle window, plus a million for each episode it missed where the law came to rest: `batched.selection_value`,
which ranks points as the rule that picks best.pt does).
The learners (`LEARNERS`): ppo, the batched PPO residual (SPACE); distill, behaviour cloning and DAgger of `mpc`
(DISTILL_SPACE), its rounds of `DISTILL_STEPS` steps on every sub-env filling the budget, validated after each; both,
a distillation on half the budget, then PPO started from its best round (`BatchedSettings.init`; FINE_TUNE_SPACE) on
the other half, the trial's value the better of the two. With several learners the learner is sampled too. TPE
samples the settings (seeded); the median pruner stops a trial whose validation point is worse than the median of
earlier trials' at the same share of their budget. The study lives in an SQLite file, so an interrupted search
continues where it stopped. The budget is stated in env steps and episodes, as the classical side's tuning is in
episodes (`SearchReport`).
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mjtraj.checks import positive_int
from mjtraj.exceptions import InvalidInputError
from mjtraj.files import write_text_atomic
from mjtraj.rl.batched_policy import BatchedSettings

SPACE: dict[str, tuple[str, Any]] = {
    "initial_std": ("log", (0.02, 0.3)),
    "residual_scale": ("choice", (2.0, 4.0, 6.0, 10.0)),
    "learning_rate": ("log", (3e-5, 1e-3)),
    "rollouts": ("choice", (16, 32, 64)),
    "epochs": ("choice", (3, 5, 10)),
    "discount": ("choice", (0.95, 0.98, 0.99, 0.995)),
    "preview": ("choice", (0, 5, 10)),
    "observe_control": ("choice", (False, True)),
}
"""What a trial samples (kind, range or choices): log-uniform, or one of the choices. The rest of BatchedSettings
keeps the recipe's defaults or the search's own settings (steps, num_envs, controller, families, seed)."""

DISTILL_SPACE: dict[str, tuple[str, Any]] = {
    "distill_action_mode": ("choice", ("torque", "residual")),
    "distill_residual_scale": ("choice", (6.0, 20.0, 60.0)),
    "distill_output": ("choice", ("linear", "cubic")),
    "distill_preview": ("choice", (10, 25, 50)),
    "distill_observe_control": ("choice", (False, True)),
    "distill_history": ("choice", (0, 1)),
    "distill_mixing": ("choice", (0.0, 0.5, 0.8, 0.9)),
    "distill_balance": ("choice", ("none", "family")),
    "distill_epochs": ("choice", (20, 40, 80)),
    "distill_learning_rate": ("log", (3e-4, 3e-3)),
}
"""What a distillation trial samples (DistillSettings' names after 'distill_'; residual_scale only in residual mode,
output only where PPO does not follow). The rest: the teacher mpc, the search's controller, families, sub-envs, seed,
validation and settle window, the relative preview frame, the task observed, 256x3 tanh layers, the annealed learning
rate."""

FINE_TUNE_SPACE: dict[str, tuple[str, Any]] = {
    "tune_learning_rate": ("log", (1e-6, 1e-4)),
    "tune_initial_std": ("log", (1e-4, 1e-2)),
}
"""What the PPO half of a 'both' trial samples (BatchedSettings' names after 'tune_'); the rest is the recipe's, its
observation, action and network the distilled policy's."""

LEARNERS = ("ppo", "distill", "both")
"""What a trial may train (`search`'s learners)."""

DISTILL_STEPS = 200
"""Steps of every sub-env per distillation round in a trial."""

STUDY = "mjtraj-batched-ppo"
"""The Optuna study's name inside its SQLite file."""


@dataclass
class SearchReport:
    """What a search wrote and found."""

    out: Path
    trials: int
    """Trials finished (complete or pruned) in the study."""
    best: dict[str, Any]
    """The best trial's settings (SPACE's names) and 'value', its best validation worst-family ratio."""
    episodes: int
    """Training episodes the trials' PPO sub-envs finished, over every trial (a distillation's budget is its labelled
    states: best.json's training_steps counts both)."""
    validation_episodes: int
    """Validation episodes over every trial."""
    wall: float


def sampled(trial: Any, space: dict[str, tuple[str, Any]] | None = None, skip: tuple[str, ...] = ()
            ) -> dict[str, Any]:
    """One trial's settings from `space` (SPACE by default), but the names in `skip`."""
    out: dict[str, Any] = {}
    for name, (kind, values) in (SPACE if space is None else space).items():
        if name in skip:
            continue
        if kind == "log":
            out[name] = trial.suggest_float(name, *values, log=True)
        else:
            out[name] = trial.suggest_categorical(name, list(values))
    return out


def distill_settings(base: BatchedSettings, params: dict[str, Any], steps: int) -> Any:
    """The DistillSettings of a trial: `params` (DISTILL_SPACE's names) on the search's `base`, as many rounds of
    DISTILL_STEPS steps on every sub-env as `steps` env steps hold (at least one)."""
    from mjtraj.rl.distill import DistillSettings

    chosen = {k.removeprefix("distill_"): v for k, v in params.items() if k.startswith("distill_")}
    return DistillSettings(teacher="mpc", controller=base.controller, families=base.families, num_envs=base.num_envs,
                           rounds=max(1, steps // (base.num_envs * DISTILL_STEPS)), steps=DISTILL_STEPS,
                           preview_frame="relative", observe_task=True, decay=True, seed=base.seed,
                           threads=base.threads, validation=base.validation, settle=base.settle, **chosen)


def search(base: BatchedSettings, out: str | Path, *, trials: int, progress: bool = True,
           on_trial: Callable[[dict[str, Any]], None] | None = None,
           learners: tuple[str, ...] = ("ppo",)) -> SearchReport:
    """Run `trials` more trials of the search into `out` (study.db, trial_K/ per trial, trials.csv, best.json),
    each training one of `learners` (sampled when there are several) with its space's names sampled on `base`;
    `base.steps` is each trial's budget and `base.seed` seeds both the trials' training and the sampler. `on_trial`
    gets each finished trial's record (number, state, value, settings); `progress` shows Optuna's bar over the trials.

    Raises:
      InvalidInputError: trials < 1, or learners not among LEARNERS.
    """
    import optuna

    from mjtraj.checks import choice

    positive_int("trials", trials)
    if not learners:
        raise InvalidInputError("learners: expected at least one of ppo, distill, both, got none")
    for learner in learners:
        choice("learners", learner, LEARNERS)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name=STUDY, storage=f"sqlite:///{out / 'study.db'}", load_if_exists=True,
                                direction="minimize", sampler=optuna.samplers.TPESampler(seed=base.seed),
                                pruner=optuna.pruners.MedianPruner(n_startup_trials=3, n_warmup_steps=0))
    clock = time.perf_counter()

    def objective(trial: Any) -> float:
        learner = learners[0] if len(learners) == 1 else trial.suggest_categorical("learner", list(learners))
        trial.set_user_attr("learner", learner)
        found = _trial(trial, learner, base, out / f"trial_{trial.number}")
        for name, value in found.items():
            trial.set_user_attr(name, value)
        if found["stopped"] == "pruned by the search":
            raise optuna.TrialPruned()
        return float(found["value"])

    def finished(study: Any, trial: Any) -> None:
        if on_trial is not None:
            on_trial({"number": trial.number, "state": trial.state.name, "value": trial.value,
                      "timesteps": trial.user_attrs.get("timesteps"), "settings": trial.params})
        _write(study, base, out)

    study.optimize(objective, n_trials=trials, callbacks=[finished], gc_after_trial=True,
                   show_progress_bar=progress)
    return _write(study, base, out, time.perf_counter() - clock)


def _trial(trial: Any, learner: str, base: BatchedSettings, folder: Path) -> dict[str, Any]:
    """Train `learner` for one trial into `folder` (a distillation's resume.pt, its data, removed once done), its
    validation points reported to the trial's pruner at their share of the budget (per mille); what the trial
    records: timesteps, episodes, validation_points, wall_s, stopped,
    value (the best point's `selection_value`, the better stage's for 'both') and policy (its best.pt)."""
    from mjtraj.rl.batched import selection_value, train_batched
    from mjtraj.rl.distill import distill

    points, spent = [0], [0]

    def report(timesteps: int, value: float) -> bool:
        trial.report(value, (1000 * (spent[0] + timesteps)) // base.steps)
        points[0] += 1
        return bool(trial.should_prune())

    if learner == "ppo":
        found = train_batched(dataclasses.replace(base, **sampled(trial)), folder, progress=False,
                              on_validation=report)
        return {"timesteps": found.timesteps, "episodes": found.episodes, "validation_points": points[0],
                "wall_s": found.wall, "stopped": found.stopped, "value": selection_value(found.best_point),
                "policy": str(found.best)}
    mode = trial.suggest_categorical("distill_action_mode", list(DISTILL_SPACE["distill_action_mode"][1]))
    skip = ("distill_action_mode", *(("distill_residual_scale",) if mode == "torque" else ()),
            *(("distill_output",) if learner == "both" else ()))
    params = {"distill_action_mode": mode, **sampled(trial, DISTILL_SPACE, skip)}
    budget = base.steps // 2 if learner == "both" else base.steps
    clock = time.perf_counter()
    taught = distill(distill_settings(base, params, budget), folder / "distill" if learner == "both" else folder,
                     progress=False, on_validation=report)
    (taught.out / "resume.pt").unlink()  # its data: a trial is not resumed, and a few hundred MB each
    value = selection_value(taught.best_point)
    result: dict[str, Any] = {"timesteps": int(taught.rounds[-1]["samples"]), "episodes": 0,
                              "validation_points": points[0], "wall_s": time.perf_counter() - clock,
                              "stopped": taught.stopped, "value": value, "policy": str(taught.best)}
    if learner == "distill" or taught.stopped:
        return result
    tuned = {k.removeprefix("tune_"): v for k, v in sampled(trial, FINE_TUNE_SPACE).items()}
    spent[0] = result["timesteps"]
    from mjtraj.rl.batched import init_defaults

    found = train_batched(dataclasses.replace(base, **init_defaults(taught.best), **tuned, init=str(taught.best),
                                              steps=max(1, base.steps - spent[0])),
                          folder / "ppo", progress=False, on_validation=report)
    better = selection_value(found.best_point) < value
    return {"timesteps": spent[0] + found.timesteps, "episodes": found.episodes, "validation_points": points[0],
            "wall_s": result["wall_s"] + found.wall, "stopped": found.stopped,
            "value": min(value, selection_value(found.best_point)),
            "policy": str(found.best if better else taught.best)}


def _write(study: Any, base: BatchedSettings, out: Path, wall: float = float("nan")) -> SearchReport:
    """trials.csv (every trial) and best.json (the best trial's settings, its value, the budget) from the study."""
    import optuna

    done = [t for t in study.trials if t.state in (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)]
    frame = study.trials_dataframe(attrs=("number", "state", "value", "params", "user_attrs", "duration"))
    write_text_atomic(out / "trials.csv", frame.to_csv(index=False))
    steps = sum(int(t.user_attrs.get("timesteps", 0)) for t in done)
    episodes = sum(int(t.user_attrs.get("episodes", 0)) for t in done)
    validation = sum(int(t.user_attrs.get("validation_points", 0)) for t in done) * base.validation * len(base.families)
    complete = [t for t in done if t.state == optuna.trial.TrialState.COMPLETE]
    best: dict[str, Any] = {}
    if complete:
        chosen = min(complete, key=lambda t: t.value)
        best = {**chosen.params, "value": chosen.value, "trial": chosen.number,
                "learner": chosen.user_attrs.get("learner", "ppo"), "policy": chosen.user_attrs.get("policy", "")}
    record = {"study": STUDY, "base": {k: list(v) if isinstance(v, tuple) else v
                                       for k, v in dataclasses.asdict(base).items()},
              "space": {k: [kind, list(v)] for k, (kind, v) in {**SPACE, **DISTILL_SPACE, **FINE_TUNE_SPACE}.items()},
              "trials": len(done),
              "best": best, "budget": {"training_steps": steps, "training_episodes": episodes,
                                       "validation_episodes": validation}}
    write_text_atomic(out / "best.json", json.dumps(record, indent=1) + "\n")
    return SearchReport(out, len(done), best, episodes, validation, wall)


def best_settings(path: str | Path) -> dict[str, Any]:
    """The best trial's settings of a search's best.json, as BatchedSettings arguments.

    Raises:
      InvalidInputError: not a search's best.json, or it has no complete trial.
    """
    try:
        record = json.loads(Path(path).read_text())
        chosen = dict(record["best"])
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InvalidInputError(f"search: {path} is not the best.json of mjtraj rl search ({e})") from e
    if not chosen:
        raise InvalidInputError(f"search: {path} has no complete trial yet")
    if chosen.get("learner", "ppo") != "ppo":
        raise InvalidInputError(f"search: the best trial of {path} is not PPO's but {chosen['learner']}'s; its policy "
                                f"is {chosen.get('policy', '')} (mjtraj rl eval --policy scores it)")
    return {k: v for k, v in chosen.items() if k in SPACE}
