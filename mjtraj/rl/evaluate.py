"""`mjtraj rl eval`: policies and planners on the same held-out sweep scenarios, one table.

The scenarios are a sweep family's (mjtraj.study.families: seed streams [seed, FAMILY_ID, i]), which no training run
draws from (checked against each policy's recorded training and validation streams). The planners' rows are the
sweep's own (`run_unit`); each policy tracks its planner's reference for the same scenario on the same plant
(perturbed per scenario in `mismatch`), with the same controller and saturation, and is scored by the same
metrics and weights. Rows are written in the sweep's format plus the columns `controller` and `policy*`.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mjtraj.checks import choice, positive_int
from mjtraj.core import LoopConfig
from mjtraj.exceptions import InvalidInputError
from mjtraj.files import write_text_atomic
from mjtraj.rl.episodes import PolicyActor
from mjtraj.rl.extra import require_sb3
from mjtraj.rl.policy import Policy, load_policy
from mjtraj.rl.streams import VALIDATION_STREAM, check_seed, family_entropies, shared_streams
from mjtraj.study import (
    FAMILIES,
    PAYLOAD_MASS,
    SWEPT,
    ActorSpec,
    Condition,
    SweepData,
    SweepSettings,
    columns,
    csv_text,
    cvar,
    numeric,
    paired_ratio,
    ratio_of_means,
    run_unit,
)

POLICY_COLUMNS = ("method", "policy", "policy_sha256", "policy_timesteps")


@dataclass
class EvalReport:
    """The rows file, the Markdown file, the per-policy table's text and the over-seeds summary's."""

    csv: Path
    markdown: Path
    table: str
    seeds: str = ""
    payload: str = ""
    """The by-payload table ('' unless the scenarios' plants carry payloads: the mismatch family)."""


def check_held_out(policy: Policy, family: str, seed: int, scenarios: int) -> None:
    """InvalidInputError if any evaluation scenario's stream is one the policy trained or validated on."""
    streams = policy.record["streams"]
    train_seed = int(policy.record["settings"]["seed"])
    used = list(streams["train"]["gym_seeds"]) + [[train_seed, VALIDATION_STREAM, i]
                                                   for i in range(int(streams["validation"]["count"]))]
    shared = shared_streams(used, family_entropies(family, seed, range(scenarios)))
    if shared:
        raise InvalidInputError(f"seed: {len(shared)} of the {family} scenarios under seed {seed} share a seed stream "
                                f"with {policy.path}'s training; choose another seed")


def _labels(policies: Sequence[Policy]) -> list[str]:
    """Each policy's table label: its configuration's, and where labels repeat, its run folder and (unless it is
    the final policy.zip) the file's stem; the position in the list if even that repeats."""
    labels = [p.label for p in policies]
    where = [("" if p.path is None else p.path.parent.name if p.path.stem == "policy" else
              f"{p.path.parent.name}/{p.path.stem}") for p in policies]
    out = [f"{label} [{w}]" if labels.count(label) > 1 else label for label, w in zip(labels, where, strict=True)]
    return [f"{label} #{k + 1}" if out.count(label) > 1 else label for k, label in enumerate(out)]


def _settings(policies: Sequence[Policy], family: str, scenarios: int, seed: int, planners: Sequence[str],
              batch: int) -> SweepSettings:
    """The sweep the planners' rows come from: the policies' controller variant, every planner they track."""
    loops = {(p.settings().loop.ff_accel, p.settings().loop.gravity_comp) for p in policies}
    if len(loops) > 1:
        raise InvalidInputError(f"policy: the policies were trained with different controllers (ff_accel, "
                                f"gravity_comp): {sorted(loops)}; evaluate them separately")
    ((ff, gc),) = loops
    names = tuple(dict.fromkeys([*planners, *(p.env_kwargs["planner"] for p in policies)]))
    settings = SweepSettings(families=(family,), scenarios=scenarios, seed=seed, planners=names, ff_accel=(ff,),
                             gravity_comp=(gc,), batch=batch)
    for p in policies:  # every other controller setting must be the base scenario's
        mine, base = p.settings().loop, settings.base.loop
        for f in dataclasses.fields(LoopConfig):
            if f.name not in SWEPT and not _same(getattr(mine, f.name), getattr(base, f.name)):
                raise InvalidInputError(f"policy: {p.path} was trained with a different controller ({f.name}) than "
                                        f"the sweep's base scenario")
    return settings


def _same(a: Any, b: Any) -> bool:
    if hasattr(a, "kp"):
        return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("kp", "ki", "kd"))
    return bool(a == b)


def actor_specs(policies: Sequence[Policy], labels: Sequence[str]) -> list[ActorSpec]:
    """Each policy as an actor of the sweep's units: its label, the planner it tracks, its row columns."""
    return [ActorSpec(label, p.env_kwargs["planner"], PolicyActor(p.act, p.settings()),
                      {"method": label, "policy": str(p.path), "policy_sha256": p.sha256[:16],
                       "policy_timesteps": p.timesteps})
            for p, label in zip(policies, labels, strict=True)]


def evaluate(policies: Sequence[str | Path], *, family: str = "nominal", scenarios: int = 200, seed: int = 0,
             planners: Sequence[str] = ("optimal", "cubic", "quintic", "trapezoidal"), out: str | Path = "rl_eval",
             batch: int = 250) -> EvalReport:
    """Evaluate `policies` (zips from `mjtraj rl train`) and the `planners` with PID alone on scenarios
    0..scenarios-1 of `family` under `seed`; writes eval_<family>.csv and EVAL_<family>.md into `out`.

    Raises:
      InvalidInputError: bad arguments, an unreadable or mismatched policy file, or scenarios that are not
        held out from a policy's training streams.
      MissingExtraError: the rl extra is not installed.
    """
    require_sb3()
    choice("family", family, FAMILIES)
    positive_int("scenarios", scenarios)
    check_seed("seed", seed)
    if not policies:
        raise InvalidInputError("policy: expected at least one policy file, got none")
    loaded = [load_policy(p) for p in policies]
    for p in loaded:
        check_held_out(p, family, seed, scenarios)
    labels = _labels(loaded)
    settings = _settings(loaded, family, scenarios, seed, planners, batch)
    rows: list[dict[str, Any]] = []
    actors = actor_specs(loaded, labels)
    names = {spec.label for spec in actors}
    for unit in settings.units():
        for row in run_unit(settings, unit, actors=actors).rows:
            rows.append(row if row["planner"] in names else
                        {**row, "method": f"{row['planner']}+PID", "policy": "", "policy_sha256": "",
                         "policy_timesteps": ""})
    out = Path(out)
    csv_path = out / f"eval_{family}.csv"
    write_text_atomic(csv_path, csv_text([*columns(settings), *POLICY_COLUMNS], rows))
    reference = loaded[0].env_kwargs["planner"]
    data = SweepData([csv_path])
    table = comparison_table(data, reference=reference)
    groups = configurations(loaded, labels)
    seeds = seed_table(data, groups, reference=reference)
    payload = payload_table(data, groups, reference=reference)
    md_path = out / f"EVAL_{family}.md"
    by_payload = [PAYLOAD_TITLE, "", payload, ""] if payload else []
    write_text_atomic(md_path, "\n".join([*_header(loaded, labels, family, scenarios, seed, policies,
                                                   settings.planners), table, "",
                                          "Over seeds (each configuration's policies; mean [min, max] over them):",
                                          "", seeds, "", *by_payload]))
    return EvalReport(csv_path, md_path, table, seeds, payload)


def configurations(policies: Sequence[Policy], labels: Sequence[str]) -> dict[str, list[str]]:
    """The policies' table labels grouped by configuration: everything of the training run but its seed and
    threads, and which of its saved policies it is (policy, best or a step checkpoint, by file name); the key is
    the configuration's label (with the file's stem unless it is the final policy), followed, where configurations
    share a label, by the settings in which they differ (such as [steps=200000])."""
    facts: dict[str, tuple[str, dict[str, Any]]] = {}
    groups: dict[str, list[str]] = {}
    for policy, label in zip(policies, labels, strict=True):
        settings = {k: v for k, v in policy.record["settings"].items() if k not in ("seed", "threads")}
        kind = policy.path.stem if policy.path is not None else "policy"
        kind = "step" if kind.startswith("step_") else kind
        key = json.dumps([settings, policy.env_kwargs, kind], sort_keys=True, default=str)
        if key not in facts:
            name = policy.label if kind == "policy" else f"{policy.label} {kind}"
            facts[key] = name, {**policy.env_kwargs, **settings}
        groups.setdefault(key, []).append(label)
    names: dict[str, str] = {}
    for key, (name, mine) in facts.items():
        twins = [other for twin, other in facts.values() if twin == name]
        if len(twins) > 1:
            differ = sorted(k for k in set().union(*twins)
                            if len({json.dumps(t.get(k), sort_keys=True, default=str) for t in twins}) > 1)
            name = f"{name} [{', '.join(f'{k}={mine.get(k)}' for k in differ)}]"
        names[key] = name
    return {names[key]: members for key, members in groups.items()}


def win_share(cost: np.ndarray, ref: np.ndarray) -> float:
    """Percentage of the scenarios where both are finite in which `cost` is strictly below `ref`; NaN if none."""
    both = np.isfinite(cost) & np.isfinite(ref)
    return float(100 * np.mean(cost[both] < ref[both])) if both.any() else float("nan")


def seed_table(data: SweepData, groups: dict[str, list[str]], *, reference: str) -> str:
    """Markdown: per configuration, its policies' J_exec / reference+PID (paired by scenario, ratio of means) and
    share of scenarios won, as the mean over its policies (seeds) with their min and max, and the seeds' 95 %
    bootstrap intervals' hull (`data`: the evaluation file's rows)."""
    (condition,) = data.conditions
    ref = data.values(condition, reference, "cost")
    lines = [f"| configuration | seeds | J_exec / {reference}+PID, mean [min, max] | 95 % CIs from .. to | beats "
             f"{reference}+PID in, mean [min, max] |", "|---|---|---|---|---|"]
    for name, members in groups.items():
        ratios, lows, highs, wins = [], [], [], []
        for label in members:
            cost = data.values(condition, label, "cost")
            r = paired_ratio(cost, ref)
            ratios.append(r.ratio)
            lows.append(r.low)
            highs.append(r.high)
            wins.append(win_share(cost, ref))
        lines.append(f"| {name} | {len(members)} | {np.mean(ratios):.3g} [{min(ratios):.3g}, {max(ratios):.3g}] | "
                     f"{min(lows):.3g} .. {max(highs):.3g} | {np.mean(wins):.0f} % [{min(wins):.0f}, "
                     f"{max(wins):.0f}] |")
    return "\n".join(lines)


PAYLOAD_BINS = 5
"""Equal-width bins of the mismatch family's payload range (PAYLOAD_MASS) in the by-payload table."""
PAYLOAD_TITLE = ("By payload (each configuration's J_exec / reference+PID, ratio of means over the bin's scenarios, "
                 "and share of them won; both the mean over its seeds):")


def payload_table(data: SweepData, groups: dict[str, list[str]], *, reference: str) -> str:
    """Markdown: the over-seeds summary of `seed_table` within bins of the scenarios' payload mass; '' when no
    scenario carries a payload (a family without plant mismatch)."""
    (condition,) = data.conditions
    by_scenario = {int(r["scenario"]): numeric(r.get("payload_kg", "")) for r in data.rows
                   if r["planner"] == reference}
    payload = np.array([by_scenario[k] for k in sorted(by_scenario)])
    if not np.any(payload > 0):
        return ""
    edges = np.linspace(*PAYLOAD_MASS, PAYLOAD_BINS + 1)
    bins = np.clip(np.searchsorted(edges, payload, side="right") - 1, 0, PAYLOAD_BINS - 1)
    ref = data.values(condition, reference, "cost")
    head = " | ".join(f"{lo:g}-{hi:g} kg ({np.sum(bins == b)})" for b, (lo, hi) in
                      enumerate(zip(edges[:-1], edges[1:], strict=True)))
    lines = [f"| configuration | {head} |", "|---|" + "---|" * PAYLOAD_BINS]
    for name, members in groups.items():
        costs = [data.values(condition, label, "cost") for label in members]
        cells = []
        for b in range(PAYLOAD_BINS):
            inside = bins == b
            ratios = [ratio_of_means(cost[inside], ref[inside]) for cost in costs]
            wins = [win_share(cost[inside], ref[inside]) for cost in costs]
            cells.append(f"{np.mean(ratios):.3g}, {np.mean(wins):.0f} %")
        lines.append(f"| {name} | {' | '.join(cells)} |")
    return "\n".join(lines)


def comparison_table(data: SweepData, *, reference: str) -> str:
    """The Markdown table of an evaluation file's rows: every controller against `reference` + PID, paired by
    scenario, with 95 % bootstrap intervals (mjtraj.study.stats)."""
    (condition,) = data.conditions
    by_planner = {r["planner"]: r["method"] for r in data.rows}
    lines = [f"| controller | ok | failed | J_exec mean | J_exec median | CVaR90 J_exec | J_exec / {reference}+PID "
             f"[95 % CI] | beats {reference}+PID in | RMS err mean (rad) | RMS dtau mean (N m) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    ref = data.values(condition, reference, "cost")
    for planner in data.planners:
        lines.append(_table_row(data, condition, planner, by_planner[planner], None if planner == reference else ref))
    return "\n".join(lines)


def _table_row(data: SweepData, c: Condition, planner: str, name: str, ref: np.ndarray | None) -> str:
    """One controller's row; `ref` the reference's J_exec per scenario (None: this is the reference)."""
    cost = data.values(c, planner, "cost")
    ok = int(np.sum(np.isfinite(cost)))
    failed = data.failures(c, planner)
    if not ok:
        return f"| {name} | 0 | {failed} | - | - | - | - | - | - | - |"
    err, dtau = data.values(c, planner, "rms_err"), data.values(c, planner, "rms_dtau")
    if ref is None:
        ratio, wins = "1 (reference)", "-"
    else:
        r = paired_ratio(cost, ref)
        ratio = f"{r.ratio:.3g} [{r.low:.3g}, {r.high:.3g}]"
        share = win_share(cost, ref)
        wins = "-" if np.isnan(share) else f"{share:.0f} %"
    return (f"| {name} | {ok} | {failed} | {np.nanmean(cost):.4g} | {np.nanmedian(cost):.4g} | {cvar(cost, 0.9):.4g} | "
            f"{ratio} | {wins} | {np.nanmean(err):.3g} | {np.nanmean(dtau):.3g} |")


def _header(policies: Sequence[Policy], labels: Sequence[str], family: str, scenarios: int, seed: int,
            paths: Sequence[str | Path], planners: Sequence[str]) -> list[str]:
    lines = [f"# Policies and planners on held-out {family} scenarios", "",
             f"Regenerate: `mjtraj rl eval {' '.join(f'--policy {p}' for p in paths)} --family {family} "
             f"--scenarios {scenarios} --seed {seed} --planners {','.join(planners)}`.", "",
             f"Scenarios 0..{scenarios - 1} of the {family} family under seed {seed} (mjtraj/families.py); none "
             "shares a seed stream with the policies' training or validation (checked). Every controller runs the "
             "same plant, saturation and scoring (J_exec with Bryson's weights per task); a failed row (diverged, "
             "unstable, plan failed) is counted under 'failed' and left out of the paired statistics.", "",
             "Policies:"]
    for label, p in zip(labels, policies, strict=True):
        s = p.record["settings"]
        lines.append(f"- {label}: {p.path} ({p.algo.upper()}, {p.timesteps} steps, task={s['task']}, "
                     f"seed {s['seed']}; stable-baselines3 {p.record['versions']['stable_baselines3']}, torch "
                     f"{p.record['versions']['torch']})")
    return [*lines, ""]
