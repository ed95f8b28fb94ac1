"""`mjtraj frontier`: the optimal planner over its weight frontier, beside the other planners."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from mjtraj.cli.common import (
    Progress,
    arm_options,
    figure_format_option,
    floats,
    json_safe,
    no_progress_option,
    scenario_of,
    task_options,
)
from mjtraj.exceptions import InvalidInputError


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj frontier`."""
    p = sub.add_parser("frontier", help="the optimal planner over its weight frontier (Q = alpha Q_bryson), beside the "
                       "other planners, by the scenario's fixed score")
    arm_options(p)
    task_options(p)
    p.add_argument("--alphas", type=floats, help="alpha values (default: 0 and 33 values from 1e-6 to 1e2)")
    p.add_argument("--splits", type=floats, help="shares of the state weight on positions, in [0, 1] (default 0.5, "
                   "Bryson's balance)")
    p.add_argument("--family", help="nominal | aggressive | mismatch: medians over a family's scenarios instead of "
                   "the scenario's task")
    p.add_argument("--scenarios", type=int, help="scenarios of --family (default 100)")
    p.add_argument("--seed", type=int, help="seed of --family's scenarios (default 0)")
    p.add_argument("--out", type=Path, default=Path("results"), help="output folder (default: results/)")
    p.add_argument("--json", action="store_true", help="print the rows as JSON on stdout")
    p.add_argument("--no-figures", action="store_true", help="skip the frontier figure")
    figure_format_option(p)
    no_progress_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from mjtraj.files import write_text_atomic
    from mjtraj.study.frontier import DEFAULT_ALPHAS, DEFAULT_SPLITS, frontier
    from mjtraj.study.report import format_frontier

    for flag, value in (("--scenarios", args.scenarios), ("--seed", args.seed)):
        if value is not None and args.family is None:
            raise InvalidInputError(f"{flag}: only used with --family (without it the frontier is on the scenario's "
                                    f"task)")
    scenario = scenario_of(args, workspace=args.family is not None)  # drawn tasks: gains over the workspace
    with Progress("mjtraj frontier", "planner", not args.no_progress) as progress:
        result = frontier(scenario, alphas=args.alphas if args.alphas is not None else DEFAULT_ALPHAS,
                          splits=args.splits if args.splits is not None else DEFAULT_SPLITS, family=args.family,
                          scenarios=100 if args.scenarios is None else args.scenarios,
                          seed=0 if args.seed is None else args.seed, progress=progress)
    name = "frontier" if args.family is None else f"frontier_{args.family}"
    record = json_safe({"setting": result.setting, "rows": [row.as_dict() for row in result.rows]})
    write_text_atomic(args.out / f"{name}.json", json.dumps(record, indent=2) + "\n")
    figure = None
    if not args.no_figures:
        from mjtraj.study.plots import frontier_figure

        figure = frontier_figure(result, args.out / f"{name}.png", formats=tuple(args.figure_format))
    if args.json:
        print(json.dumps(record, indent=2))
    else:
        print(format_frontier(result))
        print(f"\nwrote {args.out / (name + '.json')}" + (f" and {figure}" if figure else "") +
              ("" if figure or args.no_figures else " (no figure: no execution succeeded)"))
    return 0
