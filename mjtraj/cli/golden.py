"""`mjtraj golden`: check the regression oracles (mjtraj.golden) against this code, or write them."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj golden`."""
    from mjtraj.golden import SETS

    p = sub.add_parser("golden", help="check the golden values of every published number's path against this code "
                       "(bit for bit on the recording machine, else at the stated tolerances), or write them (--write)")
    p.add_argument("--write", action="store_true",
                   help="compute the golden values and write them (tests/golden/SET.json); say in CHANGELOG.md why "
                        "they moved")
    p.add_argument("--set", dest="sets", choices=(*SETS, "all"), default="all",
                   help=f"which golden file: {', '.join(SETS)} or all (default all)")
    p.add_argument("--dir", type=Path, help="the golden files' folder (default: the checkout's tests/golden)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from mjtraj import golden

    folder = args.dir if args.dir is not None else golden.default_folder()
    names = list(golden.SETS) if args.sets == "all" else [args.sets]
    moved = 0
    for name in names:
        spec = golden.SETS[name]
        if not args.write:
            golden.read(spec, folder)  # a missing or unreadable file is said before minutes of computing
        print(f"{name}: computing ...", file=sys.stderr, flush=True)
        entries = golden.compute(spec)
        if args.write:
            old = golden.golden_path(spec, folder)
            if old.is_file():
                result = golden.check(spec, folder, entries)
                print(f"{name}: {len(result.differences)} value(s) moved from {old}" +
                      (":" if result.differences else ""))
                for d in result.differences[:40]:
                    print(f"  {d.line()}")
                if len(result.differences) > 40:
                    print(f"  ... and {len(result.differences) - 40} more")
            path = golden.write(spec, entries, folder)
            print(f"{name}: wrote {path} ({len(entries)} entries); say in CHANGELOG.md why the values moved")
            continue
        result = golden.check(spec, folder, entries)
        if result.differences:
            moved += 1
            print(f"{name}: {result.message()}")
        else:
            how = "bit for bit" if result.same_machine else "within the stated tolerances (another machine)"
            print(f"{name}: {len(entries)} entries as recorded in {result.path}, {how}")
        if result.unpinned:
            print(f"{name}: {len(result.unpinned)} value(s) computed that the file does not pin (the next --write "
                  f"pins them): {', '.join(result.unpinned[:10])}" + (" ..." if len(result.unpinned) > 10 else ""))
    return 1 if moved else 0
