"""The audit's Markdown: ratios and reductions with their intervals, the header, the verdict table, each claim's
table and the note on where we differ from the paper."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from mjtraj.study.audit.reading import Condition, SweepData
from mjtraj.study.audit.rules import CLAIMS, CLASSICAL, LARGE_MOTION, ClaimCheck, in_band, overall
from mjtraj.study.fixed_tasks import TASKS
from mjtraj.study.paper import PAPER_TABLE
from mjtraj.study.stats import EXACT_PAIRS, PairedRatio
from mjtraj.versions import describe

NO_PAIRS = "- (no paired rows: no ok execution on one side)"


def fmt_ratio(r: PairedRatio) -> str:
    """A paired ratio with its interval ('(one motion)' for a single pair)."""
    if r.count == 0 or not np.isfinite(r.ratio):
        return NO_PAIRS
    return f"{r.ratio:.3f}" + (" (one motion)" if r.count == 1 else f" [{r.low:.3f}, {r.high:.3f}]")


def fmt_red(r: PairedRatio) -> str:
    """A paired ratio's reduction, %, with its interval ('(one motion)' for a single pair)."""
    red, lo, hi = r.reduction
    if r.count == 0 or not np.isfinite(red):
        return NO_PAIRS
    return f"{red:+.1f} %" + (" (one motion)" if r.count == 1 else f" [{lo:+.1f}, {hi:+.1f}]")


def header(data: SweepData, paths: Sequence[str | os.PathLike[str]]) -> list[str]:
    """The title, the command that regenerates the file, the sweep's settings and versions, and the notes on what
    was read (several weights, a partial audit, the fixed motions, the delta method's intervals)."""
    s = data.settings
    return ["# Audit of the paper's claims", "",
            f"Regenerate: `mjtraj audit {' '.join(map(str, paths))}` (this file is written by that command from the "
            f"sweep file; nothing in it is typed by hand).", "",
            f"Sweep: families {s.get('sweep_families')}, {s.get('sweep_scenarios')} scenarios per family, seed "
            f"{s.get('sweep_seed')}, planners {s.get('sweep_planners')}, ff_accel {s.get('sweep_ff_accel')}, "
            f"gravity_comp {s.get('sweep_gravity_comp')}, sensor noise {s.get('sensor_noise')} rad, delay "
            f"{s.get('delay')}; {data.count} rows. Versions: {describe(data.versions)}.", "",
            "Scenario rules are in `mjtraj/domain/families.py`; controller and weights rules in "
            "`mjtraj/study/sweep.py`.", ""] + (
        [f"Weights compared, each a sweep's scenario file, never mixed: {', '.join(data.weights)}. Each column of "
         "the verdicts reads only its own sweep's rows; the sweep settings above are the first file's.", ""]
        if len(data.weights) > 1 else []) + (
        ["Partial audit: " + "; ".join(f"{path}: {what}" for path, what in data.missing.items()) + ".", ""]
        if data.missing else []) + (
        ["The paper task and its reverse are conditions of their own: each file's planners, controller variants and "
         "scenario file run now on those two fixed motions (nominal plant, Bryson's score on the task), through "
         "the sweep's own code, with this mjtraj's versions. One motion is a measurement, so their comparisons are "
         "direct, without intervals."
         + "".join(f" Not computed for {path}: {why}." for path, why in data.task_notes.items()), ""]
        if any(c.family in TASKS for c in data.conditions) or data.task_notes else []) + (
        [f"Intervals over more than {EXACT_PAIRS:,} paired scenarios are the delta method's normal intervals, not "
         "the bootstrap's (the same to within the bootstrap's own resampling error at that size, at a small "
         "fraction of its cost).", ""]
        if any(data.values(c, p, "ok").size > EXACT_PAIRS for c in data.conditions for p in data.planners) else [])


def verdict_table(data: SweepData, checks: dict[str, dict[Condition, ClaimCheck]]) -> list[str]:
    """The verdicts: one row per claim, one column per set of weights (`overall` over its conditions)."""
    lines = ["## Verdicts", "", "| # | claim (paper) | verdict |", "|---|---|---|"]
    if len(data.weights) > 1:
        lines[-2:] = ["| # | claim (paper) | " + " | ".join(data.weights) + " |",
                      "|---|---|" + "---|" * len(data.weights)]
    for k, text in CLAIMS.items():
        cells = []
        for label in data.weights:
            mine = {c: check.verdict for c, check in checks[k].items() if c.weights == label}
            cells.append(overall(mine) if mine else "not measured (planner absent)")
        lines.append(f"| {k} | {text} | " + " | ".join(cells) + " |")
    return lines


CLAIM_TABLES = {
    "1": ("RMS tracking error: paired ratio mean(planner)/mean(optimal), 95 % bootstrap interval",
          "| condition | " + " | ".join(CLASSICAL) + " | verdict |"),
    "2": ("Corrective torque (Int. dtau): reduction of optimal vs planner, 100 (1 - optimal/planner) "
          "[interval]; paper: 28.35, 41.29, 30.27 %", "| condition | " + " | ".join(CLASSICAL) + " | verdict |"),
    "3": ("Executed cost J_exec: reduction of optimal vs planner [interval]; paper: 48.13, 62.12, 62.64 %",
          "| condition | " + " | ".join(CLASSICAL) + " | verdict |"),
    "4": ("Trapezoidal tracks worst: mean(trapezoidal)/mean(other) of RMS error",
          "| condition | vs optimal | vs cubic | vs quintic | verdict |"),
    "5": ("Quintic vs cubic effort: mean(quintic)/mean(cubic)", "| condition | Int. dtau | RMS dtau | verdict |"),
    "6": (f"Midpoint vs start linearisation on large motions (max |dq| > {LARGE_MOTION} rad): "
          "mean(start)/mean(midpoint) of the linear model's open-loop prediction error, the executed RMS error "
          "and cost (verdict on the prediction error)",
          "| condition | scenarios | model error | RMS error | cost | verdict |"),
}
"""Each claim's table: its title and its header row."""


def claim_tables(checks: dict[str, dict[Condition, ClaimCheck]]) -> list[str]:
    """One section per claim: its table (CLAIM_TABLES), a row per condition it was checked in."""
    lines: list[str] = []
    for k, (title, head) in CLAIM_TABLES.items():
        detail = [claim_row(k, c, check) for c, check in checks[k].items()]
        lines += [f"## Claim {k}: {CLAIMS[k]}", "", title, "", head,
                  "|" + "---|" * (head.count("|") - 1)] + (detail or ["| (not measured) |"]) + [""]
    return lines


def claim_row(k: str, c: Condition, check: ClaimCheck) -> str:
    """Claim k's row in condition c: its comparisons' ratios (1, 4, 5, 6) or reductions (2, 3), then its verdict."""
    parts = check.comparisons
    if k == "1":
        cells = [f"{name}/optimal {fmt_ratio(r)}" for name, _, r in parts]
    elif k in ("2", "3"):
        cells = [f"{name}: {fmt_red(r)}" for name, _, r in parts]
    elif k == "4":
        cells = [f"trapezoidal/{name} {fmt_ratio(r)}" for name, _, r in parts]
    elif k == "5":
        cells = [f"int_dtau quintic/cubic {fmt_ratio(parts[0][2])}", f"rms_dtau {fmt_ratio(parts[1][2])}"]
    else:
        cells = [str(check.large), *(f"{fmt_ratio(r)} ({v})" for _, v, r in parts)]
    verdict = check.verdict + (f"; 28-41 % band {'met' if in_band(check) else 'not met'}" if k == "2" else "")
    return f"| {c} | " + " | ".join(cells) + f" | {verdict} |"


def paper_note() -> list[str]:
    """Where we differ from the paper: its one motion against our many, in its Table I's numbers."""
    p = PAPER_TABLE
    return ["## Where we differ from the paper", "",
            "The paper reports one motion (its Table I: optimal RMS error "
            f"{p['optimal']['rms_err']:.3e} rad, Int. dtau {p['optimal']['int_dtau']} N m s, cost "
            f"{p['optimal']['cost']}; reductions {p['cubic']['dtau_red']}, {p['quintic']['dtau_red']}, "
            f"{p['trapezoidal']['dtau_red']} % of Int. dtau and {p['cubic']['cost_red']}, "
            f"{p['quintic']['cost_red']}, {p['trapezoidal']['cost_red']} % of cost). The verdicts above are what "
            "our plant, controller and stated rules give over many motions; where a verdict reads 'does not "
            "hold', our results contradict the paper's claim under that condition. `mjtraj compare` reproduces "
            "the single paper motion.", ""]
