"""`mjtraj export`: a complete sweep as a typed SQLite table, JSON Lines or CSV."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from mjtraj.cli.common import Progress, no_progress_option


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj export`."""
    p = sub.add_parser("export", help="a complete sweep (store or CSV) as a typed SQLite table, JSON Lines or CSV")
    p.add_argument("sweep", type=Path, help="the sweep: its SQLite store or CSV file")
    p.add_argument("--out", type=Path, required=True, help="output: FILE.sqlite (or .db), FILE.jsonl or FILE.csv")
    p.add_argument("--workers", type=int, help="processes that export a store in parts (default: one per CPU, at "
                   "most 4 and one per 100,000 rows; the output is the same)")
    no_progress_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from mjtraj.study.export import export

    with Progress("mjtraj export", "row", not args.no_progress) as progress:
        rows = export(args.sweep, args.out, progress=progress, workers=args.workers)
    print(f"wrote {rows} rows of {args.sweep} to {args.out}")
    return 0
