"""`mjtraj reproduce`: the study the README reports, from scratch, by the documented commands in turn.

The steps are the commands the results pages cite, run in this process through `mjtraj.cli.main` (so their
output files are exactly those commands' outputs): Table I, the weight frontier on the paper task and over
nominal motions, the three 1,000-motion audit sweeps (Bryson's weights, the held-out tuned weights, the oracle
weights) and the effort sweep with its bound, then the audit of each. A step that fails is reported and the others
still run; the exit code is then 1.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from mjtraj.cli.common import no_progress_option


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj reproduce`."""
    p = sub.add_parser("reproduce", help="the study the README reports, from scratch: Table I, the frontiers, the "
                       "three audit sweeps and the effort sweep, their audits (its wall time: docs/speed.md)")
    p.add_argument("--out", type=Path, default=Path("reproduced"), help="output folder (default reproduced/)")
    p.add_argument("--scenarios", type=int, default=1000, help="scenarios per family of each sweep (default 1000, "
                   "the published study; the nominal frontier takes at most 200)")
    p.add_argument("--workers", type=int, help="sweep worker processes (default: all cores)")
    no_progress_option(p)
    p.set_defaults(handler=run)


def steps(out: Path, scenarios: int, workers: int | None = None, progress: bool = True) -> list[list[str]]:
    """The commands of the study, as argument lists of `mjtraj`, writing under `out`."""
    from mjtraj.checks import positive_int

    n = str(positive_int("scenarios", scenarios))
    sweeps = out / "sweeps"
    families = ["--family", "nominal,aggressive,mismatch", "--scenarios", n]
    extra = (["--workers", str(workers)] if workers is not None else []) + ([] if progress else ["--no-progress"])
    quiet = [] if progress else ["--no-progress"]
    return [
        ["compare", "--out", str(out / "compare")],
        ["frontier", "--out", str(out / "frontier"), *quiet],
        ["frontier", "--family", "nominal", "--scenarios", str(min(200, int(n))), "--out", str(out / "frontier"),
         *quiet],
        ["sweep", *families, "--planners", "optimal,cubic,quintic,trapezoidal,optimal_start,min_effort",
         "--ff-accel", "sample,step_average", "--gravity-comp", "native,zoh", "--model-error",
         "--out", str(sweeps / "audit.csv"), *extra],
        ["sweep", *families, "--config", "paper_tuned", "--out", str(sweeps / "tuned.csv"), *extra],
        ["sweep", *families, "--config", "paper_oracle", "--out", str(sweeps / "oracle.csv"), *extra],
        ["audit", str(sweeps / "audit.csv"), str(sweeps / "tuned.csv"), str(sweeps / "oracle.csv"),
         "--out", str(out / "AUDIT.md"), *quiet],
        ["sweep", *families, "--planners", "optimal,cubic,quintic,trapezoidal,scurve,min_effort,nonlinear_min_effort",
         "--batch", "50", "--out", str(sweeps / "effort.csv"), *extra],
        ["audit", str(sweeps / "effort.csv"), "--out", str(out / "AUDIT_effort.md"), *quiet],
    ]


def run(args: argparse.Namespace) -> int:
    from mjtraj.cli import main

    commands = steps(args.out, args.scenarios, args.workers, progress=not args.no_progress)
    walls: list[tuple[str, float, int]] = []
    for k, argv in enumerate(commands, start=1):
        line = "mjtraj " + " ".join(argv)
        print(f"\n[{k}/{len(commands)}] {line}", flush=True)
        start = time.perf_counter()
        code = main(argv)
        walls.append((line, time.perf_counter() - start, code))
    print(f"\nreproduce: {len(commands)} commands, {sum(w for _, w, _ in walls):.0f} s in all")
    for line, wall, code in walls:
        print(f"  {wall:7.1f} s  {'ok    ' if code == 0 else f'exit {code}'}  {line}")
    failed = [line for line, _, code in walls if code != 0]
    if failed:
        print(f"reproduce: {len(failed)} of {len(commands)} commands failed (above); the others' files are written")
        return 1
    print(f"wrote everything under {args.out}/")
    return 0
