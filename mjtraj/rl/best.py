"""`baseline:best`: the shipped policy a reader should try first, chosen on validation scenarios by a stated rule.

The choice never looks at evaluation scenarios: every deployable baseline (nothing privileged reaches it at
evaluation) runs on `scenarios` validation scenarios of each family, drawn by the family's rules from the stream
[VALIDATION_SEED, VALIDATION_STREAM, family id, i] (four entropies: no sweep or rl eval scenario, which have three,
can share it), beside the protocol's reference method on the same scenarios: under protocol v2 (the default) every
episode goes on for its settle window and is scored by J_settle beside the adaptive law, under v1 it is scored by
J_exec beside cubic+PID (the rule of the baselines chosen before v2). BEST_RULES says how they are ranked;
`choose_best` writes the result, with every score and the protocol, into the baselines' BEST.json (v2: the choice
`baseline:best` names) or BEST_v1.json (v1's rule, which names nothing).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.core import window_steps, with_window
from mjtraj.envs import resolve
from mjtraj.files import write_text_atomic
from mjtraj.rl.adapters import load_any
from mjtraj.rl.baselines import BEST_FILE
from mjtraj.rl.episodes import run_episodes
from mjtraj.rl.evaluate import LAW_OF, LAW_SCENARIOS, acting_settings
from mjtraj.rl.extra import rl_versions
from mjtraj.rl.protocol import REFERENCES, SETTLE, check_protocol
from mjtraj.rl.streams import VALIDATION_STREAM
from mjtraj.study import FAMILIES, FAMILY_ID, FamilyScenario, draw_family, goal_checked, load_scenario

VALIDATION_SEED = 0
BEST_RULES = {
    "v1": ("among the deployable baselines, the one whose worst family ratio of mean J_exec to cubic+PID's is "
           "lowest, over the validation scenarios of nominal, aggressive and mismatch (a failed episode, diverged "
           "or short of the goal, makes its family's ratio +inf); ties by the mean of the three ratios"),
    "v2": ("among the deployable baselines, the one whose worst family ratio of mean J_settle to cubic+adaptive "
           "CT's is lowest, over the validation scenarios of nominal, aggressive and mismatch on which the adaptive "
           "law came to rest, every episode followed by protocol v2's settle window (a failed episode there, "
           "diverged or not at rest at the goal when its window ends, makes its family's ratio +inf); ties by the "
           "mean of the three ratios"),
}
"""How `choose_best` ranks the baselines under each protocol."""
BEST_FILES = {"v2": BEST_FILE, "v1": "BEST_v1.json"}
"""Where each protocol's choice is written: v2's is `baseline:best` (BEST_FILE); v1's, kept so that the rule of the
choices made before v2 can be run again, names no baseline."""


def validation_scenarios(family: str, count: int, model: Any, dt: float) -> list[FamilyScenario]:
    """`count` scenarios of `family` from the validation stream [VALIDATION_SEED, VALIDATION_STREAM, family id, i]."""
    out = []
    for i in range(count):
        rng = np.random.default_rng([VALIDATION_SEED, VALIDATION_STREAM, FAMILY_ID[family], i])
        task, plant = draw_family(rng, family, model, dt)
        out.append(FamilyScenario(family, i, task, plant, 0))
    return out


def _costs(policy: Any, settings: Any, draws: Sequence[FamilyScenario], window: int) -> np.ndarray:
    """Each scenario's score under `policy` (None: the controller of `settings` alone): J_exec, or with a settle
    window of `window` periods J_settle; +inf where it failed, as the protocol counts failures (diverged; with a
    window not at rest at the goal when it ends; without one, on the nominal family, short of the goal:
    GOAL_TOLERANCE)."""
    episodes = [with_window(d.task, settings.planner.plan(d.task, settings.model), window) for d in draws]
    refs, settles = [reference for reference, _ in episodes], [settle for _, settle in episodes]
    weights = [settings.weights(d.task) for d in draws]
    plants = [d.perturbation for d in draws] if draws[0].perturbation is not None else None
    outcomes = run_episodes(policy, settings, refs, weights, plants, settles)
    if draws[0].family == "nominal" and not window:
        outcomes = [goal_checked(o, float(np.max(np.abs(d.task.displacement)))) for o, d in zip(outcomes, draws,
                                                                                                strict=True)]
    return np.array([o.metrics["cost"] if o.status == "ok" else np.inf for o in outcomes])


def reference_settings(protocol: str) -> Any:
    """The random-task env settings of `protocol`'s reference method (REFERENCES): cubic + PID (v1) or cubic + the
    adaptive law from its shipped scenario (v2)."""
    law = LAW_OF[REFERENCES[protocol]]
    scenario = LAW_SCENARIOS[law]
    return resolve(task="random") if scenario is None else resolve(task="random", scenario=load_scenario(scenario))


def family_ratio(mine: NDArray[np.float64], theirs: NDArray[np.float64]) -> float:
    """A family's ratio of mean score to the reference's (each (K,), +inf where failed) over the scenarios the
    reference did not fail, +inf if the policy failed any of them: `rl eval`'s ratio of means
    (`mjtraj.rl.protocol_stats.ratio_of_means`), +inf also where the reference failed every scenario."""
    keep = np.isfinite(theirs)
    if not keep.any() or not np.all(np.isfinite(mine[keep])):
        return float(np.inf)
    return float(mine[keep].sum() / theirs[keep].sum())


def score_baselines(names: Sequence[str], *, scenarios: int = 100, protocol: str = "v2",
                    progress: Callable[[int, int], None] | None = None) -> dict[str, dict[str, float]]:
    """name -> family -> `family_ratio` of its scores to `protocol`'s reference method's on the validation scenarios:
    J_exec beside cubic+PID (v1), J_settle with the settle window beside the adaptive law (v2)."""
    check_protocol(protocol)
    reference = reference_settings(protocol)
    window = window_steps(SETTLE[protocol], reference.dt)
    draws = {f: validation_scenarios(f, scenarios, reference.model, reference.dt) for f in FAMILIES}
    theirs = {f: _costs(None, reference, d, window) for f, d in draws.items()}
    out: dict[str, dict[str, float]] = {}
    for k, name in enumerate(names):
        policy = load_any(f"baseline:{name}")
        settings = acting_settings(policy, protocol)
        out[name] = {}
        for f, d in draws.items():
            out[name][f] = family_ratio(_costs(policy, settings, d, window), theirs[f])
        if progress is not None:
            progress(k + 1, len(names))
    return out


def choose_best(folder: Path, names: Sequence[str], *, scenarios: int = 100, protocol: str = "v2", command: str = "",
                progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Score the deployable ones of `names` (shipped baselines in `folder`) under `protocol`, pick one by its rule
    (BEST_RULES) and write `folder`/BEST_FILES[protocol] (the choice, the protocol, the rule, every score, the
    command); the record written. Only v2's file is `baseline:best`'s."""
    check_protocol(protocol)
    deployable = [n for n in names if not load_any(f"baseline:{n}").sees_plant]
    scores = score_baselines(deployable, scenarios=scenarios, protocol=protocol, progress=progress)

    def key(name: str) -> tuple[float, float]:
        ratios = list(scores[name].values())
        return max(ratios), float(np.mean(ratios))

    best = min(deployable, key=key)
    record = {"best": best, "protocol": protocol, "rule": BEST_RULES[protocol], "scenarios_per_family": scenarios,
              "stream": f"[{VALIDATION_SEED}, {VALIDATION_STREAM}, family id, i]", "command": command,
              "scores": {n: {f: (r if np.isfinite(r) else "inf") for f, r in s.items()} for n, s in scores.items()},
              "versions": rl_versions()}
    write_text_atomic(folder / BEST_FILES[protocol], json.dumps(record, indent=1) + "\n")
    return record
