"""The learners' hyperparameter search: Optuna over the batched PPO recipe (mjtraj.rl.batched), as RL Zoo searches
SB3's, on the training and validation streams only (never an evaluation scenario).

Each trial trains the recipe with sampled settings for `steps` env steps and scores it by the best validation point's
worst family (its mean J_exec over the law alone's on the validation tasks, the rule that chooses `best.pt`; with a
settle window, +inf for a point that missed an episode the law came to rest on: `batched.selection_value`). TPE
samples the settings (seeded); the median pruner stops a trial whose validation point is worse than the median of
earlier trials' at the same point. The study lives in an SQLite file, so an interrupted search continues where it
stopped. The budget is stated in episodes, as the classical side's tuning is (`SearchReport.episodes`).
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
    """Training episodes the trials' sub-envs finished, over every trial."""
    validation_episodes: int
    """Validation episodes over every trial."""
    wall: float


def sampled(trial: Any) -> dict[str, Any]:
    """One trial's settings from SPACE."""
    out: dict[str, Any] = {}
    for name, (kind, values) in SPACE.items():
        if kind == "log":
            out[name] = trial.suggest_float(name, *values, log=True)
        else:
            out[name] = trial.suggest_categorical(name, list(values))
    return out


def search(base: BatchedSettings, out: str | Path, *, trials: int, progress: bool = True,
           on_trial: Callable[[dict[str, Any]], None] | None = None) -> SearchReport:
    """Run `trials` more trials of the search into `out` (study.db, trial_K/ per trial, trials.csv, best.json),
    each `base` with SPACE's names sampled; `base.steps` is each trial's budget and `base.seed` seeds both the
    trials' training and the sampler. `on_trial` gets each finished trial's record (number, state, value, settings);
    `progress` shows Optuna's bar over the trials.

    Raises:
      InvalidInputError: trials < 1.
    """
    import optuna

    positive_int("trials", trials)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    from mjtraj.rl.batched import selection_value, train_batched

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name=STUDY, storage=f"sqlite:///{out / 'study.db'}", load_if_exists=True,
                                direction="minimize", sampler=optuna.samplers.TPESampler(seed=base.seed),
                                pruner=optuna.pruners.MedianPruner(n_startup_trials=3, n_warmup_steps=0))
    clock = time.perf_counter()

    def objective(trial: Any) -> float:
        settings = dataclasses.replace(base, **sampled(trial))
        step = [0]

        def report(timesteps: int, value: float) -> bool:
            trial.report(value, step[0])
            step[0] += 1
            return bool(trial.should_prune())

        found = train_batched(settings, out / f"trial_{trial.number}", progress=False, on_validation=report)
        trial.set_user_attr("timesteps", found.timesteps)
        trial.set_user_attr("wall_s", found.wall)
        trial.set_user_attr("stopped", found.stopped)
        trial.set_user_attr("episodes", found.episodes)
        trial.set_user_attr("validation_points", step[0])
        if found.stopped == "pruned by the search":
            raise optuna.TrialPruned()
        return selection_value(found.best_point)

    def finished(study: Any, trial: Any) -> None:
        if on_trial is not None:
            on_trial({"number": trial.number, "state": trial.state.name, "value": trial.value,
                      "timesteps": trial.user_attrs.get("timesteps"), "settings": trial.params})
        _write(study, base, out)

    study.optimize(objective, n_trials=trials, callbacks=[finished], gc_after_trial=True,
                   show_progress_bar=progress)
    return _write(study, base, out, time.perf_counter() - clock)


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
        best = {**chosen.params, "value": chosen.value, "trial": chosen.number}
    record = {"study": STUDY, "base": {k: list(v) if isinstance(v, tuple) else v
                                       for k, v in dataclasses.asdict(base).items()},
              "space": {k: [kind, list(v)] for k, (kind, v) in SPACE.items()}, "trials": len(done),
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
    return {k: v for k, v in chosen.items() if k in SPACE}
