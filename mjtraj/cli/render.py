"""`mjtraj render`: execution videos per planner, a side-by-side clip and the snapshot strip."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mjtraj.cli.common import arm_options, names, no_progress_option, scenario_of, task_options


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj render`."""
    p = sub.add_parser("render", help="execution videos per planner, a side-by-side clip and the Fig. 1 snapshot strip")
    arm_options(p)
    task_options(p)
    p.add_argument("--planners", type=names, help="comma-separated planner names (default: all)")
    p.add_argument("--format", dest="formats", type=names, default=["mp4"], help="mp4 and/or gif (default: mp4)")
    p.add_argument("--width", type=int, default=640, help="image width, px (default 640)")
    p.add_argument("--height", type=int, default=480, help="image height, px (default 480)")
    p.add_argument("--camera", default="front", help="a camera of the model (the UR5: front, side, top) or free (a "
                   "free camera framed on the model); default front, or free on a model without it")
    p.add_argument("--quality", default="fast", help="fast: no shadows or floor reflection, fewer facets (default); "
                   "high: the model's own scene, for publication frames")
    p.add_argument("--every", type=int, default=1, help="keep one control period in EVERY (default 1)")
    p.add_argument("--out", type=Path, default=Path("results/videos"), help="output folder (default: "
                   "results/videos/)")
    no_progress_option(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from mjtraj.checks import choice, positive_int
    from mjtraj.media.render import RENDER_QUALITIES, check_render_options
    from mjtraj.media.videos import SNAPSHOT_TIMES, check_formats, render_all
    from mjtraj.study.comparison import compare, default_planners

    scenario = scenario_of(args)
    check_render_options(scenario.model, args.width, args.height, args.camera)
    check_formats(args.formats)
    choice("quality", args.quality, RENDER_QUALITIES)
    every = positive_int("every", args.every)
    planners = tuple(args.planners or default_planners())
    result = compare(scenario, planners)
    total = len(planners) * (scenario.task.steps // every + 1) + len(SNAPSHOT_TIMES) * len(planners)
    with tqdm(total=total, desc="mjtraj render", unit="frame", file=sys.stderr,
              disable=None if not args.no_progress else True) as bar:
        paths = render_all(result, args.out, formats=args.formats, width=args.width, height=args.height,
                           camera=args.camera, quality=args.quality, every=every, progress=bar.update)
    for path in paths:
        print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")
    return 0
