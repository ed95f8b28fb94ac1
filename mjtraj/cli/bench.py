"""`mjtraj bench`: speed ratios measured in one run (mjtraj.bench measures; this prints)."""

from __future__ import annotations

import argparse
import contextlib
import io
import json
from pathlib import Path
from typing import Any

from mjtraj.cli.common import counts, json_safe
from mjtraj.exceptions import InvalidInputError

BENCH_ALL = ("plan", "planners", "busy", "loop", "floor", "startup", "env")
"""What a bare `mjtraj bench` runs, in order (`train` needs the rl extra and runs when named)."""
BENCH_ALL_MINUTES = 3
"""How long a bare `mjtraj bench` took on the 2-core development machine (docs/speed.md), minutes."""
TAIL_TASKS = {"nominal": 200, "aggressive": 100}
"""`bench planners`' tail table: random tasks per family (mjtraj.bench.bench_tail)."""

STORE_STAGE_NAMES = {"csv": "export .csv", "jsonl": "export .jsonl", "sqlite": "export .sqlite",
                     "audit": "audit --no-tasks"}
"""`bench store --stages`' short names of mjtraj.bench.STORE_STAGES."""


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj bench`."""
    p = sub.add_parser("bench", help="speed ratios measured in one run")
    p.add_argument("what", choices=(*BENCH_ALL, "train", "sweep", "store", "all"), nargs="?", default="all",
                   help=f"what to time (default all: {', '.join(BENCH_ALL)}; train (the rl extra), the minute-long "
                   "sweep and the store run only when named)")
    p.add_argument("--config", type=Path, help="scenario TOML (default: the shipped paper scenario)")
    p.add_argument("--json", action="store_true", help="print every measurement as JSON on stdout instead of the "
                   "tables (for scripts)")
    p.add_argument("--sizes", type=counts, help="loop batch sizes, comma-separated whole numbers >= 1")
    p.add_argument("--scenarios", type=int, default=10_000, help="sweep: nominal scenarios (default 10000)")
    p.add_argument("--planner-scenarios", type=int, default=12,
                   help="planners: nominal scenarios each nonlinear planner plans with both solvers (default 12)")
    p.add_argument("--tail-tasks", dest="tail_tasks", type=int, default=TAIL_TASKS["nominal"],
                   help="planners: random nominal tasks of the tail table, and half as many aggressive ones (default "
                   f"{TAIL_TASKS['nominal']})")
    p.add_argument("--workers", type=int, help="sweep: worker processes (default: all cores)")
    p.add_argument("--rows", type=int, default=100_000, help="store: rows of the synthetic store (default 100000)")
    p.add_argument("--stages", default="csv,jsonl,sqlite,audit",
                   help="store: what to time, comma-separated: csv, jsonl, sqlite (export to them), audit "
                   "(default all)")
    p.set_defaults(handler=run)


def store_stages(text: str) -> list[str]:
    """`bench store --stages`: names of mjtraj.bench.STORE_STAGES from their short names."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in STORE_STAGE_NAMES]
    if unknown or not names:
        raise InvalidInputError(f"stages: expected some of {', '.join(STORE_STAGE_NAMES)}, comma-separated, got "
                                f"{text!r}")
    return [STORE_STAGE_NAMES[n] for n in names]


def run(args: argparse.Namespace) -> int:
    from mjtraj.domain.scenario import load_scenario

    scenario = load_scenario(args.config)
    results: dict[str, Any] = {}

    def record(name: str, value: Any) -> Any:
        results[name] = value
        return value

    with contextlib.redirect_stdout(io.StringIO()) if args.json else contextlib.nullcontext():
        _sections(args, scenario, record)
    if args.json:
        print(json.dumps(json_safe(results), indent=1))
    return 0


def _sections(args: argparse.Namespace, scenario: Any, record: Any) -> None:
    """Run and print what `args.what` names, handing each measurement to `record(name, value)`."""
    if args.what == "all":
        print(f"mjtraj bench: {', '.join(BENCH_ALL)} in turn (about {BENCH_ALL_MINUTES} minutes on two cores; "
              "`mjtraj bench sweep` and `mjtraj bench store` run on their own)", flush=True)
    if args.what in ("plan", "all"):
        _plan(scenario, record)
    if args.what in ("planners", "all"):
        _planners(args, scenario, record)
    if args.what in ("busy", "all"):
        _busy(record)
    if args.what in ("loop", "all"):
        _loop(args, scenario, record)
    if args.what == "train":
        _train(record)
    if args.what == "store":
        _store(args, record)
    if args.what == "sweep":
        _sweep(args, record)
    if args.what in ("floor", "all"):
        _floor(scenario, record)
    if args.what in ("startup", "all"):
        _startup(record)
    if args.what in ("env", "all"):
        _env(record)


def _plan(scenario: Any, record: Any) -> None:
    """`bench plan`: the optimal planner's plan time by horizon, then its QP against the other solvers'."""
    from mjtraj.bench import bench_plan

    print("optimal planner (linearise + solve; the exact active set on the banded KKT system, OSQP as "
          "fallback), median wall time; target N=100 <= 1 ms, N=800 <= 10 ms")
    print(f"{'N':>6} {'median ms':>10} {'ratio to N=100':>15}")
    for row in record("plan", bench_plan(scenario)):
        print(f"{row['N']:>6} {row['median_ms']:>10.2f} {row['ratio_to_first']:>15.2f}")
    from mjtraj.bench import QP_SOLVERS, bench_qp

    qp_rows = record("qp", bench_qp(scenario))
    print(f"the same QP (N = {scenario.task.steps}), median wall time of the solve alone: mjtraj's banded-KKT "
          f"active set vs {', '.join(QP_SOLVERS)} on the condensed QP (the `bench` extra; those not installed are "
          f"left out); target: mjtraj at least 4 times faster than quadprog")
    print(f"{'solver':<28} {'median ms':>10} {'x mjtraj':>9} {'max |u - u_mjtraj| N m':>23}")
    for row in qp_rows:
        print(f"{row['solver']:<28} {1e3 * row['seconds']:>10.3f} {row['seconds'] / qp_rows[0]['seconds']:>9.2f} "
              f"{row['max_diff']:>23.1e}")


def _planners(args: argparse.Namespace, scenario: Any, record: Any) -> None:
    """`bench planners`: the fair study's planners on the scenario's task and family, then the tail."""
    from mjtraj.bench import bench_new_planners
    from mjtraj.checks import positive_int

    new = record("planners", bench_new_planners(scenario, scenarios=12 if args.what == "all" else
                             positive_int("planner_scenarios", args.planner_scenarios)))
    linear = new["linear_s"]
    print(f"the fair study's planners on the scenario's task (N = {new['steps']}), one process: the linear "
          f"optimal plan takes {1e3 * linear:.2f} ms on one core; the nonlinear planners linearise by "
          f"the compiled dynamics derivatives where their step is MuJoCo's, else by batched differences on "
          f"{new['threads']} threads (MuJoCo's batch, every CPU); targets: scurve below the closed loop that "
          f"executes it, each nonlinear planner at most 100 times the linear plan")
    print(f"{'planner':<22} {'solver':<6} {'s per plan':>10} {'x linear':>9} {'iterations':>10} {'objective':>12}")
    print(f"{'scurve':<22} {'':<6} {new['scurve_s']:>10.5f} {new['scurve_s'] / linear:>9.2f} {'':>10} {'':>12}"
          f"   (one closed-loop execution: {new['loop_s']:.5f} s; ratio {new['scurve_s'] / new['loop_s']:.2f})")
    for name in ("nonlinear_min_effort", "nonlinear_optimal"):
        for solver in ("sqp", "slsqp"):
            row = new[f"{name} {solver}"]
            if "error" in row:
                print(f"{name:<22} {solver:<6} failed: {row['error']}")
                continue
            print(f"{name:<22} {solver:<6} {row['plan_time']:>10.3f} {row['plan_time'] / linear:>9.0f} "
                  f"{row['iterations']:>10} {row['objective']:>12.6g}")
    family = new["nonlinear_min_effort family"]
    print(f"each nonlinear planner over {family['scenarios']} nominal scenarios, by solver ('auto': the SQP, "
          f"then SLSQP where it did not converge; each solver from the linear start, then the tracked one, "
          f"except nonlinear_min_effort's SQP: from both, the lower plan kept); gaps relative to SLSQP alone's "
          f"objective")
    print(f"{'planner':<22} {'solver':<6} {'failed':>6} {'median s':>9} {'x linear':>8} {'p90 s':>7} "
          f"{'x linear':>8} {'max s':>7} {'x linear':>8} {'by SLSQP':>8} {'tracked':>7} {'max gap':>9} "
          f"{'worse':>5}")
    for name in ("nonlinear_min_effort", "nonlinear_optimal"):
        family = new[f"{name} family"]
        for solver, row in family["solvers"].items():
            label = f"{solver}*" if solver == family["default"] else solver
            print(f"{name:<22} {label:<6} {row['failed']:>6} {row['median_s']:>9.3f} "
                  f"{row['median_s'] / linear:>8.0f} {row['p90_s']:>7.3f} {row['p90_s'] / linear:>8.0f} "
                  f"{row['max_s']:>7.2f} {row['max_s'] / linear:>8.0f} {row['by_slsqp']:>8} "
                  f"{row['tracked']:>7} {row['max_gap']:>+9.1e} {row['worse']:>5}")
    print("* the planner's default solver")
    print(f"linearisations over these plans: {new['jacobians']['analytic']} analytic, "
          f"{new['jacobians']['differenced']} differenced")
    from mjtraj.bench import bench_tail

    nominal = positive_int("tail_tasks", args.tail_tasks)
    tail = record("tail", bench_tail(scenario, {"nominal": nominal, "aggressive": max(1, nominal // 2)}))
    print(f"the tail: each nonlinear planner (default solver) on {tail['tasks']} random tasks of seed "
          f"{tail['seed']} (nominal and aggressive; {tail['skipped']} aggressive tasks the linear plan cannot "
          f"meet left out), multiples of the linear plan of the same task; targets: 90th percentile <= 100, "
          f"largest <= 300")
    print(f"{'planner':<22} {'median x':>9} {'p90 x':>7} {'max x':>7} {'failed':>6}  slowest")
    for name in ("nonlinear_min_effort", "nonlinear_optimal"):
        row = tail[name]
        print(f"{name:<22} {row['median']:>9.0f} {row['p90']:>7.0f} {row['max']:>7.0f} {row['failed']:>6}  "
              f"{row['slowest']} ({row['slowest_s']:.2f} s)")


def _busy(record: Any) -> None:
    """`bench busy`: the public API's calls, quiet and beside a busy core."""
    from mjtraj.bench_busy import HELD_OUT_TASK, bench_busy

    print(f"the public API as a Python script calls it (a fresh interpreter, no thread variables set by mjtraj), "
          f"quiet and with a helper process spinning on one core, same run: seconds per plan of the task q0 = "
          f"{HELD_OUT_TASK[0]}, qg = {HELD_OUT_TASK[1]} and per UR5Track-v1 env.step; target: the linear "
          f"plan busy <= 1.2 times quiet")
    print(f"{'call':<22} {'quiet ms':>10} {'busy ms':>10} {'busy / quiet':>13}")
    for row in record("busy", bench_busy()):
        print(f"{row['call']:<22} {1e3 * row['quiet_s']:>10.3f} {1e3 * row['busy_s']:>10.3f} "
              f"{row['ratio']:>13.2f}")


def _loop(args: argparse.Namespace, scenario: Any, record: Any) -> None:
    """`bench loop`: the closed loop against raw mujoco.batch stepping, by batch size."""
    from mjtraj.bench import LOOP_SIZES, bench_loop

    print("closed loop (FF + PID + plant) vs raw mujoco.batch stepping, same run")
    print(f"{'scenarios':>9} {'raw steps/s':>12} {'loop steps/s':>13} {'ratio':>6}")
    for row in record("loop", bench_loop(scenario, tuple(args.sizes) if args.sizes else LOOP_SIZES)):
        print(f"{row['scenarios']:>9} {row['raw_steps_per_s']:>12.0f} {row['loop_steps_per_s']:>13.0f} "
              f"{row['ratio']:>6.2f}")


def _train(record: Any) -> None:
    """`bench train`: batched training against the same sub-envs stepped alone."""
    from mjtraj.bench import bench_train

    print("batched training (skrl's PPO on the native vector env, 512 sub-envs, the adaptive law, 32-step "
          "rollouts and their updates) vs the same sub-envs stepped alone, same run; target 10,000,000 steps "
          "<= 30 minutes with the default mixture")
    print(f"{'families':<28} {'envs':>5} {'train steps/s':>14} {'env alone/s':>12} {'ratio':>6} "
          f"{'10M steps, min':>15}")
    for row in record("train", bench_train()):
        print(f"{row['families']:<28} {row['envs']:>5} {row['train_steps_per_s']:>14.0f} "
              f"{row['env_steps_per_s']:>12.0f} {row['ratio']:>6.2f} {row['minutes_10M']:>15.1f}")


def _store(args: argparse.Namespace, record: Any) -> None:
    """`bench store`: a synthetic store's stages (export, audit), each in a fresh process."""
    from mjtraj.bench import bench_store
    from mjtraj.checks import positive_int

    store = record("store", bench_store(positive_int("rows", args.rows), store_stages(args.stages)))
    rows = store["rows"]
    print(f"store: a synthetic nominal sweep store of {rows} rows with the real schema (written in "
          f"{store['write_s']:.1f} s, {rows / store['write_s']:.0f} rows/s), then each stage alone in a fresh "
          "process (peak MB: it and its workers, summed); targets: export <= 300 MB peak and >= 50,000 "
          "rows/s; audit of 4,000,000 rows <= 4 GB peak and "
          "<= 5 min")
    print(f"{'stage':<18} {'wall s':>8} {'rows/s':>9} {'peak MB':>8} {'kB/row':>7}")
    for name, stage in store["stages"].items():
        print(f"{name:<18} {stage['wall_s']:>8.1f} {rows / stage['wall_s']:>9.0f} {stage['peak_mb']:>8.0f} "
              f"{1024 * stage['peak_mb'] / rows:>7.2f}")


def _sweep(args: argparse.Namespace, record: Any) -> None:
    """`bench sweep`: a nominal sweep end to end, its stages and its floor."""
    from mjtraj.bench import bench_sweep

    sweep: dict[str, Any] = record("sweep", bench_sweep(args.scenarios, workers=args.workers))
    print(f"sweep: {args.scenarios} nominal scenarios x 4 planners end to end (plan, execute, metrics, write) on "
          f"{sweep['workers']} worker processes; target <= 20 s")
    print(f"{'wall s':>7} {'rows':>7} {'rows/s':>8}")
    print(f"{sweep['wall']:>7.1f} {sweep['rows']:>7} {sweep['rows'] / sweep['wall']:>8.0f}")
    print("per stage, CPU seconds summed over workers (share of their total):")
    total = sum(sweep["stages"].values())
    for stage, seconds in sweep["stages"].items():
        print(f"  {stage:<8} {seconds:>7.1f} s {100 * seconds / total:>5.1f} %")
    print(f"floor: raw mujoco.batch stepping of the same {sweep['periods']} control periods on {sweep['workers']} "
          f"threads: {sweep['floor']:.1f} s; sweep / floor = {sweep['wall'] / sweep['floor']:.2f}")
    print(f"the driver's peak resident memory (this process; target <= 500 MB whatever the scenarios): "
          f"{sweep['driver_mb']:.0f} MB")


def _floor(scenario: Any, record: Any) -> None:
    """`bench floor`: the clairvoyant floor's solve time, then the control laws' periods."""
    from mjtraj.bench import bench_controllers, bench_floor

    print("the clairvoyant floor: solve time per scenario on one core (seed 1, cubic reference, the best-ranked of "
          "the laws' starts; every start: mjtraj floor --every-start); target median <= 0.2 s")
    print(f"{'family':>11} {'scenarios':>10} {'floored':>8} {'median s':>9} {'p90 s':>7} {'max s':>7}")
    for row in record("floor", bench_floor(scenario)):
        print(f"{row['family']:>11} {row['scenarios']:>10} {row['floored']:>8} {row['median_s']:>9.3f} "
              f"{row['p90_s']:>7.3f} {row['max_s']:>7.3f}")
    print("control laws: one closed-loop period on one simulation (the law and the plant's step), 5 mismatch "
          "scenarios; target mpc median <= 0.5 of the control period")
    print(f"{'law':>25} {'median ms':>10} {'p90 ms':>7} {'of period':>10}")
    for row in record("controllers", bench_controllers(scenario)):
        print(f"{row['law']:>25} {row['median_ms']:>10.3f} {row['p90_ms']:>7.3f} {row['of_period']:>10.3f}")
    from mjtraj.bench import bench_predictive

    print("the predictive laws on protocol v2's episodes (motion and 0.5 s settle window), one simulation on one "
          "core, 3 scenarios per family; target: the worst period below the control period at 20 ms")
    print(f"{'law':>13} {'period ms':>10} {'family':>11} {'median ms':>10} {'p99 ms':>7} {'worst ms':>9} "
          f"{'worst / period':>15} {'QP median ms':>13} {'QP worst ms':>12}")
    for row in record("predictive", bench_predictive(scenario)):
        print(f"{row['law']:>13} {row['period_ms']:>10.0f} {row['family']:>11} {row['median_ms']:>10.2f} "
              f"{row['p99_ms']:>7.2f} {row['max_ms']:>9.2f} {row['worst_of_period']:>15.2f} "
              f"{row['qp_median_ms']:>13.3f} {row['qp_max_ms']:>12.3f}")
    from mjtraj.bench import bench_labels

    print("the predictive laws as teachers: labels per second (loop.teach beside the adaptive law in a native vector "
          "env of 16 mismatch sub-envs, protocol v2, one core), the env's own steps per second in the same run, and "
          "the minutes a million labels take")
    print(f"{'teacher':>13} {'envs':>5} {'labels/s':>9} {'env steps/s':>12} {'min / 1M':>9}")
    for row in record("labels", bench_labels()):
        print(f"{row['law']:>13} {row['envs']:>5} {row['labels_per_s']:>9.0f} {row['env_steps_per_s']:>12.0f} "
              f"{row['minutes_1M']:>9.1f}")


def _startup(record: Any) -> None:
    """`bench startup`: `mjtraj compare`'s start against the bare imports."""
    from mjtraj.bench import bench_startup

    start = record("startup", bench_startup())
    print("mjtraj compare on the paper scenario (no figures), imports included, vs python -c \"import mujoco, "
          "gymnasium, scipy\" (and with scipy.linalg, which compare needs), fresh interpreters, same run; target "
          "ratio <= 1.5")
    print(f"{'imports s':>10} {'+ scipy.linalg s':>17} {'compare s':>10} {'ratio':>6} {'ratio to + linalg':>18}")
    print(f"{start['imports_s']:>10.2f} {start['linalg_s']:>17.2f} {start['compare_s']:>10.2f} "
          f"{start['ratio']:>6.2f} {start['ratio_linalg']:>18.2f}")


def _env(record: Any) -> None:
    """`bench env`: env.step and the vector env against raw stepping, then rendering."""
    from mjtraj.bench import bench_env, bench_render, bench_vector_env

    row = record("env", bench_env())
    print("UR5Track-v0 env.step in pid mode through gym.make (default wrappers) vs a raw mj_step loop at rest and "
          "replaying the env's own motion (its start state and torques), same run; target ratio >= 0.4")
    print(f"{'raw at rest/s':>14} {'raw replay/s':>13} {'env.step/s':>11} {'ratio':>6} {'to replay':>10}")
    print(f"{row['raw_steps_per_s']:>14.0f} {row['replay_steps_per_s']:>13.0f} {row['env_steps_per_s']:>11.0f} "
          f"{row['ratio']:>6.2f} {row['ratio_replay']:>10.2f}")
    print("vector env (vector_entry_point) vs raw mujoco.batch stepping at rest and replaying the env's motions, "
          "same run; target ratio >= 0.85 at 1024")
    print(f"{'envs':>6} {'raw at rest/s':>14} {'raw replay/s':>13} {'env steps/s':>12} {'ratio':>6} "
          f"{'to replay':>10}")
    for row in record("vector_env", bench_vector_env()):
        print(f"{row['envs']:>6} {row['raw_steps_per_s']:>14.0f} {row['replay_steps_per_s']:>13.0f} "
              f"{row['env_steps_per_s']:>12.0f} {row['ratio']:>6.2f} {row['ratio_replay']:>10.2f}")
    print("rendering: env.render() frames/s of UR5Track-v0 (executed arm + ghost) at render_quality fast "
          "(default) and high, and of Gymnasium's Reacher-v5, same run; targets fast / Reacher-v5 >= 0.5, "
          "high / Reacher-v5 >= 0.1 at 640x480")
    print(f"{'size':>9} {'backend':>8} {'fast':>7} {'high':>7} {'Reacher-v5':>11} {'fast / R':>9} "
          f"{'high / R':>9}")
    for f in record("render", bench_render()):
        print(f"{f['size']:>9} {f['backend']:>8} {f['fast_fps']:>7.1f} {f['high_fps']:>7.1f} "
              f"{f['reacher_fps']:>11.1f} {f['ratio']:>9.2f} {f['high_ratio']:>9.2f}")
