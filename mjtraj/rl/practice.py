"""What a practitioner reads beside the score (protocol v2): how each method's executions ended, and whether its
ranking survives another weighting.

A score alone hides how it was earned: a law that saves torque by arriving late and still moving can score below
one that stops. The execution table shows, per family and method, the share of episodes at rest at the goal, the
score's position, velocity and torque parts, the tracking errors, the end error and speed, the settling time and the
peak torque. The weighting check ranks the methods again under a tracking-heavy weighting (the position weight from
TRACKING_SHARE of the move instead of the whole move) and gives Kendall's tau between the two rankings.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy.stats import kendalltau

from mjtraj.study import numeric

TRACKING_SHARE = 0.01
"""The tracking-heavy weighting's position scale, as a fraction of the move: Bryson's rule with an acceptable
position error of 1 % of the move instead of the whole move, so the position weight is 1 / 0.01^2 = 10,000 times
J_settle's; the velocity and torque weights stay."""
EXECUTION_COLUMNS = ("success", "cost", "cost_position", "cost_velocity", "cost_torque", "rms_err", "max_err",
                     "end_err", "end_speed", "settle_time", "peak_dtau")
"""The execution table's columns: the share of episodes at rest at the goal, then means over the episodes that ran
(status ok or not_settled; the settling time over those that settled)."""
HEADS = {"success": "success", "cost": "J_settle", "cost_position": "position part", "cost_velocity": "velocity part",
         "cost_torque": "torque part", "rms_err": "rms err (rad)", "max_err": "max err (rad)",
         "end_err": "end err (rad)", "end_speed": "end speed (rad/s)", "settle_time": "settle (s)",
         "peak_dtau": "peak torque (N m)"}
RAN = ("ok", "not_settled")
"""Statuses whose rows carry metrics."""


def _method_of(groups: Mapping[str, Sequence[str]]) -> dict[str, str]:
    """A row's method label -> the configuration it belongs to (its seeds pooled); other labels stand for themselves."""
    return {member: name for name, members in groups.items() for member in members}


def _by_method(rows: Sequence[dict[str, Any]], groups: Mapping[str, Sequence[str]], family: str
               ) -> dict[str, list[dict[str, Any]]]:
    """The family's rows by method (configurations' seeds pooled), in first-seen order."""
    of = _method_of(groups)
    out: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        if row["family"] == family:
            out.setdefault(of.get(row["method"], row["method"]), []).append(row)
    return out


def execution_summary(rows: Sequence[dict[str, Any]]) -> dict[str, float]:
    """One method's EXECUTION_COLUMNS over its `rows` of one family (NaN where none ran)."""
    ran = [r for r in rows if r["status"] in RAN]
    out = {"success": float(np.mean([r["status"] == "ok" for r in rows])) if rows else float("nan")}
    for name in EXECUTION_COLUMNS[1:]:
        values = np.array([numeric(r.get(name, "nan")) for r in ran], dtype=np.float64)
        values = values[np.isfinite(values)]
        out[name] = float(np.mean(values)) if values.size else float("nan")
    return out


def execution_table(rows: Sequence[dict[str, Any]], groups: Mapping[str, Sequence[str]], families: Sequence[str]
                    ) -> tuple[str, dict[str, dict[str, dict[str, float]]]]:
    """Markdown, one row per family and method, of EXECUTION_COLUMNS; and the same as family -> method -> values."""
    record: dict[str, dict[str, dict[str, float]]] = {}
    lines = ["| family | method | " + " | ".join(HEADS[c] for c in EXECUTION_COLUMNS) + " |",
             "|---|---|" + "---|" * len(EXECUTION_COLUMNS)]
    for family in families:
        record[family] = {}
        for method, mine in _by_method(rows, groups, family).items():
            values = record[family][method] = execution_summary(mine)
            cells = [f"{values['success']:.0%}", *(f"{values[c]:.3g}" for c in EXECUTION_COLUMNS[1:])]
            lines.append(f"| {family} | {method} | " + " | ".join(cells) + " |")
    return "\n".join(lines), record


def tracking_heavy(row: dict[str, Any]) -> float:
    """A row's score under the tracking-heavy weighting (TRACKING_SHARE): its position part scaled by
    1 / TRACKING_SHARE^2, plus its velocity and torque parts."""
    return (numeric(row["cost_position"]) / TRACKING_SHARE**2 + numeric(row["cost_velocity"])
            + numeric(row["cost_torque"]))


def _common(methods: Mapping[str, Sequence[dict[str, Any]]]) -> set[int]:
    """The scenarios on which every method's every row ran (has metrics: ok or not_settled)."""
    common: set[int] | None = None
    for rows in methods.values():
        ran = {int(r["scenario"]) for r in rows if r["status"] in RAN}
        ran -= {int(r["scenario"]) for r in rows if r["status"] not in RAN}
        common = ran if common is None else common & ran
    return common or set()


def weighting_agreement(rows: Sequence[dict[str, Any]], groups: Mapping[str, Sequence[str]],
                        families: Sequence[str]) -> tuple[str, dict[str, dict[str, Any]]]:
    """Per family, the methods ranked by mean J_settle and by mean tracking-heavy score, both over the scenarios on
    which every method ran (whether or not it ended at rest: the success column says that), and Kendall's tau-b
    between the two rankings (NaN with fewer than two methods or no such scenario): a markdown table and the same
    as a dict. A method none of whose episodes ran (every row an error, under --keep-going) is not ranked and is
    named below the table."""
    record: dict[str, dict[str, Any]] = {}
    lines = [f"Rankings under J_settle and under a tracking-heavy weighting (position weight from "
             f"{TRACKING_SHARE:.0%} of the move, {1 / TRACKING_SHARE**2:,.0f} times J_settle's), best first, each "
             "a mean over the scenarios on which every method ran (at rest or not), and Kendall's tau between them "
             "(1: the same order, -1: reversed):", "",
             "| family | scenarios | by J_settle | by tracking-heavy J | Kendall's tau |", "|---|---|---|---|---|"]
    unranked: list[str] = []
    for family in families:
        every = _by_method(rows, groups, family)
        methods = {m: mine for m, mine in every.items() if any(r["status"] in RAN for r in mine)}
        unranked += [f"{m} ({family})" for m in every if m not in methods]
        common = _common(methods)
        shared = {m: [r for r in mine if int(r["scenario"]) in common] for m, mine in methods.items()}
        nan = float("nan")
        bryson = {m: float(np.mean([numeric(r["cost"]) for r in r_])) if r_ else nan for m, r_ in shared.items()}
        heavy = {m: float(np.mean([tracking_heavy(r) for r in r_])) if r_ else nan for m, r_ in shared.items()}
        names = list(methods)
        tau = nan
        if len(names) > 1 and common:
            with np.errstate(invalid="ignore"):
                tau = float(kendalltau([bryson[m] for m in names], [heavy[m] for m in names]).statistic)
        first = sorted(names, key=lambda m: bryson[m])
        second = sorted(names, key=lambda m: heavy[m])
        record[family] = {"scenarios": len(common), "by_score": first, "by_tracking_heavy": second,
                          "kendall_tau": tau, "score": bryson, "tracking_heavy": heavy,
                          "not_ranked": [m for m in every if m not in methods]}
        lines.append(f"| {family} | {len(common)} | {' < '.join(first)} | {' < '.join(second)} | {tau:.2f} |")
    if unranked:
        lines += ["", f"Not ranked, no episode of theirs ran (every row an error): {', '.join(unranked)}."]
    return "\n".join(lines), record
