"""The audit's verdict rules: a comparison of two planners (`below`), a claim in one condition (`claim_holds`) and
across conditions (`overall`), and the paper's six claims checked in each condition (`check_claims`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mjtraj.study.audit.reading import Condition, SweepData
from mjtraj.study.fixed_tasks import TASKS
from mjtraj.study.stats import PairedRatio, paired_ratio

VERDICT_RULE = (
    "per condition (family x ff_accel x gravity_comp): a comparison \"A below B\" holds when the 95 % bootstrap "
    "interval of the paired ratio mean(B)/mean(A) lies above 1, fails when it lies below 1, and is inconclusive "
    "otherwise. On the paper task and its reverse (one fixed motion each, a measurement rather than a sample) it "
    "holds when B's value is above A's and fails when it is below. A claim holds in a condition when all its "
    "comparisons hold. Across conditions: \"holds\" (all), \"does not hold\" (none), else \"depends\" with the "
    "conditions where it holds.")
"""The verdict rule, as AUDIT.md states it."""
CLASSICAL = ("cubic", "quintic", "trapezoidal")
LARGE_MOTION = 1.0
"""rad: claim 6 is checked on scenarios whose largest joint displacement exceeds this."""
MIN_SCENARIOS = 10
"""A comparison on fewer paired scenarios gets no verdict (its bootstrap interval would mean nothing)."""
CLAIMS = {"1": "the optimal planner has the lowest RMS tracking error",
          "2": "it has the lowest corrective torque, 28 to 41 % below the classical planners",
          "3": "it has the lowest executed cost, about 48 % below cubic, over 62 % below quintic and trapezoidal",
          "4": "the trapezoidal planner tracks worst",
          "5": "higher-order smoothness does not lower effort (quintic needs more than cubic)",
          "6": "midpoint linearisation beats start-point linearisation for large motions"}
"""The paper's six claims, by number."""


def below(data: SweepData, c: Condition, a: str, b: str, metric: str, mask: NDArray[np.bool_] | None = None
          ) -> tuple[str, PairedRatio]:
    """Is planner a's metric below planner b's? ('yes' | 'no' | 'inconclusive', ratio mean(b)/mean(a))."""
    x, y = data.values(c, b, metric), data.values(c, a, metric)
    if mask is not None:
        x, y = x[mask], y[mask]
    r = paired_ratio(x, y)
    if c.family in TASKS:  # one fixed motion: a measurement, compared directly
        return ("yes" if r.ratio > 1.0 else "no" if r.ratio < 1.0 else "inconclusive") if r.count else "too few", r
    verdict = ("too few" if r.count < MIN_SCENARIOS else "yes" if r.low > 1.0 else "no" if r.high < 1.0
               else "inconclusive")
    return verdict, r


def claim_holds(parts: list[str]) -> str:
    """A claim's verdict in one condition from its comparisons' ('yes', 'no', 'inconclusive', 'too few')."""
    if any(p == "too few" for p in parts):
        return f"no verdict (fewer than {MIN_SCENARIOS} paired scenarios)"
    return "holds" if all(p == "yes" for p in parts) else "does not hold" if any(p == "no" for p in parts) \
        else "inconclusive"


def overall(per_condition: dict[Condition, str]) -> str:
    """A claim's verdict across conditions from its verdict in each: holds, does not hold, or depends (naming where
    it holds: a family in every controller variant, else each condition)."""
    per_condition = {c: v for c, v in per_condition.items() if not v.startswith("no verdict")}
    if not per_condition:
        return f"no verdict (fewer than {MIN_SCENARIOS} paired scenarios)"
    held = [c for c, v in per_condition.items() if v == "holds"]
    if len(held) == len(per_condition):
        return "holds"
    if not held:
        return "does not hold"
    parts = []
    for family in dict.fromkeys(c.family for c in per_condition):
        mine = [c for c in per_condition if c.family == family]
        ok = [c for c in mine if c in held]
        if len(ok) == len(mine):
            parts.append(f"{family} (every controller variant)")
        else:
            parts += [str(c) for c in ok]
    return "depends: holds only in " + "; ".join(parts)


@dataclass(frozen=True)
class ClaimCheck:
    """One claim checked in one condition: its verdict, the comparisons it rests on as (planner or metric, verdict,
    paired ratio), and for claim 6 the large motions it is checked on."""

    verdict: str
    comparisons: list[tuple[str, str, PairedRatio]]
    large: int = 0


def check_claims(data: SweepData) -> dict[str, dict[Condition, ClaimCheck]]:
    """Each claim (CLAIMS' numbers) checked in each condition where the optimal planner ran and the planners the
    claim compares are present."""
    checks: dict[str, dict[Condition, ClaimCheck]] = {k: {} for k in CLAIMS}
    for c in data.conditions:
        if not data.has(c, "optimal"):
            continue
        for k, check in _claims_in(data, c).items():
            checks[k][c] = check
    return checks


def _claims_in(data: SweepData, c: Condition) -> dict[str, ClaimCheck]:
    """The claims checkable in condition c: 1-3 against the classical planners present, 4 with trapezoidal, 5 with
    quintic and cubic, 6 with optimal_start (on the motions above LARGE_MOTION, verdict on the model error)."""
    present = [p for p in CLASSICAL if data.has(c, p)]
    out = {k: _check([(p, *below(data, c, "optimal", p, metric)) for p in present])
           for k, metric in (("1", "rms_err"), ("2", "int_dtau"), ("3", "cost"))}
    others = [p for p in ("optimal", "cubic", "quintic") if data.has(c, p)]
    if data.has(c, "trapezoidal"):
        out["4"] = _check([(p, *below(data, c, p, "trapezoidal", "rms_err")) for p in others])
    if data.has(c, "quintic") and data.has(c, "cubic"):
        out["5"] = _check([(m, *below(data, c, "cubic", "quintic", m)) for m in ("int_dtau", "rms_dtau")])
    if data.has(c, "optimal_start"):
        large = data.values(c, "optimal", "max_displacement") > LARGE_MOTION
        parts = [(m, *below(data, c, "optimal", "optimal_start", m, large)) for m in ("model_error", "rms_err", "cost")]
        out["6"] = ClaimCheck(claim_holds([v for _, v, _ in parts[:1]]), parts, int(large.sum()))
    return out


def _check(parts: list[tuple[str, str, PairedRatio]]) -> ClaimCheck:
    """A claim that holds where every one of its comparisons does."""
    return ClaimCheck(claim_holds([v for _, v, _ in parts]), parts)


def in_band(check: ClaimCheck) -> bool:
    """Claim 2's band: every reduction's interval reaches into 28 to 41 %."""
    return all(r.reduction[2] >= 28.0 and r.reduction[1] <= 41.0 for _, _, r in check.comparisons)
