"""`mjtraj sweep`: every planner on many seeded scenarios, committed unit by unit to a store."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from mjtraj.cli.common import names, no_progress_option, torque_limit_option


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj sweep`."""
    p = sub.add_parser("sweep", help="every planner on many seeded scenarios; rows committed unit by unit to a "
                       "SQLite store (resumable)")
    p.add_argument("--family", "--families", dest="families", type=names, default=["nominal"],
                   help="nominal, aggressive and/or mismatch, comma-separated (default nominal)")
    p.add_argument("--scenarios", type=int, default=1000, help="scenarios per family (default 1000)")
    p.add_argument("--seed", type=int, default=0, help="the sweep's seed (default 0)")
    p.add_argument("--planners", type=names, help="planners and variants, comma-separated (default: optimal, cubic, "
                   "quintic, trapezoidal; variants: optimal_start, min_effort)")
    p.add_argument("--ff-accel", dest="ff_accel", type=names, default=["sample"],
                   help="feedforward acceleration modes to run: sample and/or step_average (default sample)")
    p.add_argument("--gravity-comp", dest="gravity_comp", type=names, default=["native"],
                   help="gravity compensation modes to run: native and/or zoh (default native)")
    p.add_argument("--model-error", action="store_true",
                   help="also measure the linear model's open-loop prediction error of optimal-type planners")
    p.add_argument("--floor", action="store_true",
                   help="also each row's clairvoyant floor and its score over it (columns floor, cost_over_floor; "
                        "with --settle, protocol v2's floor; solve times: docs/floor.md)")
    p.add_argument("--sensor-noise", type=float, default=0.0, help="mismatch: position noise std, rad (default 0)")
    p.add_argument("--delay", type=int, default=0, help="mismatch: actuation delay, control periods, 0 or 1 "
                   "(default 0)")
    p.add_argument("--settle", type=float, default=0.0,
                   help="protocol v2's settle window, s: every execution goes on this long after its motion, the "
                   "goal held, scored over it (J_settle) and held to the at-rest rule (default 0: the paper's study, "
                   "J_exec over the motion; the benchmark's window is 0.5)")
    p.add_argument("--batch", type=int, default=None, help="scenarios per unit of work (default 250; 25 with "
                   "--floor, whose solves take longer, so that the workers share the floors and the progress "
                   "bar moves)")
    p.add_argument("--config", help="base scenario TOML: controller and planner options (default: paper.toml)")
    p.add_argument("--model", help="your MJCF arm instead of the UR5")
    torque_limit_option(p)
    p.add_argument("--out", type=Path, default=Path("sweep.sqlite"), help="results: a SQLite store (.sqlite, "
                   ".sqlite3 or .db; one transaction per unit) or a CSV file (any other suffix); default "
                   "sweep.sqlite")
    p.add_argument("--resume", action="store_true", help="continue an interrupted sweep in --out")
    p.add_argument("--backend", default="local", help="local (process pool) or ray (default local)")
    p.add_argument("--workers", type=int, help="local worker processes, or CPUs of a local Ray (default: all)")
    p.add_argument("--ray-address", help="Ray cluster HOST:PORT, ray://HOST:PORT or auto (default: a local Ray)")
    no_progress_option(p)
    p.set_defaults(handler=run)


FLOOR_BATCH = 25
"""--batch's default with --floor: scenarios per unit of work when every row also solves its floor."""


def sweep_settings(args: argparse.Namespace):  # noqa: ANN202
    from mjtraj.study.sweep import DEFAULT_PLANNERS, SweepSettings

    return SweepSettings(families=tuple(args.families), scenarios=args.scenarios, seed=args.seed,
                         planners=tuple(args.planners or DEFAULT_PLANNERS), ff_accel=tuple(args.ff_accel),
                         gravity_comp=tuple(args.gravity_comp),
                         batch=args.batch if args.batch is not None else FLOOR_BATCH if args.floor else 250,
                         sensor_noise=args.sensor_noise,
                         delay=args.delay, model_error=args.model_error, config=args.config, model=args.model,
                         torque_limit=args.torque_limit, floors=args.floor, settle=args.settle)


def run(args: argparse.Namespace) -> int:
    from mjtraj.study.runner import run_sweep

    settings = sweep_settings(args)
    report = run_sweep(settings, args.out, resume=args.resume, backend=args.backend, workers=args.workers,
                       ray_address=args.ray_address, progress=not args.no_progress)
    statuses = ", ".join(f"{k} {v}" for k, v in sorted(report.statuses.items())) or "none"
    print(f"wrote {report.rows} rows to {report.path} in {report.wall:.1f} s ({report.skipped_units} units were "
          f"already done); statuses: {statuses}")
    return 0
