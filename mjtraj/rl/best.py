"""`baseline:best`: the shipped policy a reader should try first, chosen on validation scenarios by a stated rule.

The choice never looks at evaluation scenarios: every deployable baseline (nothing privileged reaches it at
evaluation) runs on `scenarios` validation scenarios of each family, drawn by the family's rules from the stream
[VALIDATION_SEED, VALIDATION_STREAM, family id, i] (four entropies: no sweep or rl eval scenario, which have three,
can share it), beside cubic+PID on the same scenarios. BEST_RULE says how they are ranked; `choose_best` writes
the result, with every score, into the baselines' BEST.json.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mjtraj.envs import resolve
from mjtraj.files import write_text_atomic
from mjtraj.rl.adapters import load_any
from mjtraj.rl.baselines import BEST_FILE
from mjtraj.rl.episodes import run_episodes
from mjtraj.rl.extra import rl_versions
from mjtraj.rl.streams import VALIDATION_STREAM
from mjtraj.study import FAMILIES, FAMILY_ID, FamilyScenario, draw_family, goal_checked

VALIDATION_SEED = 0
BEST_RULE = ("among the deployable baselines, the one whose worst family ratio of mean J_exec to cubic+PID's is "
             "lowest, over the validation scenarios of nominal, aggressive and mismatch (a failed episode, diverged "
             "or short of the goal, makes its family's ratio +inf); ties by the mean of the three ratios")


def validation_scenarios(family: str, count: int, model: Any, dt: float) -> list[FamilyScenario]:
    """`count` scenarios of `family` from the validation stream [VALIDATION_SEED, VALIDATION_STREAM, family id, i]."""
    out = []
    for i in range(count):
        rng = np.random.default_rng([VALIDATION_SEED, VALIDATION_STREAM, FAMILY_ID[family], i])
        task, plant = draw_family(rng, family, model, dt)
        out.append(FamilyScenario(family, i, task, plant, 0))
    return out


def _costs(policy: Any, settings: Any, draws: Sequence[FamilyScenario]) -> np.ndarray:
    """Each scenario's J_exec under `policy` (None: the controller of `settings` alone); +inf where it failed, as
    the protocol counts failures (on the nominal family, ending short of the goal is one: GOAL_TOLERANCE)."""
    refs = [settings.planner.plan(d.task, settings.model) for d in draws]
    weights = [settings.weights(d.task) for d in draws]
    plants = [d.perturbation for d in draws] if draws[0].perturbation is not None else None
    outcomes = run_episodes(policy, settings, refs, weights, plants)
    if draws[0].family == "nominal":
        outcomes = [goal_checked(o, float(np.max(np.abs(d.task.displacement)))) for o, d in zip(outcomes, draws,
                                                                                                strict=True)]
    return np.array([o.metrics["cost"] if o.status == "ok" else np.inf for o in outcomes])


def score_baselines(names: Sequence[str], *, scenarios: int = 100,
                    progress: Callable[[int, int], None] | None = None) -> dict[str, dict[str, float]]:
    """name -> family -> ratio of mean J_exec to cubic+PID's on the validation scenarios (+inf on a failure)."""
    pid = resolve(task="random")
    draws = {f: validation_scenarios(f, scenarios, pid.model, pid.dt) for f in FAMILIES}
    reference = {f: _costs(None, pid, d) for f, d in draws.items()}
    out: dict[str, dict[str, float]] = {}
    for k, name in enumerate(names):
        policy = load_any(f"baseline:{name}")
        settings = policy.settings()
        out[name] = {}
        for f, d in draws.items():
            costs = _costs(policy, settings, d)
            out[name][f] = float(np.inf) if not np.all(np.isfinite(costs)) else float(costs.mean()
                                                                                          / reference[f].mean())
        if progress is not None:
            progress(k + 1, len(names))
    return out


def choose_best(folder: Path, names: Sequence[str], *, scenarios: int = 100, command: str = "",
                progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Score the deployable ones of `names` (shipped baselines in `folder`), pick one by BEST_RULE and write
    `folder`/BEST.json (the choice, the rule, every score, the command); the record written."""
    deployable = [n for n in names if not load_any(f"baseline:{n}").sees_plant]
    scores = score_baselines(deployable, scenarios=scenarios, progress=progress)

    def key(name: str) -> tuple[float, float]:
        ratios = list(scores[name].values())
        return max(ratios), float(np.mean(ratios))

    best = min(deployable, key=key)
    record = {"best": best, "rule": BEST_RULE, "scenarios_per_family": scenarios,
              "stream": f"[{VALIDATION_SEED}, {VALIDATION_STREAM}, family id, i]", "command": command,
              "scores": {n: {f: (r if np.isfinite(r) else "inf") for f, r in s.items()} for n, s in scores.items()},
              "versions": rl_versions()}
    write_text_atomic(folder / BEST_FILE, json.dumps(record, indent=1) + "\n")
    return record
