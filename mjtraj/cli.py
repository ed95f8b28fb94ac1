"""The `mjtraj` command: parses, calls the library, writes files. `main(argv) -> exit code`."""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import re
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from mjtraj.exceptions import InvalidInputError, MjtrajError
from mjtraj.rl.protocol import PROTOCOL_V1

BENCH_ALL = ("plan", "planners", "busy", "loop", "floor", "startup", "env")
"""What a bare `mjtraj bench` runs, in order."""
BENCH_ALL_MINUTES = 9
"""How long a bare `mjtraj bench` took on the 2-core development machine (docs/speed.md), minutes."""
TAIL_TASKS = {"nominal": 200, "aggressive": 100}
"""`bench planners`' tail table: random tasks per family (mjtraj.bench.bench_tail)."""

log = logging.getLogger(__name__)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        self.exit(2, f"mjtraj: error: {message}\n")


def _floats(text: str) -> list[float]:
    try:
        return [float(x) for x in text.replace(",", " ").split()]
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from e


def _figure_formats(text: str) -> list[str]:
    from mjtraj.study.plots import FIGURE_FORMATS

    kinds = [k.strip() for k in text.split(",")]
    unknown = [k for k in kinds if k not in FIGURE_FORMATS]
    if unknown or not text:
        raise argparse.ArgumentTypeError(f"expected {', '.join(FIGURE_FORMATS)} (comma-separated), got {text!r}")
    return list(dict.fromkeys(kinds))


STORE_STAGE_NAMES = {"csv": "export .csv", "jsonl": "export .jsonl", "sqlite": "export .sqlite",
                     "audit": "audit --no-tasks"}


def _store_stages(text: str) -> list[str]:
    """`bench store --stages`: names of mjtraj.bench.STORE_STAGES from their short names."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in STORE_STAGE_NAMES]
    if unknown or not names:
        raise InvalidInputError(f"stages: expected some of {', '.join(STORE_STAGE_NAMES)}, comma-separated, got "
                                f"{text!r}")
    return [STORE_STAGE_NAMES[n] for n in names]


def _counts(text: str) -> list[int]:
    try:
        values = [int(x) for x in text.split(",")]
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected whole numbers separated by commas, got {text!r}") from e
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected whole numbers >= 1, got {text!r}")
    return values


NEGATIVE = re.compile(r"-\.?\d")


class _Progress:
    """A tqdm bar on stderr driven by progress(done, total) callbacks; off with --no-progress or when stderr is
    not a terminal."""

    def __init__(self, desc: str, unit: str, enabled: bool) -> None:
        from tqdm import tqdm

        self.bar = tqdm(desc=desc, unit=unit, file=sys.stderr, leave=False, disable=None if enabled else True)

    def __call__(self, done: int, total: int) -> None:
        self.bar.total = total
        self.bar.update(done - self.bar.n)

    def __enter__(self) -> _Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.bar.close()


def _overrides(file: Path | None, pairs: list[str], what: str = "hyperparameter") -> dict[str, Any]:
    """rl train's hyperparameter overrides (or rl eval's policy env settings, `what`): the JSON object in `file`,
    then each NAME=VALUE of `pairs` (VALUE as JSON, else a string)."""
    out: dict[str, Any] = {}
    if file is not None:
        try:
            loaded = json.loads(file.read_text())
        except (OSError, ValueError) as e:
            raise InvalidInputError(f"hyperparameters: cannot read {file} as JSON ({e})") from e
        if not isinstance(loaded, dict):
            raise InvalidInputError(f"hyperparameters: expected a JSON object in {file}, got {type(loaded).__name__}")
        out.update(loaded)
    for pair in pairs:
        name, sep, text = pair.partition("=")
        if not sep or not name:
            raise InvalidInputError(f"{what}: expected NAME=VALUE, got {pair!r}")
        try:
            out[name] = json.loads(text)
        except ValueError:
            out[name] = text
    return out
"""A value that starts like a negative number ('-6.28,0,0'), which argparse would take for an option."""


def _join_negative_values(argv: Sequence[str]) -> list[str]:
    """`--q0 -6.28,0,0` as `--q0=-6.28,0,0`, so that argparse reads the value as one."""
    out: list[str] = []
    for token in argv:
        if out and out[-1].startswith("--") and "=" not in out[-1] and NEGATIVE.match(token):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def _names(text: str) -> list[str]:
    names = [x.strip() for x in text.split(",")]
    if not text.strip() or any(not x for x in names):
        raise argparse.ArgumentTypeError(f"expected comma-separated names without empty ones, got {text!r}")
    return names


def _loop_flags(parser: argparse.ArgumentParser) -> None:
    """A flag per declared loop option (mjtraj.core.closed_loop.LoopConfig), overriding the scenario's value."""
    from mjtraj.core import LoopConfig, declared_options

    for f, declaration, kind in declared_options(LoopConfig, scenario_only=True):
        flags = [f"--{f.name.replace('_', '-')}"] + ([declaration.flag] if declaration.flag else [])
        valid = declaration.choices if isinstance(declaration.choices, tuple) else None  # not plug-ins: no import
        choices = f" ({' | '.join(map(str, valid))})" if valid else ""
        parser.add_argument(*flags, dest=f.name, type=kind, help=f"{declaration.help}{choices}; default: the "
                            "scenario's")


def _parser() -> argparse.ArgumentParser:
    from mjtraj.core import controller_names
    from mjtraj.versions import __version__

    laws = ", ".join(controller_names())  # help from the registry: it cannot drift from what runs

    parser = _Parser(prog="mjtraj", description="How the trajectory planner changes closed-loop execution.")
    parser.add_argument("--version", action="version", version=f"mjtraj {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)

    c = sub.add_parser("compare", help="the paper's Table I: every planner through one closed loop")
    c.add_argument("--config", type=Path, help="scenario TOML (default: the shipped paper scenario)")
    c.add_argument("--model", type=Path, help="your MJCF arm instead of the UR5 (its scenario follows the stated "
                   "rules: mjtraj.core.arm.ARM_RULES, mjtraj.study.scenario.ARM_TASK_RULE)")
    c.add_argument("--torque-limit", type=_floats, help="with --model: the corrective saturation, N m: one "
                   "value for every joint, or one per joint, comma-separated (default: from the model's actuators)")
    c.add_argument("--q0", type=_floats, help="start, rad, comma-separated")
    c.add_argument("--qg", type=_floats, help="goal, rad, comma-separated")
    c.add_argument("--duration", type=float, help="T, s (a whole number of dt)")
    c.add_argument("--dt", type=float, help="control period, s")
    _loop_flags(c)
    c.add_argument("--planners", type=_names, help="comma-separated planner names (default: all)")
    c.add_argument("--out", type=Path, help="output folder (default: results/, or results/MODEL/ with --model, "
                   "MODEL the file's name without .xml)")
    c.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    c.add_argument("--no-figures", action="store_true", help="skip the figures")
    c.add_argument("--figure-format", dest="figure_format", type=_figure_formats, default=["png"],
                   help="figure formats, comma-separated: png, pdf, svg (default png)")

    f = sub.add_parser("frontier", help="the optimal planner over its weight frontier (Q = alpha Q_bryson), beside the "
                       "other planners, by the scenario's fixed score")
    f.add_argument("--config", type=Path, help="scenario TOML (default: the shipped paper scenario)")
    f.add_argument("--model", type=Path, help="your MJCF arm instead of the UR5 (docs/design.md, \"Your own arm\")")
    f.add_argument("--torque-limit", type=_floats, help="with --model: the corrective saturation, N m: one "
                   "value for every joint, or one per joint, comma-separated (default: from the model's actuators)")
    f.add_argument("--q0", type=_floats, help="start, rad, comma-separated (default: the scenario's)")
    f.add_argument("--qg", type=_floats, help="goal, rad, comma-separated (default: the scenario's)")
    f.add_argument("--duration", type=float, help="T, s (a whole number of dt; default: the scenario's)")
    f.add_argument("--alphas", type=_floats, help="alpha values (default: 0 and 33 values from 1e-6 to 1e2)")
    f.add_argument("--splits", type=_floats, help="shares of the state weight on positions, in [0, 1] (default 0.5, "
                   "Bryson's balance)")
    f.add_argument("--family", help="nominal | aggressive | mismatch: medians over a family's scenarios instead of "
                   "the scenario's task")
    f.add_argument("--scenarios", type=int, help="scenarios of --family (default 100)")
    f.add_argument("--seed", type=int, help="seed of --family's scenarios (default 0)")
    f.add_argument("--out", type=Path, default=Path("results"), help="output folder (default: results/)")
    f.add_argument("--json", action="store_true", help="print the rows as JSON on stdout")
    f.add_argument("--no-figures", action="store_true", help="skip the frontier figure")
    f.add_argument("--no-progress", action="store_true", help="no progress bar")

    u = sub.add_parser("tune", help="tune every planner's free parameters with an equal, held-out budget; writes a "
                       "scenario file with the tuned options and the tuning record")
    u.add_argument("--config", type=Path, help="base scenario TOML (default: the shipped paper scenario)")
    u.add_argument("--model", type=Path, help="your MJCF arm instead of the UR5 (docs/design.md, \"Your own arm\")")
    u.add_argument("--torque-limit", type=_floats, help="with --model: the corrective saturation, N m: one "
                   "value for every joint, or one per joint, comma-separated (default: from the model's actuators)")
    u.add_argument("--planners", type=_names, default=["optimal", "trapezoidal", "scurve"],
                   help="planners to tune (default optimal, trapezoidal, scurve; cubic and quintic have no parameters)")
    u.add_argument("--family", default="nominal", help="family whose rules draw the training scenarios (default "
                   "nominal)")
    u.add_argument("--scenarios", type=int, default=50, help="training scenarios (default 50)")
    u.add_argument("--seed", type=int, default=0, help="seed of the training scenarios and of the optimiser")
    u.add_argument("--budget", type=int, default=32, help="evaluations per planner (default 32)")
    u.add_argument("--on-task", action="store_true", help="oracle mode: tune on the scenario's own task (labelled; "
                   "not a held-out result)")
    u.add_argument("--gains", action="store_true", help="tune the control law's parameters instead: the PID gains "
                   "(factors on kp, ki, kd, log-uniform in [1/4, 4]) or, with --config paper_adaptive.toml, the "
                   "adaptive law's adaptation rate (log-uniform in [1e-4, 1]); cubic references; --planners and "
                   "--on-task do not apply; a PID file is rl eval's --tuned-gains baseline")
    u.add_argument("--no-progress", action="store_true", help="no progress bar")
    u.add_argument("--out", type=Path, default=Path("tuned.toml"), help="the tuned scenario file (default "
                   "tuned.toml)")

    b = sub.add_parser("bench", help="speed ratios measured in one run")
    b.add_argument("what", choices=("plan", "planners", "busy", "loop", "floor", "env", "startup", "sweep", "store",
                                    "all"),
                   nargs="?", default="all",
                   help="what to time ('all' skips the minute-long sweep and the store)")
    b.add_argument("--config", type=Path, help="scenario TOML (default: the shipped paper scenario)")
    b.add_argument("--sizes", type=_counts, help="loop batch sizes, comma-separated whole numbers >= 1")
    b.add_argument("--scenarios", type=int, default=10_000, help="sweep: nominal scenarios (default 10000)")
    b.add_argument("--planner-scenarios", type=int, default=12,
                   help="planners: nominal scenarios each nonlinear planner plans with both solvers (default 12)")
    b.add_argument("--tail-tasks", dest="tail_tasks", type=int, default=TAIL_TASKS["nominal"],
                   help="planners: random nominal tasks of the tail table, and half as many aggressive ones (default "
                   f"{TAIL_TASKS['nominal']})")
    b.add_argument("--workers", type=int, help="sweep: worker processes (default: all cores)")
    b.add_argument("--rows", type=int, default=100_000, help="store: rows of the synthetic store (default 100000)")
    b.add_argument("--stages", default="csv,jsonl,sqlite,audit",
                   help="store: what to time, comma-separated: csv, jsonl, sqlite (export to them), audit "
                   "(default all)")

    w = sub.add_parser("sweep", help="every planner on many seeded scenarios; rows committed unit by unit to a "
                       "SQLite store (resumable)")
    w.add_argument("--family", dest="families", type=_names, default=["nominal"],
                   help="nominal, aggressive and/or mismatch, comma-separated (default nominal)")
    w.add_argument("--scenarios", type=int, default=1000, help="scenarios per family (default 1000)")
    w.add_argument("--seed", type=int, default=0, help="the sweep's seed (default 0)")
    w.add_argument("--planners", type=_names, help="planners and variants, comma-separated (default: optimal, cubic, "
                   "quintic, trapezoidal; variants: optimal_start, min_effort)")
    w.add_argument("--ff-accel", dest="ff_accel", type=_names, default=["sample"],
                   help="feedforward acceleration modes to run: sample and/or step_average (default sample)")
    w.add_argument("--gravity-comp", dest="gravity_comp", type=_names, default=["native"],
                   help="gravity compensation modes to run: native and/or zoh (default native)")
    w.add_argument("--model-error", action="store_true",
                   help="also measure the linear model's open-loop prediction error of optimal-type planners")
    w.add_argument("--sensor-noise", type=float, default=0.0, help="mismatch: position noise std, rad (default 0)")
    w.add_argument("--delay", type=int, default=0, help="mismatch: actuation delay, control periods, 0 or 1")
    w.add_argument("--batch", type=int, default=250, help="scenarios per unit of work (default 250)")
    w.add_argument("--config", help="base scenario TOML: controller and planner options (default: paper.toml)")
    w.add_argument("--model", help="your MJCF arm instead of the UR5")
    w.add_argument("--torque-limit", type=_floats, help="with --model: the corrective saturation, N m: one "
                   "value for every joint, or one per joint, comma-separated (default: from the model's actuators)")
    w.add_argument("--out", type=Path, default=Path("sweep.sqlite"), help="results: a SQLite store (.sqlite, "
                   ".sqlite3 or .db; one transaction per unit) or a CSV file (any other suffix); default "
                   "sweep.sqlite")
    w.add_argument("--resume", action="store_true", help="continue an interrupted sweep in --out")
    w.add_argument("--backend", default="local", help="local (process pool) or ray (default local)")
    w.add_argument("--workers", type=int, help="local worker processes, or CPUs of a local Ray (default: all)")
    w.add_argument("--ray-address", help="Ray cluster HOST:PORT, ray://HOST:PORT or auto (default: a local Ray)")
    w.add_argument("--no-progress", action="store_true", help="no progress bar")

    x = sub.add_parser("export", help="a complete sweep (store or CSV) as a typed SQLite table, JSON Lines or CSV")
    x.add_argument("sweep", type=Path, help="the sweep: its SQLite store or CSV file")
    x.add_argument("--out", type=Path, required=True, help="output: FILE.sqlite (or .db), FILE.jsonl or FILE.csv")
    x.add_argument("--workers", type=int, help="processes that export a store in parts (default: one per CPU, at "
                   "most 4 and one per 100,000 rows; the output is the same)")
    x.add_argument("--no-progress", action="store_true", help="no progress bar")

    a = sub.add_parser("audit", help="check the paper's claims against sweep files; writes AUDIT.md and figures")
    a.add_argument("sweeps", nargs="+", type=Path, help="sweep results: SQLite stores or CSV files")
    a.add_argument("--out", type=Path, default=Path("results/AUDIT.md"), help="output Markdown (default "
                   "results/AUDIT.md)")
    a.add_argument("--partial", action="store_true", help="audit the complete units of an unfinished sweep (and say "
                   "what is missing) instead of refusing it")
    a.add_argument("--no-tasks", action="store_true", help="skip the paper task, its reverse and the weight frontier "
                   "(computed at audit time from each file's settings)")
    a.add_argument("--no-progress", action="store_true", help="no progress display")

    r = sub.add_parser("render", help="execution videos per planner, a side-by-side clip and the Fig. 1 snapshot strip")
    r.add_argument("--config", type=Path, help="scenario TOML (default: the shipped paper scenario)")
    r.add_argument("--model", type=Path, help="your MJCF arm instead of the UR5 (docs/design.md, \"Your own arm\")")
    r.add_argument("--torque-limit", type=_floats, help="with --model: the corrective saturation, N m: one "
                   "value for every joint, or one per joint, comma-separated (default: from the model's actuators)")
    r.add_argument("--q0", type=_floats, help="start, rad, comma-separated (default: the scenario's)")
    r.add_argument("--qg", type=_floats, help="goal, rad, comma-separated (default: the scenario's)")
    r.add_argument("--duration", type=float, help="T, s (a whole number of dt; default: the scenario's)")
    r.add_argument("--planners", type=_names, help="comma-separated planner names (default: all)")
    r.add_argument("--format", dest="formats", type=_names, default=["mp4"], help="mp4 and/or gif (default: mp4)")
    r.add_argument("--width", type=int, default=640, help="image width, px (default 640)")
    r.add_argument("--height", type=int, default=480, help="image height, px (default 480)")
    r.add_argument("--camera", default="front", help="a camera of the model (the UR5: front, side, top) or free (a "
                   "free camera framed on the model); default front, or free on a model without it")
    r.add_argument("--quality", default="fast", help="fast: no shadows or floor reflection, fewer facets (default); "
                   "high: the model's own scene, for publication frames")
    r.add_argument("--every", type=int, default=1, help="keep one control period in EVERY (default 1)")
    r.add_argument("--out", type=Path, default=Path("results/videos"), help="output folder (default: "
                   "results/videos/)")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")

    sub.add_parser("doctor", help="which OpenGL backends render here, and the library versions")

    rl = sub.add_parser("rl", help="RL tracking policies: train on the UR5Track-v1 envs (the rl extra), score any "
                        "policy by the benchmark protocol beside the planners and control laws")
    rl.set_defaults(print_help=rl.print_help)  # a bare `mjtraj rl` lists its commands
    rl_sub = rl.add_subparsers(dest="rl_command", parser_class=_Parser)
    t = rl_sub.add_parser("train", help="train an SB3 agent on the vectorised env; checkpoints, learning curve, "
                          "run.json")
    t.add_argument("--algo", default="sac", help="sac | ppo | td3 | recurrent_ppo (sb3-contrib's LSTM PPO: "
                   "memory across an episode) (default sac)")
    t.add_argument("--action-mode", dest="action_mode", default="residual",
                   help="residual (added to feedforward + PID) | torque (the whole corrective torque); default "
                   "residual")
    t.add_argument("--residual-scale", dest="residual_scale", type=float,
                   help="N m per unit of action in residual mode (default 6: PID's median per-joint RMS feedback "
                   "torque on the mismatch family)")
    t.add_argument("--observe-control", dest="observe_control", action="store_true",
                   help="the policy also observes the PID integral and the next feedforward torque")
    t.add_argument("--observe-plant", dest="observe_plant", default="none",
                   help="none | true: the policy also observes the plant's payload, damping and friction (a "
                   "privileged teacher, labelled so in rl eval) | estimate: the adaptive law's online estimate of "
                   "them (deployable; --controller adaptive_computed_torque) (default none)")
    t.add_argument("--history", type=int, default=0, help="previous observations the policy also sees, latest "
                   "first (default 0)")
    t.add_argument("--observation-scaling", dest="observation_scaling", default="running",
                   help="running (VecNormalize's running statistics) | fixed (errors as the PID torque they make, "
                   "in units of the residual scale; positions by pi rad, velocities by pi rad/s; docs/design.md) "
                   "(default running)")
    t.add_argument("--reward-baseline", dest="reward_baseline", default="none",
                   help="none | pid: train on the advantage over PID alone on the same episode (a shadow run); "
                   "validation and evaluation still score J_exec (default none)")
    t.add_argument("--plant-randomization", dest="plant_randomization", default="none",
                   help="none | mismatch: train and validate on plants drawn by the mismatch family's rules "
                   "(default none)")
    t.add_argument("--planner", default="cubic", help="planner whose references the policy tracks (default cubic)")
    t.add_argument("--controller", default="pid", help=f"control law the residual acts on: {laws} (or a "
                   "registered plug-in law; default pid)")
    t.add_argument("--task", default="random", help="random (a new move each episode) | paper (default random)")
    t.add_argument("--steps", type=int, default=100_000, help="environment steps (default 100000)")
    t.add_argument("--seed", type=int, default=0, help="the run's seed, 0 <= seed < 2^32 (default 0)")
    t.add_argument("--num-envs", dest="num_envs", type=int, help="sub-envs (default: 4 for sac/td3, 8 for ppo)")
    t.add_argument("--checkpoints", type=int, default=5, help="checkpoints along the run (default 5)")
    t.add_argument("--evaluations", type=int, default=20, help="validation points of the learning curve (default 20)")
    t.add_argument("--validation", type=int, default=32, help="validation tasks (default 32)")
    t.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads (default 1, as in the Python API: "
                   "small networks run fastest on one, and runs can go side by side; recorded in run.json)")
    t.add_argument("--hyperparameter", dest="hyperparameter", action="append", default=[], metavar="NAME=VALUE",
                   help="an SB3 argument replacing the default (VALUE as JSON, else a string); repeat for several")
    t.add_argument("--hyperparameters", type=Path, metavar="FILE",
                   help="a JSON object of SB3 arguments replacing the defaults (--hyperparameter wins)")
    t.add_argument("--out", type=Path, default=Path("runs/rl"), help="output folder (default runs/rl)")
    t.add_argument("--resume", type=Path, metavar="RUN", help="continue the interrupted run in RUN from its last "
                   "checkpoint, with the settings its run.json records (the other training flags are not read); on "
                   "the same machine and thread count it ends with the policy an uninterrupted run would have")
    t.add_argument("--tensorboard", type=Path, metavar="DIR",
                   help="also log to TensorBoard event files in DIR (SB3's logger; needs the tensorboard package)")
    t.add_argument("--no-progress", action="store_true", help="no progress bar")
    p = rl_sub.add_parser("plot", help="redraw a run's learning_curve.png from its learning_curve.csv (also of a run "
                          "still going or interrupted)")
    p.add_argument("run", type=Path, help="the folder rl train wrote")
    e = rl_sub.add_parser("eval", help="the benchmark protocol: any policies beside the planners under every control "
                          "law on the same held-out scenarios; eval.csv, summary.json, SUMMARY.md, profiles.png")
    e.add_argument("--policy", dest="policies", action="append", default=[],
                   help="PATH.zip (rl train's), baseline:NAME (mjtraj rl baselines), MODULE:ATTR or FILE.py:ATTR (a "
                   "callable or torch module; docs/benchmark.md); repeat for several; none: the classical methods")
    e.add_argument("--baselines", action="store_true", help="also score every shipped baseline (mjtraj rl baselines)")
    e.add_argument("--policy-env", dest="policy_env", action="append", default=[], metavar="KEY=VALUE",
                   help="an env setting for policies that are not zips and do not declare it (planner, controller, "
                   "action_mode, residual_scale, observe_control, preview, observe_plant, history; default "
                   "UR5Track-v1's); repeatable")
    e.add_argument("--family", type=_names, default=list(PROTOCOL_V1["families"]),
                   help="families, comma-separated: nominal, aggressive, mismatch (default all three, protocol v1)")
    e.add_argument("--scenarios", type=int, default=PROTOCOL_V1["scenarios"],
                   help="held-out scenarios per family (default 200, protocol v1)")
    e.add_argument("--seed", type=int, default=PROTOCOL_V1["seed"],
                   help="the scenarios' seed (default 1, protocol v1: held out from sweeps and training, seed 0); "
                   "any other family, count, seed or --reps is stamped off-protocol in SUMMARY.md and summary.json")
    e.add_argument("--planners", type=_names, default=["cubic"],
                   help="planners scored under each control law (cubic, the reference's, always; default cubic)")
    e.add_argument("--controllers", type=_names, default=["pid"],
                   help=f"control laws the planners run under, comma-separated: {laws} or registered plug-ins "
                   "(pid always; each policy also runs on its own)")
    e.add_argument("--tuned-gains", dest="tuned_gains", type=Path,
                   help="a scenario file from `mjtraj tune --gains`, scored as 'cubic+PID (tuned gains)'")
    e.add_argument("--floor", action="store_true", help="also compute each scenario's clairvoyant floor and read "
                   "every method against it and against the strongest classical method (floor.csv; mismatch floors "
                   "take about 4 s a scenario)")
    e.add_argument("--reps", type=int, default=PROTOCOL_V1["reps"],
                   help="bootstrap resamples per interval (default 2000, protocol v1)")
    e.add_argument("--threads", type=int, default=1, help="PyTorch CPU threads (default 1, the rule of rl train)")
    e.add_argument("--out", type=Path, default=Path("rl_eval"), help="output folder (default rl_eval/)")
    e.add_argument("--no-progress", action="store_true", help="no progress bar")
    rl_sub.add_parser("baselines", help="list the shipped trained policies (use them as --policy baseline:NAME)")
    best = rl_sub.add_parser("best", help="choose baseline:best on validation scenarios (never evaluation ones) by "
                             "the stated rule and write it, with every score, into the baselines' BEST.json")
    best.add_argument("--scenarios", type=int, default=100, help="validation scenarios per family (default 100)")
    best.add_argument("--no-progress", action="store_true", help="no progress bar")
    h = rl_sub.add_parser("ship", help="ship a run's policy as a baseline: its zip without optimiser states (the same "
                          "actions, checked), its record and run.json")
    h.add_argument("run", type=Path, help="the folder rl train wrote")
    h.add_argument("--name", required=True, help="the baseline's name (letters, digits, _ and -)")
    h.add_argument("--which", default="best", help="best (selected on validation; default) | policy (the final one)")
    h.add_argument("--into", type=Path, help="folder of baselines (default: the package's own, mjtraj/rl/baselines)")
    h.add_argument("--student", action="store_true", help="ship a privileged teacher (--observe-plant true on the "
                   "adaptive law) as its deployable student: the same weights observing the adaptive law's estimate")

    g = sub.add_parser("gains", help="derive the default PID gains and optimal weights by their stated rules")
    g.add_argument("--config", type=Path, help="scenario TOML whose task to use (default: the paper scenario)")

    fl = sub.add_parser("floor", help="the clairvoyant floor of J_exec: the least any controller can score on each "
                        "scenario (true plant, torques within the saturation, the goal reached), beside the control "
                        "laws' own scores")
    fl.add_argument("--config", type=Path, help="scenario TOML (default: the paper scenario)")
    fl.add_argument("--family", choices=("nominal", "aggressive", "mismatch"), default="nominal",
                    help="the scenarios' family, drawn as sweeps draw them (default nominal)")
    fl.add_argument("--scenarios", type=_scenario_range, default=range(0, 20),
                    help="how many (K: 0..K-1) or which (A:B, B excluded) scenarios (default 20)")
    fl.add_argument("--seed", type=int, default=1, help="the family's seed (default 1: the held-out scenarios)")
    fl.add_argument("--planner", default="cubic", help="the planner whose reference is executed (default cubic)")
    fl.add_argument("--out", type=Path, help="also write every record to this CSV file")
    fl.add_argument("--json", action="store_true", help="print the records and the summary as JSON")
    fl.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def _scenario(args: argparse.Namespace, *, workspace: bool = False):  # noqa: ANN202
    """The command's scenario: --config or --model, with the task and loop flags the command has applied."""
    from mjtraj.core import LoopConfig, option_names

    task = {k: getattr(args, k) for k in ("q0", "qg", "duration", "dt") if getattr(args, k, None) is not None}
    loop = {k: getattr(args, k) for k in option_names(LoopConfig) if getattr(args, k, None) is not None}
    if getattr(args, "model", None) is not None:
        scenario = _base_scenario(args, workspace=workspace, **task)
        return scenario.replace(loop=loop) if loop else scenario
    scenario = _base_scenario(args)
    return scenario.replace(task=task, loop=loop) if task or loop else scenario


def _base_scenario(args: argparse.Namespace, *, workspace: bool = False, **task: Any):  # noqa: ANN202
    """The scenario of --config, or of --model PATH by the arm rules (with `task` overrides), never both."""
    from mjtraj.study.scenario import load_scenario, scenario_for_model

    if getattr(args, "model", None) is None:
        if getattr(args, "torque_limit", None) is not None:
            raise InvalidInputError("torque-limit: only with --model (a scenario file sets torque_limit beside "
                                    "model)")
        return load_scenario(args.config)
    if args.config is not None:
        raise InvalidInputError("model, config: give one (a scenario file names its arm with model = \"PATH\")")
    return scenario_for_model(args.model, torque_limit=args.torque_limit, workspace=workspace, **task)


def _compare_out(args: argparse.Namespace) -> Path:
    """compare's output folder: --out, else results/ for the UR5 and results/MODEL/ for an arm file (its results
    beside the UR5's, never over them)."""
    if args.out is not None:
        return Path(args.out)
    return Path("results") / args.model.stem if args.model is not None else Path("results")


def _compare(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from mjtraj.files import write_text_atomic
    from mjtraj.study.comparison import compare, comparison_record
    from mjtraj.study.report import format_report, results_csv, write_series

    scenario = _scenario(args)
    scenario.task.check_limits(scenario.model)
    args.out = _compare_out(args)
    from mjtraj.study.comparison import default_planners

    # plans, execute, check, figures
    stages = len(args.planners or default_planners()) + 2 + (0 if args.no_figures else 1)
    with tqdm(total=stages, desc="mjtraj compare", file=sys.stderr, leave=False, disable=None) as bar:
        def progress(label: str) -> None:
            bar.set_postfix_str(label)
            bar.update(1)

        result = compare(scenario, args.planners, progress=progress)
        record = _json_safe(comparison_record(result))
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


def _frontier(args: argparse.Namespace) -> int:
    from mjtraj.files import write_text_atomic
    from mjtraj.study.frontier import DEFAULT_ALPHAS, DEFAULT_SPLITS, frontier
    from mjtraj.study.report import format_frontier

    for flag, value in (("--scenarios", args.scenarios), ("--seed", args.seed)):
        if value is not None and args.family is None:
            raise InvalidInputError(f"{flag}: only used with --family (without it the frontier is on the scenario's "
                                    f"task)")
    scenario = _scenario(args, workspace=args.family is not None)  # drawn tasks: gains over the workspace
    with _Progress("mjtraj frontier", "planner", not args.no_progress) as progress:
        result = frontier(scenario, alphas=args.alphas if args.alphas is not None else DEFAULT_ALPHAS,
                          splits=args.splits if args.splits is not None else DEFAULT_SPLITS, family=args.family,
                          scenarios=100 if args.scenarios is None else args.scenarios,
                          seed=0 if args.seed is None else args.seed, progress=progress)
    name = "frontier" if args.family is None else f"frontier_{args.family}"
    record = _json_safe({"setting": result.setting, "rows": [row.as_dict() for row in result.rows]})
    write_text_atomic(args.out / f"{name}.json", json.dumps(record, indent=2) + "\n")
    figure = None
    if not args.no_figures:
        from mjtraj.study.plots import frontier_figure

        figure = frontier_figure(result, args.out / f"{name}.png")
    if args.json:
        print(json.dumps(record, indent=2))
    else:
        print(format_frontier(result))
        print(f"\nwrote {args.out / (name + '.json')}" + (f" and {figure}" if figure else "") +
              ("" if figure or args.no_figures else " (no figure: no execution succeeded)"))
    return 0


def _tune(args: argparse.Namespace) -> int:
    from mjtraj.files import write_text_atomic
    from mjtraj.study.toml_text import dumps
    from mjtraj.study.tuning import tune

    base = _base_scenario(args, workspace=not args.on_task)  # drawn tasks: gains over the workspace
    if args.gains:
        from mjtraj.study.tuning import tune_gains

        with _Progress("mjtraj tune --gains", "point", not args.no_progress) as progress:
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
    with _Progress("mjtraj tune", "point", not args.no_progress) as progress:
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


def _bench(args: argparse.Namespace) -> int:
    from mjtraj.bench import LOOP_SIZES, bench_loop, bench_plan
    from mjtraj.study.scenario import load_scenario

    scenario = load_scenario(args.config)
    if args.what == "all":
        print(f"mjtraj bench: {', '.join(BENCH_ALL)} in turn (about {BENCH_ALL_MINUTES} minutes on two cores; "
              "`mjtraj bench sweep` and `mjtraj bench store` run on their own)", flush=True)
    if args.what in ("plan", "all"):
        print("optimal planner (linearise + solve; the exact active set on the banded KKT system, OSQP as "
              "fallback), median wall time; target N=100 <= 1 ms, N=800 <= 10 ms")
        print(f"{'N':>6} {'median ms':>10} {'ratio to N=100':>15}")
        for row in bench_plan(scenario):
            print(f"{row['N']:>6} {row['median_ms']:>10.2f} {row['ratio_to_first']:>15.2f}")
        from mjtraj.bench import QP_SOLVERS, bench_qp

        qp_rows = bench_qp(scenario)
        print(f"the same QP (N = {scenario.task.steps}), median wall time of the solve alone: mjtraj's banded-KKT "
              f"active set vs {', '.join(QP_SOLVERS)} on the condensed QP (the `bench` extra; those not installed are "
              f"left out); target: mjtraj at least 4 times faster than quadprog")
        print(f"{'solver':<28} {'median ms':>10} {'x mjtraj':>9} {'max |u - u_mjtraj| N m':>23}")
        for row in qp_rows:
            print(f"{row['solver']:<28} {1e3 * row['seconds']:>10.3f} {row['seconds'] / qp_rows[0]['seconds']:>9.2f} "
                  f"{row['max_diff']:>23.1e}")
    if args.what in ("planners", "all"):
        from mjtraj.bench import bench_new_planners
        from mjtraj.checks import positive_int

        new = bench_new_planners(scenario, scenarios=12 if args.what == "all" else
                                 positive_int("planner_scenarios", args.planner_scenarios))
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
        tail = bench_tail(scenario, {"nominal": nominal, "aggressive": max(1, nominal // 2)})
        print(f"the tail: each nonlinear planner (default solver) on {tail['tasks']} random tasks of seed "
              f"{tail['seed']} (nominal and aggressive; {tail['skipped']} aggressive tasks the linear plan cannot "
              f"meet left out), multiples of the linear plan of the same task; targets: 90th percentile <= 100, "
              f"largest <= 300")
        print(f"{'planner':<22} {'median x':>9} {'p90 x':>7} {'max x':>7} {'failed':>6}  slowest")
        for name in ("nonlinear_min_effort", "nonlinear_optimal"):
            row = tail[name]
            print(f"{name:<22} {row['median']:>9.0f} {row['p90']:>7.0f} {row['max']:>7.0f} {row['failed']:>6}  "
                  f"{row['slowest']} ({row['slowest_s']:.2f} s)")
    if args.what in ("busy", "all"):
        from mjtraj.bench_busy import HELD_OUT_TASK, bench_busy

        print(f"the public API as a Python script calls it (a fresh interpreter, no thread variables set by mjtraj), "
              f"quiet and with a helper process spinning on one core, same run: seconds per plan of the task q0 = "
              f"{HELD_OUT_TASK[0]}, qg = {HELD_OUT_TASK[1]} and per UR5Track-v1 env.step; target: the linear "
              f"plan busy <= 1.2 times quiet")
        print(f"{'call':<22} {'quiet ms':>10} {'busy ms':>10} {'busy / quiet':>13}")
        for row in bench_busy():
            print(f"{row['call']:<22} {1e3 * row['quiet_s']:>10.3f} {1e3 * row['busy_s']:>10.3f} "
                  f"{row['ratio']:>13.2f}")
    if args.what in ("loop", "all"):
        print("closed loop (FF + PID + plant) vs raw mujoco.batch stepping, same run")
        print(f"{'scenarios':>9} {'raw steps/s':>12} {'loop steps/s':>13} {'ratio':>6}")
        for row in bench_loop(scenario, tuple(args.sizes) if args.sizes else LOOP_SIZES):
            print(f"{row['scenarios']:>9} {row['raw_steps_per_s']:>12.0f} {row['loop_steps_per_s']:>13.0f} "
                  f"{row['ratio']:>6.2f}")
    if args.what == "store":
        from mjtraj.bench import bench_store
        from mjtraj.checks import positive_int

        store = bench_store(positive_int("rows", args.rows), _store_stages(args.stages))
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
    if args.what == "sweep":
        from mjtraj.bench import bench_sweep

        sweep: dict[str, Any] = bench_sweep(args.scenarios, workers=args.workers)
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
    if args.what in ("floor", "all"):
        from mjtraj.bench import bench_controllers, bench_floor

        print("the clairvoyant floor: solve time per scenario on one core (seed 1, cubic reference, four starts); "
              "target median <= 0.2 s")
        print(f"{'family':>11} {'scenarios':>10} {'floored':>8} {'median s':>9} {'p90 s':>7} {'max s':>7}")
        for row in bench_floor(scenario):
            print(f"{row['family']:>11} {row['scenarios']:>10} {row['floored']:>8} {row['median_s']:>9.3f} "
                  f"{row['p90_s']:>7.3f} {row['max_s']:>7.3f}")
        print("control laws: one closed-loop period on one simulation (the law and the plant's step), 5 mismatch "
              "scenarios; target mpc median <= 0.5 of the control period")
        print(f"{'law':>25} {'median ms':>10} {'p90 ms':>7} {'of period':>10}")
        for row in bench_controllers(scenario):
            print(f"{row['law']:>25} {row['median_ms']:>10.3f} {row['p90_ms']:>7.3f} {row['of_period']:>10.3f}")
    if args.what in ("startup", "all"):
        from mjtraj.bench import bench_startup

        start = bench_startup()
        print("mjtraj compare on the paper scenario (no figures), imports included, vs python -c \"import mujoco, "
              "gymnasium, scipy\" (and with scipy.linalg, which compare needs), fresh interpreters, same run; target "
              "ratio <= 1.5")
        print(f"{'imports s':>10} {'+ scipy.linalg s':>17} {'compare s':>10} {'ratio':>6} {'ratio to + linalg':>18}")
        print(f"{start['imports_s']:>10.2f} {start['linalg_s']:>17.2f} {start['compare_s']:>10.2f} "
              f"{start['ratio']:>6.2f} {start['ratio_linalg']:>18.2f}")
    if args.what in ("env", "all"):
        from mjtraj.bench import bench_env, bench_render, bench_vector_env

        row = bench_env()
        print("UR5Track-v0 env.step in pid mode through gym.make (default wrappers) vs a raw mj_step loop at rest and "
              "replaying the env's own motion (its start state and torques), same run; target ratio >= 0.4")
        print(f"{'raw at rest/s':>14} {'raw replay/s':>13} {'env.step/s':>11} {'ratio':>6} {'to replay':>10}")
        print(f"{row['raw_steps_per_s']:>14.0f} {row['replay_steps_per_s']:>13.0f} {row['env_steps_per_s']:>11.0f} "
              f"{row['ratio']:>6.2f} {row['ratio_replay']:>10.2f}")
        print("vector env (vector_entry_point) vs raw mujoco.batch stepping at rest and replaying the env's motions, "
              "same run; target ratio >= 0.85 at 1024")
        print(f"{'envs':>6} {'raw at rest/s':>14} {'raw replay/s':>13} {'env steps/s':>12} {'ratio':>6} "
              f"{'to replay':>10}")
        for row in bench_vector_env():
            print(f"{row['envs']:>6} {row['raw_steps_per_s']:>14.0f} {row['replay_steps_per_s']:>13.0f} "
                  f"{row['env_steps_per_s']:>12.0f} {row['ratio']:>6.2f} {row['ratio_replay']:>10.2f}")
        print("rendering: env.render() frames/s of UR5Track-v0 (executed arm + ghost) at render_quality fast "
              "(default) and high, and of Gymnasium's Reacher-v5, same run; targets fast / Reacher-v5 >= 0.5, "
              "high / Reacher-v5 >= 0.1 at 640x480")
        print(f"{'size':>9} {'backend':>8} {'fast':>7} {'high':>7} {'Reacher-v5':>11} {'fast / R':>9} "
              f"{'high / R':>9}")
        for f in bench_render():
            print(f"{f['size']:>9} {f['backend']:>8} {f['fast_fps']:>7.1f} {f['high_fps']:>7.1f} "
                  f"{f['reacher_fps']:>11.1f} {f['ratio']:>9.2f} {f['high_ratio']:>9.2f}")
    return 0


def _sweep_settings(args: argparse.Namespace):  # noqa: ANN202
    from mjtraj.study.sweep import DEFAULT_PLANNERS, SweepSettings

    return SweepSettings(families=tuple(args.families), scenarios=args.scenarios, seed=args.seed,
                         planners=tuple(args.planners or DEFAULT_PLANNERS), ff_accel=tuple(args.ff_accel),
                         gravity_comp=tuple(args.gravity_comp), batch=args.batch, sensor_noise=args.sensor_noise,
                         delay=args.delay, model_error=args.model_error, config=args.config, model=args.model,
                         torque_limit=args.torque_limit)


def _sweep(args: argparse.Namespace) -> int:
    from mjtraj.study.runner import run_sweep

    settings = _sweep_settings(args)
    report = run_sweep(settings, args.out, resume=args.resume, backend=args.backend, workers=args.workers,
                       ray_address=args.ray_address, progress=not args.no_progress)
    statuses = ", ".join(f"{k} {v}" for k, v in sorted(report.statuses.items())) or "none"
    print(f"wrote {report.rows} rows to {report.path} in {report.wall:.1f} s ({report.skipped_units} units were "
          f"already done); statuses: {statuses}")
    return 0


def _export(args: argparse.Namespace) -> int:
    from mjtraj.study.export import export

    with _Progress("mjtraj export", "row", not args.no_progress) as progress:
        rows = export(args.sweep, args.out, progress=progress, workers=args.workers)
    print(f"wrote {rows} rows of {args.sweep} to {args.out}")
    return 0


def _audit(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from mjtraj.study.audit import write_audit

    with tqdm(desc="mjtraj audit", unit="stage", file=sys.stderr, leave=False,
              disable=None if not args.no_progress else True) as bar:
        def stage(name: str) -> None:
            bar.set_description_str(f"mjtraj audit: {name}")
            bar.update(1)

        text = write_audit(args.sweeps, args.out, partial=args.partial, tasks=not args.no_tasks, progress=stage)
    verdicts = text.split("## Verdicts", 1)[1].split("\n\nVerdict rule")[0]
    print(verdicts.strip())
    print(f"\nwrote {args.out}")
    return 0


def _render(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from mjtraj.checks import choice, positive_int
    from mjtraj.media.render import RENDER_QUALITIES, check_render_options
    from mjtraj.media.videos import SNAPSHOT_TIMES, check_formats, render_all
    from mjtraj.study.comparison import compare, default_planners

    scenario = _scenario(args)
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


def _doctor(args: argparse.Namespace) -> int:
    from mjtraj.media import gl
    from mjtraj.versions import versions

    print("versions: " + ", ".join(f"{k} {v}" for k, v in versions().items()))
    user = gl.user_backend()
    chosen = user or gl.default_backend()
    print(f"python {sys.version.split()[0]}; MUJOCO_GL set by you: {user or '(unset)'}; renderers use: "
          f"{chosen or 'none found'}" + ("" if user else " (mjtraj's choice when MUJOCO_GL is unset: OSMesa if "
                                         "libOSMesa is present, else EGL)"))
    working = []
    for backend in gl.BACKENDS:
        ok, detail = gl.probe_backend(backend) if gl.library_present(backend) else (False, "library not found")
        print(f"  {backend:<7} {'works' if ok else 'fails'}: {detail}")
        if ok:
            working.append(backend)
    if not working:
        print(f"no OpenGL backend renders here: {gl.INSTALL_HINT}")
        return 1
    return 0


def _scenario_range(text: str) -> range:
    """--scenarios of `mjtraj floor`: K (0..K-1) or A:B."""
    first, sep, last = text.partition(":")
    try:
        span = range(int(first), int(last)) if sep else range(int(first))
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected K or A:B (integers), got {text!r}") from e
    if len(span) == 0 or span.start < 0:
        raise argparse.ArgumentTypeError(f"expected a non-empty range of indices >= 0, got {text!r}")
    return span


def _floor(args: argparse.Namespace) -> int:
    import csv

    import numpy as np

    from mjtraj.study.floor import family_floors
    from mjtraj.study.scenario import load_scenario

    scenario = load_scenario(args.config)
    records = []
    with _Progress("mjtraj floor", "scenario", not args.no_progress) as progress:
        for record in family_floors(scenario, args.family, seed=args.seed, scenarios=args.scenarios,
                                    planner=args.planner):
            records.append(record)
            progress(len(records), len(args.scenarios))
    ok = [r for r in records if r["status"] == "ok"]
    laws = [k[2:] for k in ok[0] if k.startswith("J_")] if ok else []
    summary: dict[str, Any] = {"family": args.family, "seed": args.seed, "planner": args.planner,
                               "scenarios": len(records), "floored": len(ok)}
    if ok:
        pid = np.array([r["J_pid"] for r in ok]) if "pid" in laws else None
        for law in laws:
            summary[f"mean J_{law}"] = float(np.mean([r[f"J_{law}"] for r in ok]))
        summary["mean floor"] = float(np.mean([r["floor"] for r in ok]))
        if pid is not None:
            summary["floor / cubic+PID (ratio of means)"] = summary["mean floor"] / float(np.mean(pid))
        summary["median floor / best law"] = float(np.median([r["floor_over_best"] for r in ok]))
        summary["median seconds"] = float(np.median([r["seconds"] for r in ok]))
        summary["largest terminal_err / goal radius"] = float(max(r["terminal_err"] / r["goal_radius"] for r in ok))
    if args.out is not None:
        names = list(dict.fromkeys(k for r in records for k in r))
        with open(args.out, "w", newline="") as handle:
            writer = csv.DictWriter(handle, names)
            writer.writeheader()
            writer.writerows({k: repr(v) if isinstance(v, float) else v for k, v in r.items()} for r in records)
    if args.json:
        print(json.dumps(_json_safe({"summary": summary, "records": records}), indent=2))
        return 0
    print(f"{'scenario':>8} " + " ".join(f"{'J ' + law:>26}" for law in laws) + f" {'floor':>10} {'/best':>6} "
          f"{'start':>24} {'s':>6}")
    for r in records:
        if r["status"] != "ok":
            print(f"{r['scenario']:>8} {r['status']}")
            continue
        print(f"{r['scenario']:>8} " + " ".join(f"{r['J_' + law]:>26.5g}" for law in laws)
              + f" {r['floor']:>10.5g} {r['floor_over_best']:>6.3f} {r['start']:>24} {r['seconds']:>6.2f}")
    print()
    for key, value in summary.items():
        print(f"{key}: {value:.4g}" if isinstance(value, float) else f"{key}: {value}")
    return 0


def _gains(args: argparse.Namespace) -> int:
    import numpy as np

    from mjtraj.core.gains import GAIN_RULE, gain_rule
    from mjtraj.core.scoring import bryson_weights
    from mjtraj.study.scenario import load_scenario

    scenario = load_scenario(args.config)
    model = scenario.model
    gains = gain_rule(model, scenario.task.q0, scenario.task.qg, scenario.task.dt)
    Q, R = bryson_weights(scenario.task, scenario.torque_limit)
    show = lambda a: "[" + ", ".join(repr(float(x)) for x in np.asarray(a)) + "]"  # noqa: E731
    print(f"# gain rule: {GAIN_RULE}")
    print(f"kp = {show(gains.kp)}\nki = {show(gains.ki)}\nkd = {show(gains.kd)}")
    print("# optimal planner weights, Bryson's rule (mjtraj.core.scoring.bryson_weights)")
    print(f"state_weight = {show(Q)}\ninput_weight = {show(R)}")
    return 0


def _rl(args: argparse.Namespace) -> int:
    if args.rl_command is None:
        args.print_help()
        return 0
    if args.rl_command == "plot":
        from mjtraj.rl.train import plot_run

        print(f"wrote {plot_run(args.run)}")
        return 0
    if args.rl_command == "train":
        from mjtraj.rl.extra import require_sb3

        require_sb3()
        from mjtraj.rl.train import TrainSettings, resume_training, train

        if args.resume is not None:
            report = resume_training(args.resume, progress=not args.no_progress, tensorboard=args.tensorboard)
            print(f"resumed {args.resume} and trained to {report.timesteps} steps; validation mean J_exec "
                  f"{report.final['cost_mean']:.4g}")
            print(f"wrote {report.policy}")
            return 0

        extra: dict[str, Any] = {} if args.residual_scale is None else {"residual_scale": args.residual_scale}
        extra["overrides"] = _overrides(args.hyperparameters, args.hyperparameter)
        extra["observe_control"] = args.observe_control
        extra["observe_plant"] = args.observe_plant
        extra["history"] = args.history
        extra["observation_scaling"] = args.observation_scaling
        extra["plant_randomization"] = args.plant_randomization
        extra["reward_baseline"] = args.reward_baseline
        settings = TrainSettings(algo=args.algo, action_mode=args.action_mode, **extra, planner=args.planner,
                                 controller=args.controller, task=args.task,
                                 steps=args.steps, seed=args.seed, num_envs=args.num_envs,
                                 checkpoints=args.checkpoints, evaluations=args.evaluations,
                                 validation=args.validation, threads=args.threads)
        report = train(settings, args.out, progress=not args.no_progress, tensorboard=args.tensorboard)
        final = report.final
        print(f"trained {report.timesteps} steps in {report.wall:.0f} s; validation mean J_exec "
              f"{final['cost_mean']:.4g} (median {final['cost_median']:.4g}, {final['diverged']} diverged)")
        print(f"wrote {report.policy}, {report.out / 'best.zip'} (best on validation), "
              f"{report.out / 'learning_curve.csv'}, {report.out / 'learning_curve.png'}, {report.out / 'run.json'} "
              f"and {report.out / 'checkpoints'}/")
        return 0
    if args.rl_command == "baselines":
        from mjtraj.rl.baselines import baseline_names, describe

        for name in baseline_names():
            facts = describe(name)
            print(f"baseline:{name}  {facts['algo'].upper()} seed {facts['seed']}, {facts['timesteps']} steps, "
                  f"controller {facts['env'].get('controller', 'pid')}, plants {facts['env']['plant_randomization']}")
        return 0
    if args.rl_command == "best":
        from mjtraj.checks import positive_int
        from mjtraj.rl.baselines import baseline_names, baselines_folder
        from mjtraj.rl.best import choose_best

        positive_int("scenarios", args.scenarios)
        command = "mjtraj " + " ".join(shlex.quote(a) for a in args.argv)
        with _Progress("mjtraj rl best", "baseline", not args.no_progress) as progress:
            chosen = choose_best(baselines_folder(), baseline_names(), scenarios=args.scenarios, command=command,
                                 progress=progress)
        for name, scores in chosen["scores"].items():
            print(f"{name}: " + ", ".join(f"{f} {r if isinstance(r, str) else format(r, '.4g')}"
                                          for f, r in scores.items()))
        print(f"baseline:best = {chosen['best']} ({chosen['rule']})")
        return 0
    if args.rl_command == "ship":
        from mjtraj.checks import choice
        from mjtraj.rl.baselines import ship

        choice("which", args.which, ("best", "policy"))
        print(f"wrote {ship(args.run, args.name, which=args.which, into=args.into, student=args.student)}")
        return 0
    from mjtraj.rl.evaluate import REFERENCE, evaluate

    command = "mjtraj " + " ".join(shlex.quote(a) for a in args.argv)
    policies = list(args.policies)
    if args.baselines:
        from mjtraj.rl.baselines import baseline_names

        policies += [f"baseline:{name}" for name in baseline_names()]
    evaluation = evaluate(policies, families=tuple(args.family), scenarios=args.scenarios, seed=args.seed,
                          planners=tuple(args.planners), controllers=tuple(args.controllers),
                          tuned_gains=args.tuned_gains, reps=args.reps, threads=args.threads,
                          settings=_overrides(None, args.policy_env, "policy-env"), out=args.out, command=command,
                          progress=not args.no_progress, floor=args.floor)
    print(evaluation.table)
    print(f"\nIn short (J / {REFERENCE}, then P(improve)):\n")
    print(evaluation.compact)
    if evaluation.floor_table:
        print("\nAgainst the floor and the strongest classical method:\n")
        print(evaluation.floor_table)
    print(f"\nwrote {evaluation.csv}, {evaluation.summary_json}, {evaluation.markdown} and {evaluation.figure}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (2 on bad input, with a one-line message on stderr).

    The command runs its BLAS on one thread unless the user set a count: mjtraj's matrices are small and its
    parallelism is across scenarios, and the nonlinear planners' iterates depend on the BLAS's summation order, which
    depends on its thread count (same numbers bit for bit in `compare`, a sweep's workers and its in-process path).
    """
    if "numpy" not in sys.modules:  # its BLAS reads this once, when it loads
        unset = [name for name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS") if name not in os.environ]
        for name in unset:
            os.environ[name] = "1"
        os.environ["MJTRAJ_SET_THREADS"] = ",".join(unset)  # `bench busy` times the API without them
    words = _join_negative_values(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    args = parser.parse_args(words)
    if args.command is None:  # a bare `mjtraj`: what it can do
        parser.print_help()
        return 0
    args.argv = words
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        commands = {"compare": _compare, "frontier": _frontier, "tune": _tune, "bench": _bench, "gains": _gains,
                    "render": _render, "doctor": _doctor, "floor": _floor, "sweep": _sweep, "audit": _audit,
                    "export": _export,
                    "rl": _rl}
        return commands[args.command](args)
    except MjtrajError as e:
        print(f"mjtraj: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (`mjtraj compare --json | head`): nothing more to say
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        again = " with --resume" if args.command == "sweep" else ""
        print(f"mjtraj: interrupted; run the same command{again} to continue", file=sys.stderr)
        return 130
    except OSError as e:
        where = f"{e.filename}: " if e.filename else ""
        print(f"mjtraj: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2
