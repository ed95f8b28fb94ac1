"""`mjtraj floor`: the clairvoyant floor of a family's scenarios (J_settle at rest in protocol v2, J_exec in v1)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from mjtraj.cli.common import Progress, json_safe, names, no_progress_option, scenario_range

FAMILIES = ("nominal", "aggressive", "mismatch")


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj floor`."""
    from mjtraj.rl.protocol import PROTOCOL, PROTOCOLS

    p = sub.add_parser("floor", help="the clairvoyant floor: the least score any controller can reach on each "
                        "scenario (true plant, torques within the saturation; protocol v2: J_settle, at rest at the "
                        "goal; v1: J_exec, the goal reached), beside the control laws' own scores")
    p.add_argument("--config", type=Path, help="scenario TOML (default: the paper scenario)")
    p.add_argument("--family", "--families", dest="families", type=names, default=["nominal"],
                   help=f"the scenarios' families, comma-separated: {', '.join(FAMILIES)}, drawn as sweeps draw them "
                   "(default nominal)")
    p.add_argument("--protocol", choices=tuple(PROTOCOLS), default=PROTOCOL,
                   help=f"the benchmark protocol (default {PROTOCOL}: the episode goes on for the settle window, "
                   "scored by J_settle, the floor at rest at the goal; on the mismatch plants every start is solved "
                   "and floor_without_LAW recorded; v1: J_exec over the motion, the goal rule)")
    p.add_argument("--scenarios", type=scenario_range, default=range(0, 20),
                    help="how many (K: 0..K-1) or which (A:B, B excluded) scenarios (default 20)")
    p.add_argument("--seed", type=int, default=1, help="the family's seed (default 1: the held-out scenarios)")
    p.add_argument("--planner", default="cubic", help="the planner whose reference is executed (default cubic)")
    p.add_argument("--every-start", action="store_true",
                   help="solve from every control law's torques and keep the least (the check that the starts agree; "
                        "about four times the time); by default only the start of least merit is solved")
    p.add_argument("--out", type=Path, help="also write every record to this CSV file")
    p.add_argument("--json", action="store_true", help="print the records and the summary as JSON")
    no_progress_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import csv

    from mjtraj.domain.scenario import load_scenario
    from mjtraj.exceptions import InvalidInputError
    from mjtraj.rl.protocol import SETTLE
    from mjtraj.study.floor import family_floors

    unknown = [f for f in args.families if f not in FAMILIES]
    if unknown:
        raise InvalidInputError(f"--family: expected {', '.join(FAMILIES)} (comma-separated), got "
                                f"{','.join(args.families)}")
    scenario = load_scenario(args.config)
    everything: list[dict[str, Any]] = []
    summaries = []
    with Progress("mjtraj floor", "scenario", not args.no_progress) as progress:
        for family in args.families:
            records = []
            for record in family_floors(scenario, family, seed=args.seed, scenarios=args.scenarios,
                                        planner=args.planner, every_start=args.every_start,
                                        settle=SETTLE[args.protocol]):
                records.append(record)
                everything.append(record)
                progress(len(everything), len(args.scenarios) * len(args.families))
            summaries.append(_summary(args, family, records))
    if args.out is not None:
        columns = list(dict.fromkeys(k for r in everything for k in r))
        with open(args.out, "w", newline="") as handle:
            writer = csv.DictWriter(handle, columns)
            writer.writeheader()
            writer.writerows({k: repr(v) if isinstance(v, float) else v for k, v in r.items()} for r in everything)
    if args.json:
        print(json.dumps(json_safe({"summary": summaries[0] if len(summaries) == 1 else summaries,
                                    "records": everything}), indent=2))
        return 0
    for family, summary in zip(args.families, summaries, strict=True):
        _print(summary, [r for r in everything if r["family"] == family])
    return 0


def _summary(args: argparse.Namespace, family: str, records: list[dict[str, Any]]) -> dict[str, Any]:
    """One family's summary of its records."""
    ok = [r for r in records if r["status"] == "ok"]
    laws = [k[2:] for k in ok[0] if k.startswith("J_")] if ok else []
    v2 = args.protocol == "v2"
    summary: dict[str, Any] = {"family": family, "protocol": args.protocol, "seed": args.seed,
                               "planner": args.planner,
                               "starts": "every start" if args.every_start or (v2 and family == "mismatch")
                               else "the best-ranked start", "scenarios": len(records), "floored": len(ok)}
    if ok:
        summary.update(_at_rest_means(ok, laws) if v2 else _means(ok, laws))
        summary.update(_solves(ok, laws, v2))
    return summary


def _ratio(pairs: list[tuple[float, float]]) -> float:
    """The ratio of means of (numerator, denominator) pairs, over the pairs whose both are finite (NaN: none)."""
    import numpy as np

    values = np.array(pairs, dtype=np.float64).reshape(-1, 2)
    done = np.isfinite(values).all(axis=1)
    return float(np.mean(values[done, 0]) / np.mean(values[done, 1])) if done.any() else float("nan")


def _means(ok: list[dict[str, Any]], laws: list[str]) -> dict[str, Any]:
    """Protocol v1: each law's mean J_exec and the floor's, and the floor over cubic+PID's."""
    import numpy as np

    out: dict[str, Any] = {f"mean J_{law}": float(np.mean([r[f"J_{law}"] for r in ok])) for law in laws}
    out["mean floor"] = float(np.mean([r["floor"] for r in ok]))
    if "pid" in laws:
        out["floor / cubic+PID (ratio of means)"] = out["mean floor"] / float(np.mean([r["J_pid"] for r in ok]))
    return out


def _at_rest_means(ok: list[dict[str, Any]], laws: list[str]) -> dict[str, Any]:
    """Protocol v2: a law that did not come to rest failed, so its mean J_settle and its ratio to the floor are over
    the scenarios it succeeded on, beside how many it failed."""
    import numpy as np

    out: dict[str, Any] = {}
    for law in laws:
        cost = np.array([r[f"J_{law}"] for r in ok])
        done = np.isfinite(cost)
        out[f"mean J_{law} (at rest)"] = float(np.mean(cost[done])) if done.any() else float("nan")
        out[f"J_{law}: not at rest"] = int(np.sum(~done))
        out[f"J_{law} / floor (ratio of means, where at rest)"] = _ratio([(r[f"J_{law}"], r["floor"]) for r in ok])
    out["mean floor"] = float(np.mean([r["floor"] for r in ok]))
    return out


def _solves(ok: list[dict[str, Any]], laws: list[str], v2: bool) -> dict[str, Any]:
    """How the solves went: the floor over the best law, time, the starts' spread, the terminal rule's slack, and in
    v2 on mismatch plants each law against the floor found without its own start."""
    import numpy as np

    out: dict[str, Any] = {"median floor / best law": float(np.median([r["floor_over_best"] for r in ok])),
                           "median seconds": float(np.median([r["seconds"] for r in ok]))}
    spreads = [r["start_spread"] for r in ok if np.isfinite(r["start_spread"])]
    if spreads:
        out["median spread of the starts' floors"] = float(np.median(spreads))
    out["largest end error / settling band" if v2 else "largest terminal_err / goal radius"] = float(
        max(r["terminal_err"] / r["goal_radius"] for r in ok))
    if "end_speed" in ok[0]:
        out["largest end speed (rad/s)"] = float(max(r["end_speed"] for r in ok))
    for law in laws:
        if f"floor_without_{law}" in ok[0]:
            out[f"J_{law} / floor without its start (ratio of means, where at rest)"] = _ratio(
                [(r[f"J_{law}"], r[f"floor_without_{law}"]) for r in ok])
    return out


def _print(summary: dict[str, Any], records: list[dict[str, Any]]) -> None:
    """One family's records and summary on the terminal."""
    ok = [r for r in records if r["status"] == "ok"]
    laws = [k[2:] for k in ok[0] if k.startswith("J_")] if ok else []
    print(f"{'scenario':>8} " + " ".join(f"{'J ' + law:>26}" for law in laws) + f" {'floor':>10} {'/best':>6} "
          f"{'start':>24} {'s':>6}")
    for r in records:
        if r["status"] != "ok":
            print(f"{r['scenario']:>8} {r['status']}")
            continue
        print(f"{r['scenario']:>8} " + " ".join(f"{r['J_' + law]:>26.5g}" for law in laws)
              + f" {r['floor']:>10.5g} {r['floor_over_best']:>6.3f} {r['start']:>24} {r['seconds']:>6.2f}")
    print()
    for key, value in summary.items():
        print(f"{key}: {value:.4g}" if isinstance(value, float) else f"{key}: {value}")
    print()
