"""`mjtraj floor`: the clairvoyant floor of J_exec of a family's scenarios."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from mjtraj.cli.common import Progress, json_safe, no_progress_option, scenario_range


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj floor`."""
    p = sub.add_parser("floor", help="the clairvoyant floor of J_exec: the least any controller can score on each "
                        "scenario (true plant, torques within the saturation, the goal reached), beside the control "
                        "laws' own scores")
    p.add_argument("--config", type=Path, help="scenario TOML (default: the paper scenario)")
    p.add_argument("--family", choices=("nominal", "aggressive", "mismatch"), default="nominal",
                    help="the scenarios' family, drawn as sweeps draw them (default nominal)")
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

    import numpy as np

    from mjtraj.study.floor import family_floors
    from mjtraj.study.scenario import load_scenario

    scenario = load_scenario(args.config)
    records = []
    with Progress("mjtraj floor", "scenario", not args.no_progress) as progress:
        for record in family_floors(scenario, args.family, seed=args.seed, scenarios=args.scenarios,
                                    planner=args.planner, every_start=args.every_start):
            records.append(record)
            progress(len(records), len(args.scenarios))
    ok = [r for r in records if r["status"] == "ok"]
    laws = [k[2:] for k in ok[0] if k.startswith("J_")] if ok else []
    summary: dict[str, Any] = {"family": args.family, "seed": args.seed, "planner": args.planner,
                               "starts": "every start" if args.every_start else "the best-ranked start",
                               "scenarios": len(records), "floored": len(ok)}
    if ok:
        pid = np.array([r["J_pid"] for r in ok]) if "pid" in laws else None
        for law in laws:
            summary[f"mean J_{law}"] = float(np.mean([r[f"J_{law}"] for r in ok]))
        summary["mean floor"] = float(np.mean([r["floor"] for r in ok]))
        if pid is not None:
            summary["floor / cubic+PID (ratio of means)"] = summary["mean floor"] / float(np.mean(pid))
        summary["median floor / best law"] = float(np.median([r["floor_over_best"] for r in ok]))
        summary["median seconds"] = float(np.median([r["seconds"] for r in ok]))
        spreads = [r["start_spread"] for r in ok if np.isfinite(r["start_spread"])]
        if spreads:
            summary["median spread of the starts' floors"] = float(np.median(spreads))
        summary["largest terminal_err / goal radius"] = float(max(r["terminal_err"] / r["goal_radius"] for r in ok))
    if args.out is not None:
        names = list(dict.fromkeys(k for r in records for k in r))
        with open(args.out, "w", newline="") as handle:
            writer = csv.DictWriter(handle, names)
            writer.writeheader()
            writer.writerows({k: repr(v) if isinstance(v, float) else v for k, v in r.items()} for r in records)
    if args.json:
        print(json.dumps(json_safe({"summary": summary, "records": records}), indent=2))
        return 0
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
    return 0
