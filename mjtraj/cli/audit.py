"""`mjtraj audit`: the paper's claims checked against sweeps."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mjtraj.cli.common import figure_format_option


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj audit`."""
    p = sub.add_parser("audit", help="check the paper's claims against sweep files; writes AUDIT.md and figures")
    p.add_argument("sweeps", nargs="+", type=Path, help="sweep results: SQLite stores or CSV files")
    p.add_argument("--out", type=Path, default=Path("results/AUDIT.md"), help="output Markdown (default "
                   "results/AUDIT.md)")
    p.add_argument("--partial", action="store_true", help="audit the complete units of an unfinished sweep (and say "
                   "what is missing) instead of refusing it")
    p.add_argument("--no-tasks", action="store_true", help="skip the paper task, its reverse and the weight frontier "
                   "(computed at audit time from each file's settings)")
    p.add_argument("--no-progress", action="store_true", help="no progress display")
    figure_format_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from mjtraj.study.audit import write_audit

    with tqdm(desc="mjtraj audit", unit="stage", file=sys.stderr, leave=False,
              disable=None if not args.no_progress else True) as bar:
        def stage(name: str) -> None:
            bar.set_description_str(f"mjtraj audit: {name}")
            bar.update(1)

        text = write_audit(args.sweeps, args.out, partial=args.partial, tasks=not args.no_tasks, progress=stage,
                           figure_formats=tuple(args.figure_format))
    verdicts = text.split("## Verdicts", 1)[1].split("\n\nVerdict rule")[0]
    print(verdicts.strip())
    print(f"\nwrote {args.out}")
    return 0
