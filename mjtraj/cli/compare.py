"""`mjtraj compare`: the paper's Table I, every planner through one closed loop."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from mjtraj.cli.common import arm_options, figure_format_option, json_safe, loop_flags, names, scenario_of, task_options


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj compare`."""
    p = sub.add_parser("compare", help="the paper's Table I: every planner through one closed loop")
    arm_options(p)
    task_options(p)
    p.add_argument("--dt", type=float, help="control period, s (default: the scenario's; 0.02 in the paper "
                   "scenario)")
    loop_flags(p)
    p.add_argument("--planners", type=names, help="comma-separated planner names (default: all)")
    p.add_argument("--out", type=Path, help="output folder (default: results/, or results/MODEL/ with --model, "
                   "MODEL the file's name without .xml; then LAW/ with --controller other than pid, so Table I's "
                   "files are never overwritten)")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    figure_format_option(p)
    p.set_defaults(handler=run)


def output_folder(args: argparse.Namespace) -> Path:
    """compare's output folder: --out, else results/ for the UR5 and results/MODEL/ for an arm file, and within it
    LAW/ for a control law other than PID named by --controller (each beside Table I's results, never over them)."""
    if args.out is not None:
        return Path(args.out)
    folder = Path("results") / args.model.stem if args.model is not None else Path("results")
    law = getattr(args, "controller", None)
    return folder / law if law not in (None, "pid") else folder


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from mjtraj.files import write_text_atomic
    from mjtraj.study.comparison import compare, comparison_record
    from mjtraj.study.report import format_report, results_csv, write_series

    scenario = scenario_of(args)
    scenario.task.check_limits(scenario.model)
    args.out = output_folder(args)
    from mjtraj.study.comparison import default_planners

    # plans, execute, check, figures
    stages = len(args.planners or default_planners()) + 2 + (0 if args.no_figures else 1)
    with tqdm(total=stages, desc="mjtraj compare", file=sys.stderr, leave=False, disable=None) as bar:
        def progress(label: str) -> None:
            bar.set_postfix_str(label)
            bar.update(1)

        result = compare(scenario, args.planners, progress=progress)
        record = json_safe(comparison_record(result))
        write_text_atomic(args.out / "results.json", json.dumps(record, indent=2) + "\n")
        write_text_atomic(args.out / "results.csv", results_csv(result))
        write_series(result, args.out / "results.npz")
        figures = []
        if not args.no_figures:
            from mjtraj.study.plots import write_figures

            progress("figures")
            figures = write_figures(result, args.out, formats=tuple(args.figure_format))
    if args.json:
        print(json.dumps(record, indent=2))
    else:
        print(format_report(result))
        print(f"\nwrote {args.out / 'results.json'}, {args.out / 'results.csv'}, {args.out / 'results.npz'}"
              + (f" and {len(figures)} figures" if figures else ""))
    return 0
