"""`mjtraj audit`: the paper's claims checked against sweeps."""

from __future__ import annotations

import argparse
import json
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
    p.add_argument("--json", action="store_true", help="print the verdicts as JSON on stdout (for scripts)")
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
    verdicts = text.split("## Verdicts", 1)[1].split("\n\nVerdict rule")[0].strip()
    if args.json:
        print(json.dumps({"out": str(args.out), "verdicts": verdict_records(verdicts)}, indent=1))
        return 0
    print(verdicts)
    print(f"\nwrote {args.out}")
    return 0


def verdict_records(table: str) -> list[dict[str, Any]]:
    """The audit's verdict table (Markdown) as records: claim number, the paper's claim, and the verdict under each
    set of weights audited (the table's own column names)."""
    lines = [line for line in table.splitlines() if line.startswith("|")]
    columns = [c.strip() for c in lines[0].strip("|").split("|")]
    records = []
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        records.append({"claim": int(cells[0]), "text": cells[1], "verdicts": dict(zip(columns[2:], cells[2:],
                                                                                        strict=True))})
    return records
