"""`mjtraj tune`: every planner's free parameters (or the control law's) tuned with one held-out budget."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from mjtraj.cli.common import Progress, arm_options, base_scenario, names, no_progress_option


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj tune`."""
    p = sub.add_parser("tune", help="tune every planner's free parameters with an equal, held-out budget; writes a "
                       "scenario file with the tuned options and the tuning record")
    arm_options(p, config="base scenario TOML (default: the shipped paper scenario)")
    p.add_argument("--planners", type=names, default=["optimal", "trapezoidal", "scurve"],
                   help="planners to tune (default optimal, trapezoidal, scurve; cubic and quintic have no parameters)")
    p.add_argument("--family", default="nominal", help="family whose rules draw the training scenarios (default "
                   "nominal)")
    p.add_argument("--scenarios", type=int, default=50, help="training scenarios (default 50)")
    p.add_argument("--seed", type=int, default=0, help="seed of the training scenarios and of the optimiser")
    p.add_argument("--budget", type=int, default=32, help="evaluations per planner (default 32)")
    p.add_argument("--on-task", action="store_true", help="oracle mode: tune on the scenario's own task (labelled; "
                   "not a held-out result)")
    p.add_argument("--gains", action="store_true", help="tune the control law's parameters instead: the PID gains "
                   "(factors on kp, ki, kd, log-uniform in [1/4, 4]) or, with --config paper_adaptive.toml, the "
                   "adaptive law's adaptation rate (log-uniform in [1e-4, 1]); cubic references; --planners and "
                   "--on-task do not apply; a PID file is rl eval's --tuned-gains baseline")
    no_progress_option(p)
    p.add_argument("--out", type=Path, default=Path("tuned.toml"), help="the tuned scenario file (default "
                   "tuned.toml)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from mjtraj.domain.toml_text import dumps
    from mjtraj.files import write_text_atomic
    from mjtraj.study.tuning import tune

    base = base_scenario(args, workspace=not args.on_task)  # drawn tasks: gains over the workspace
    if args.gains:
        from mjtraj.study.tuning import tune_gains

        with Progress("mjtraj tune --gains", "point", not args.no_progress) as progress:
            tuned, gains = tune_gains(base, family=args.family, scenarios=args.scenarios, seed=args.seed,
                                      budget=args.budget, progress=progress)
        write_text_atomic(args.out, dumps(tuned.as_dict(), header=(
            f"Written by `mjtraj tune --gains` from {args.config or 'the shipped paper.toml'}: the control law's "
            "parameters below were tuned by the rules recorded in [tuning]. Score PID gains with `mjtraj rl eval "
            "--tuned-gains`.")))
        best = gains.best
        what = "PID gains" if base.loop.controller == "pid" else f"{base.loop.controller} parameters"
        print(f"{what}: {', '.join(f'{k} = {v:.4g}' for k, v in best.parameters.items())}; mean J_exec "
              f"{best.objective:.4g} over {args.scenarios} {args.family} training scenarios "
              f"({len(gains.trials)} evaluations)")
        print(f"wrote {args.out}")
        return 0
    with Progress("mjtraj tune", "point", not args.no_progress) as progress:
        tuned, results = tune(base, planners=args.planners, family=args.family, scenarios=args.scenarios,
                              seed=args.seed, budget=args.budget, on_task=args.on_task, progress=progress)
    import textwrap

    use = ("ORACLE: tuned on the scenario's own task, to show what that task allows; never a held-out result."
           if args.on_task else "Evaluate on held-out scenarios with `mjtraj compare --config` or `mjtraj sweep "
           "--config`.")
    header = textwrap.fill(f"Written by `mjtraj tune{' --on-task' if args.on_task else ''}` from "
                           f"{args.config or 'the shipped paper.toml'}: the planner options below were tuned by the "
                           f"rules recorded in [tuning]. {use}", 110)
    write_text_atomic(args.out, dumps(tuned.as_dict(), header=header))
    for result in results:
        best = result.best
        shown = ", ".join(f"{k} = {v:.4g}" for k, v in best.parameters.items()) or "(no parameters)"
        print(f"{result.planner}: {shown}; mean J_exec {best.objective:.4g} over {tuned.tuning['scenarios']} "  # type: ignore[index]
              f"training scenarios ({len(result.trials)} evaluations)")
    print(f"wrote {args.out} ({tuned.tuning['mode']})")  # type: ignore[index]
    return 0
