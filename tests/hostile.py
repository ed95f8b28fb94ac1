"""A catalogue of bad and extreme inputs, as a hostile user would try them, and their outcomes.

Each case is run and classified:
- `refused`: one line from the MjtrajError family (the CLI: exit 2, one line on stderr starting "mjtraj: ");
- `ran`: accepted and run to the end (exit 0, or no exception);
- `traceback`: anything else (another exception, exit 1, or a message over several lines).
Every case states its right outcome: a bad input is refused in one line that names what it got wrong (`names`: the
flag, argument, key or file, found in the line; '{tmp}' there is the case's folder), so that a refusal for another
reason (a missing flag, a neighbouring error) fails it; an extreme input runs. `run_catalogue` returns one outcome
per case; `table` tallies them by kind. `python -m pytest tests/test_hostile_inputs.py -s` prints the table.
"""

from __future__ import annotations

import contextlib
import io
import math
import shutil
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mjtraj.exceptions import MjtrajError

BAD, EXTREME = "bad", "extreme"


@dataclass(frozen=True)
class Case:
    """One input: its kind (a row of the table), a label, how to run it, and whether it is bad or extreme."""

    kind: str
    label: str
    run: Callable[[Path], Any]
    expect: str = BAD
    names: str = ""
    """What the refusal of a bad input must name (a flag, argument, key, value or file); '{tmp}' is the case's
    folder, and a dash may read as an underscore (--num-envs, num_envs)."""


@dataclass(frozen=True)
class Outcome:
    case: Case
    result: str
    """refused, ran or traceback."""
    detail: str

    folder: str = ""
    """The folder the case ran in."""

    @property
    def ok(self) -> bool:
        """A bad input refused in one line naming what it got wrong, an extreme one run."""
        if self.case.expect == EXTREME:
            return self.result == "ran"
        names = self.case.names.replace("{tmp}", self.folder)
        return self.result == "refused" and bool(names) and (names in self.detail  # a flag's dashes may read as _
                                                             or names.replace("-", "_") in self.detail)


class CliResult:
    def __init__(self, code: int, err: str) -> None:
        self.code, self.err = code, err


def cli(argv: list[str]) -> Callable[[Path], CliResult]:
    """A case that runs `mjtraj argv` in this process; '{tmp}' in an argument is the case's own folder."""

    def run(tmp: Path) -> CliResult:
        from mjtraj.cli import main

        args = [a.replace("{tmp}", str(tmp)) for a in argv]
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = main(args)
            except SystemExit as e:
                code = int(e.code) if isinstance(e.code, int) else 1
        return CliResult(code, err.getvalue())

    return run


def classify(case: Case, tmp: Path) -> Outcome:
    """Run `case` in the folder `tmp` and classify what happened."""
    try:
        result = case.run(tmp)
    except MjtrajError as e:
        text = str(e)
        return Outcome(case, "refused" if "\n" not in text else "traceback", text, str(tmp))
    except Exception as e:  # noqa: BLE001 - the point is to catch what escapes
        return Outcome(case, "traceback", f"{type(e).__name__}: {e}", str(tmp))
    if isinstance(result, CliResult):
        lines = result.err.strip().splitlines()
        if result.code == 0:
            return Outcome(case, "ran", "", str(tmp))
        if (result.code in (2, 130) and len(lines) == 1 and lines[0].startswith("mjtraj: ")
                and "Traceback" not in result.err):
            return Outcome(case, "refused", lines[0], str(tmp))
        return Outcome(case, "traceback", f"exit {result.code}: {result.err[-400:]}", str(tmp))
    return Outcome(case, "ran", "", str(tmp))


# ---------------------------------------------------------------------------------------------------------------
# the catalogue

NUMBERS = ["0", "-1", "nan", "inf", "x", "", "1e400", "1,2"]
"""Bad values for a flag that takes a positive number."""


def _flag_cases(kind: str, command: list[str], flag: str, values: list[str], tail: list[str],
                names: str | None = None) -> list[Case]:
    """`command flag value tail` for each bad value, whose refusal names the flag (`names`: another word it names)."""
    named = names if names is not None else flag.removeprefix("--")
    return [Case(kind, f"{' '.join(command)} {flag} {v!r}", cli([*command, flag, v, *tail]), names=named)
            for v in values]


def cli_cases() -> list[Case]:
    cases: list[Case] = []
    out = ["--out", "{tmp}/o"]
    compare = ["compare", "--no-figures", "--planners", "cubic", *out]
    for flag in ("--duration", "--dt", "--substeps"):
        cases += _flag_cases("CLI numbers", ["compare"], flag, NUMBERS, compare[1:])
    for flag, values in (("--q0", ["a", "1,2", "9,9,9", "nan,0,0", "inf,0,0", "1,,2", "0,0,0,0", ""]),
                         ("--qg", ["a", "1,2", "0,9,0", "0,0,nan", "-inf,0,0"])):
        cases += _flag_cases("CLI vectors", ["compare"], flag, values, compare[1:])
    for flag, values in (("--planners", ["spline", "cubic,cubic", ",", "", "CUBIC", "cubic,,quintic"]),
                         ("--controller", ["pd", "", "PID"]), ("--feedforward", ["model", ""]),
                         ("--ff-accel", ["mean"]), ("--gravity-comp", ["off"]), ("--anti-windup", ["always"])):
        cases += _flag_cases("CLI names", ["compare"], flag, values, [*out, "--no-figures"])
    cases += _flag_cases("CLI numbers", ["frontier"], "--alphas", ["-1", "x", "1,1", "nan", "inf", ""], [*out])
    cases += _flag_cases("CLI numbers", ["frontier"], "--splits", ["2", "-0.5", "nan", "x"], [*out])
    cases += _flag_cases("CLI names", ["frontier"], "--family", ["hard", ""], [*out])
    cases += _flag_cases("CLI numbers", ["frontier", "--family", "nominal"], "--scenarios",
                         ["0", "-1", "x", "1", "2.5"], [*out])
    cases += _flag_cases("CLI numbers", ["frontier", "--family", "nominal"], "--seed", ["-1", "x", "1.5"], [*out])
    cases += _flag_cases("CLI numbers", ["tune"], "--budget", ["0", "-3", "x", "1.5", "1e400"],
                         ["--out", "{tmp}/t.toml"])
    cases += _flag_cases("CLI numbers", ["tune"], "--scenarios", ["0", "-1", "x"], ["--out", "{tmp}/t.toml"])
    cases += _flag_cases("CLI names", ["tune"], "--planners", ["spline", ""], ["--out", "{tmp}/t.toml"])
    cases += _flag_cases("CLI names", ["tune"], "--family", ["hard"], ["--out", "{tmp}/t.toml"])
    sweep = ["sweep", "--no-progress"]
    for flag, values in (("--scenarios", ["0", "-1", "x", "1e400"]), ("--seed", ["-1", "x", "1.5"]),
                         ("--batch", ["0", "-2", "x"]), ("--sensor-noise", ["-1", "nan", "inf", "x"]),
                         ("--delay", ["2", "-1", "x"]), ("--workers", ["0", "-1", "x"])):
        cases += _flag_cases("CLI numbers", sweep, flag, values, ["--out", "{tmp}/s.sqlite"])
    for flag, values in (("--family", ["hard", "", "nominal,nominal"]), ("--planners", ["spline", "cubic,cubic"]),
                         ("--ff-accel", ["mean"]), ("--gravity-comp", ["off"]), ("--backend", ["gpu", ""])):
        cases += _flag_cases("CLI names", sweep, flag, values, ["--out", "{tmp}/s.sqlite"],
                             "planner" if flag == "--planners" else None)
    render = ["render", "--planners", "cubic", "--every", "100", "--width", "32", "--height", "24"]
    for flag, values in (("--width", ["0", "5000", "x", "-5"]), ("--height", ["0", "5000", "x"]),
                         ("--every", ["0", "-1", "x"])):
        cases += _flag_cases("CLI numbers", render, flag, values, out)
    for flag, values in (("--camera", ["back", ""]), ("--format", ["avi", ""]), ("--quality", ["best"]),
                         ("--planners", ["spline"])):
        cases += _flag_cases("CLI names", render, flag, values, out)
    cases += _flag_cases("CLI numbers", ["bench", "loop"], "--sizes", ["0", "x", "-1", ""], [])
    cases += [Case("CLI names", "bench 'everything'", cli(["bench", "everything"]), names="'everything'")]
    rl = ["rl", "train", "--steps", "64", "--no-progress", "--out", "{tmp}/rl"]
    for flag, values in (("--steps", ["0", "-1", "x"]), ("--num-envs", ["0", "x"]), ("--residual-scale",
                         ["0", "-1", "nan"]), ("--threads", ["0", "x"]), ("--evaluations", ["-1", "x"])):
        cases += _flag_cases("CLI numbers", rl, flag, values, [])
    for flag, values in (("--algo", ["dqn"]), ("--action-mode", ["velocity"]), ("--reward-baseline", ["x"]),
                         ("--plant-randomization", ["heavy"]), ("--planner", ["spline"]), ("--task", ["circle"]),
                         ("--hyperparameter", ["lr", "bogus=1", "learning_rate=x y"])):
        cases += _flag_cases("CLI names", rl, flag, values, [])
    evaluate = ["rl", "eval", "--scenarios", "2", "--reps", "10", "--no-progress", "--out", "{tmp}/eval"]
    for flag, values in (("--family", ["hard", ""]), ("--controllers", ["lqr"]), ("--planners", ["spline"]),
                         ("--policy", ["nope.zip", "no_such_module:policy", "json:nothing", "baseline:nope"])):
        cases += _flag_cases("CLI names", evaluate, flag, values, [], "planner" if flag == "--planners" else None)
    for value, named in (("gain=2", "'gain'"), ("action_mode=flying", "action_mode")):  # named: the setting
        cases += _flag_cases("CLI names", evaluate, "--policy-env", [value], [], named)
    cases += _flag_cases("CLI numbers", evaluate, "--reps", ["0", "x"], [])
    cases += [Case("CLI usage", " ".join(a), cli(a), names=named) for a, named in (
        (["bogus"], "'bogus'"), (["--bogus"], "--bogus"), (["compare", "--bogus"], "--bogus"),
        (["compare", "extra"], "extra"), (["compare", "--dt"], "--dt"), (["sweep", "--out"], "--out"),
        (["audit"], "sweeps"), (["export", "{tmp}/x.csv"], "--out"), (["rl", "eval", "--policy"], "--policy"),
        (["compare", "--config", "paper", "--model", "x.xml"], "model, config"),
        (["compare", "--torque-limit", "5"], "torque-limit"))]
    # an output path's refusal names the path, or the part of it that is in the way (file.txt, a file)
    cases += [Case("CLI output paths", f"compare --out {p}", cli(["compare", "--planners", "cubic", "--out", p]),
                   names=named)
              for p, named in (("{tmp}/file.txt/sub", "{tmp}/file.txt/sub"), ("/proc/version", "/proc/version"),
                               ("/proc/mjtraj", "/proc/mjtraj"), ("{tmp}/file.txt", "{tmp}/file.txt"))]
    cases += [Case("CLI output paths", f"sweep --out {p}", cli(["sweep", "--scenarios", "1", "--planners", "cubic",
                                                               "--no-progress", "--out", p]), names=named)
              for p, named in (("{tmp}/file.txt/s.sqlite", "{tmp}/file.txt"), ("/proc/s.sqlite", "/proc/s.sqlite"),
                               ("{tmp}", "out: {tmp} exists"), ("{tmp}/file.txt", "out: {tmp}/file.txt exists"))]
    # named: the folder given as --out is in the way of the file written (the line names the writer's temporary file
    # beside it, {tmp}/../.caseNNNN.*, not --out itself)
    cases += [Case("CLI output paths", "tune --out a folder", cli(["tune", "--budget", "1", "--out", "{tmp}"]),
                   names="Is a directory")]
    cases += [Case("CLI extreme values", " ".join(a), cli(a), EXTREME) for a in (
        ["compare", "--q0", "0,-1.5707963267948966,0", "--qg", "0,-1.5707963267948966,0", *compare[1:]],
        ["compare", "--duration", "0.02", *compare[1:]], ["compare", "--duration", "0.04", *compare[1:]],
        ["compare", "--duration", "20", "--planners", "cubic", "--no-figures", *out],
        ["compare", "--dt", "0.5", "--duration", "2", *compare[1:]],
        ["compare", "--dt", "0.001", "--duration", "0.1", *compare[1:]],
        ["compare", "--q0", "6.28,0,0", "--qg", "-6.28,0,0", *compare[1:]],
        ["compare", "--substeps", "1000", "--duration", "0.1", *compare[1:]],
        ["compare", "--qg", "3.14159,3.14159,3.14159", *compare[1:]],
        ["compare", "--duration", "0.1", "--planners", "optimal,trapezoidal,scurve", "--no-figures", *out],
        ["frontier", "--alphas", "1e-300", *out],
        ["render", "--planners", "cubic", "--every", "1000", "--width", "1", "--height", "1", *out],
        ["sweep", "--scenarios", "1", "--planners", "cubic", "--no-progress", "--out", "{tmp}/one.sqlite"],
        ["sweep", "--scenarios", "3", "--batch", "1000", "--planners", "cubic", "--no-progress", "--out",
         "{tmp}/b.csv"],
        ["tune", "--planners", "cubic", "--budget", "1", "--scenarios", "2", "--out", "{tmp}/t.toml"])]
    # extreme, but above the frontier's declared ceiling of 1e12: refused, naming it
    cases += [Case("CLI extreme values", "frontier --alphas 0,1e300", cli(["frontier", "--alphas", "0,1e300",
                                                                            "--no-figures", *out]), names="alphas")]
    return cases


PAPER_TOML = None


def _paper_text() -> str:
    from importlib import resources

    return resources.files("mjtraj.domain.scenarios").joinpath("paper.toml").read_text()


def _config_case(label: str, make: Callable[[str], str | bytes], names: str, planners: str = "cubic") -> Case:
    def run(tmp: Path) -> CliResult:
        content = make(_paper_text())
        path = tmp / "s.toml"
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
        return cli(["compare", "--config", str(path), "--planners", planners, "--no-figures", "--out",
                    str(tmp / "o")])(tmp)

    return Case("scenario files", label, run, names=names)


def _replace(old: str, new: str) -> Callable[[str], str]:
    def make(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, 1)

    return make


def _section(name: str, body: str) -> Callable[[str], str]:
    """The paper scenario with the table [name]'s body replaced by `body`."""

    def make(text: str) -> str:
        start = text.index(f"[{name}]\n")
        end = text.find("\n[", start + 1)
        return text[:start] + f"[{name}]\n{body}" + (text[end:] if end >= 0 else "")

    return make


def config_cases() -> list[Case]:
    q0 = "q0 = [0.0, -1.5707963267948966, 0.0]"
    dt = "dt = 0.02        # [paper] control period 0.02 s, N = 100"
    kp = "kp = [23.891577780936444, 92.58602250615462, 22.055960792072106]"
    optimal = "[planners.optimal]\n"
    edits: dict[str, tuple[Callable[[str], str | bytes], str]] = {  # label: (the edit, what the refusal names)
        "name a path": (_replace('name = "paper"', 'name = "../escaped"'), "name"),
        "name absolute": (_replace('name = "paper"', 'name = "/tmp/abs"'), "name"),
        "name a number": (_replace('name = "paper"', "name = 5"), "name"),
        "name empty": (_replace('name = "paper"', 'name = ""'), "name"),
        "q0 true": (_replace(q0, "q0 = true"), "q0"), "q0 text": (_replace(q0, 'q0 = "a"'), "q0"),
        # q0 sets the joint count before the arm is read: the mismatch is named at qg ("expected 2 values")
        "q0 two values": (_replace(q0, "q0 = [0.0, 1.0]"), "qg: expected 2 values"),
        "q0 nested": (_replace(q0, "q0 = [[0.0], [1.0], [2.0]]"), "q0"),
        "q0 out of range": (_replace(q0, "q0 = [0.0, 9.0, 0.0]"), "q0"),
        "q0 nan": (_replace(q0, "q0 = [nan, 0.0, 0.0]"), "q0"), "q0 inf": (_replace(q0, "q0 = [inf, 0.0, 0.0]"), "q0"),
        "q0 missing": (_replace(q0, ""), "'q0'"),
        "dt zero": (_replace(dt, "dt = 0"), "dt"), "dt negative": (_replace(dt, "dt = -0.02"), "dt"),
        "dt text": (_replace(dt, 'dt = "0.02"'), "dt"), "dt not dividing T": (_replace(dt, "dt = 0.03"), "dt=0.03"),
        "dt true": (_replace(dt, "dt = true"), "dt"),
        "duration off the grid": (_replace("duration = 2.0", "duration = 2.011"), "duration"),
        "kp short": (_replace(kp, "kp = [1.0, 2.0]"), "kp"),
        "kp negative": (_replace(kp, "kp = [-1.0, 1.0, 1.0]"), "kp"),
        "kp text": (_replace(kp, 'kp = "high"'), "kp"),
        "planners a number": (lambda t: t.replace("[planners.trapezoidal]\ncruise_factor = 1.5", "[planners]\ncubic "
                                                  "= 5\n[planners.trapezoidal]\ncruise_factor = 1.5"),
                              "[planners.cubic]"),
        "unknown planner table": (lambda t: t + "\n[planners.spline]\norder = 3\n", "[planners.spline]"),
        "torque_bound negative": (_replace(optimal, optimal + "torque_bound = -1\n"),
                                  "torque_bound: expected positive"),
        "unknown planner option": (_replace(optimal, optimal + "bogus = 1\n"),
                                   "planner 'optimal': unknown option 'bogus'"),
        "cruise_factor zero": (_replace("cruise_factor = 1.5", "cruise_factor = 0"), "cruise_factor"),
        "cruise_factor too high": (_replace("cruise_factor = 1.5", "cruise_factor = 2.5"), "cruise_factor"),
        "cost rule unknown": (_section("cost", 'rule = "lqr"\n'), "'lqr'"),
        "unknown top-level key": (lambda t: "extra = 1\n" + t, "'extra'"),
        "unknown controller key": (_replace("substeps = 1 ", "substepz = 1 "), "'substepz'"),
        "substeps zero": (_replace("substeps = 1 ", "substeps = 0 "), "substeps"),
        "controller unknown law": (_replace('feedforward = "inverse"', 'controller = "pd"\nfeedforward = "inverse"'),
                                   "'pd'"),
        "feedforward unknown": (_replace('feedforward = "inverse"', 'feedforward = "magic"'), "'magic'"),
        "model a number": (lambda t: "model = 5\n" + t, "model"),
        "model missing file": (lambda t: 'model = "/nonexistent/arm.xml"\n' + t, "/nonexistent/arm.xml"),
        "torque_limit without model": (lambda t: "torque_limit = 5.0\n" + t, "torque_limit"),
        "TOML syntax error": (lambda t: t + "\n[task\n", "{tmp}/s.toml is not valid TOML"),
        "duplicate key": (lambda t: t.replace('name = "paper"', 'name = "paper"\nname = "again"'),
                          "{tmp}/s.toml is not valid TOML"),
        "empty file": (lambda t: "", "[task]"),
        "binary": (lambda t: bytes(range(256)) * 4, "{tmp}/s.toml is not a text file"),
        "UTF-16": (lambda t: t.encode("utf-16"), "{tmp}/s.toml is not a text file"),
        "task a number": (lambda t: "task = 3\n" + _section("task", "")(t).replace("[task]\n", "", 1),
                          "[task] must be a table, got 3"),
    }
    cases = [_config_case(label, make, names) for label, (make, names) in edits.items()]
    # a planner's per-joint option is checked against the task when that planner plans (a file whose optimal
    # planner's q_bar is short loads, and runs the other planners): the case plans with it
    cases.append(_config_case("q_bar short", _replace(optimal, optimal + "q_bar = [0, 0]\n"),
                              "q_bar: expected 3 values", "optimal"))
    cases += [Case("scenario files", f"--config {p}", cli(["compare", "--config", p, "--out", "{tmp}/o"]),
                   names=f"config: scenario file not found: {p}")
              for p in ("/nonexistent.toml", "{tmp}", "/dev/null", "nosuchshipped")]
    return cases


ARM = ('<mujoco><worldbody><body name="a">{joint}<inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>'
       '<body name="b" pos="0.2 0 0"><joint name="j2" type="hinge" axis="0 1 0"/><inertial pos="0.1 0 0" mass="1" '
       'diaginertia="0.01 0.01 0.01"/></body></body></worldbody>{extra}<actuator>{actuators}</actuator></mujoco>')
HINGE = '<joint name="j1" type="hinge" axis="0 1 0"/>'
MOTORS = '<motor joint="j1" ctrlrange="-5 5"/><motor joint="j2" ctrlrange="-5 5"/>'


def _model_case(label: str, content: str | bytes | None, command: str = "compare") -> Case:
    def run(tmp: Path) -> CliResult:
        path = tmp / "arm.xml"
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif content is not None:
            path.write_text(content)
        argv = {"compare": ["compare", "--model", str(path), "--no-figures", "--out", str(tmp / "o")],
                "render": ["render", "--model", str(path), "--every", "100", "--out", str(tmp / "o")],
                "sweep": ["sweep", "--model", str(path), "--scenarios", "1", "--no-progress", "--out",
                          str(tmp / "s.sqlite")],
                "frontier": ["frontier", "--model", str(path), "--no-figures", "--out", str(tmp / "o")]}[command]
        return cli(argv)(tmp)

    return Case("model files", f"{command} --model: {label}", run, names="{tmp}/arm.xml")


def model_cases() -> list[Case]:
    models: dict[str, str | bytes | None] = {
        "missing": None, "empty": "", "binary": bytes(range(256)), "not XML": "arm: yes\n",
        "not MJCF": "<robot name='r'/>", "ball joint": ARM.format(joint='<joint name="j1" type="ball"/>', extra="",
                                                                 actuators='<motor joint="j2" ctrlrange="-5 5"/>'),
        "slide joint": ARM.format(joint='<joint name="j1" type="slide" axis="1 0 0"/>', extra="", actuators=MOTORS),
        "free joint": ARM.format(joint='<freejoint name="j1"/>', extra="",
                                 actuators='<motor joint="j2" ctrlrange="-5 5"/>'),
        "tendon": ARM.format(joint=HINGE, extra='<tendon><fixed name="t"><joint joint="j1" coef="1"/></fixed>'
                             '</tendon>', actuators=MOTORS),
        "equality": ARM.format(joint=HINGE, extra='<equality><joint name="e" joint1="j1" joint2="j2"/></equality>',
                               actuators=MOTORS),
        "no force range": ARM.format(joint=HINGE, extra="", actuators='<motor joint="j1" ctrlrange="-5 5"/>'),
        "no joints": "<mujoco><worldbody><body><geom size='0.1'/></body></worldbody></mujoco>",
        "unnamed hinge": ARM.format(joint='<joint type="hinge" axis="0 1 0"/>', extra="",
                                    actuators='<motor joint="j2" ctrlrange="-5 5"/>'),
        "bad include": "<mujoco><include file='nowhere.xml'/></mujoco>",
    }
    cases = [_model_case(label, content) for label, content in models.items()]
    cases += [_model_case(label, models[label], command) for label in ("ball joint", "missing", "binary")
              for command in ("render", "sweep", "frontier")]
    return cases


def _sweep_file(tmp: Path, name: str = "s.csv", scenarios: int = 4) -> Path:
    """A complete small sweep (`scenarios` nominal scenarios, cubic, units of 2) at tmp/name."""
    from mjtraj.study.runner import run_sweep
    from mjtraj.study.sweep import SweepSettings

    path = tmp / name
    run_sweep(SweepSettings(scenarios=scenarios, batch=2, planners=("cubic",)), path, workers=1, progress=False)
    return path


def _resume_case(label: str, damage: Callable[[Path], None], suffix: str = ".csv") -> Case:
    def run(tmp: Path) -> CliResult:
        path = _sweep_file(tmp, "s" + suffix)
        damage(path)
        return cli(["sweep", "--scenarios", "4", "--batch", "2", "--planners", "cubic", "--no-progress", "--out",
                    str(path), "--resume"])(tmp)

    return Case("sweep files (resume)", label, run, names="{tmp}/s" + suffix)


def _read_case(kind: str, label: str, damage: Callable[[Path], None], command: str, suffix: str = ".csv",
               scenarios: int = 4, expect: str = BAD, names: str | None = None) -> Case:
    def run(tmp: Path) -> CliResult:
        path = _sweep_file(tmp, "s" + suffix, scenarios)
        damage(path)
        argv = {"audit": ["audit", str(path), "--no-tasks", "--out", str(tmp / "A.md")],
                "export": ["export", str(path), "--out", str(tmp / "e.jsonl")]}[command]
        return cli(argv)(tmp)

    return Case(kind, f"{command}: {label}", run, expect, "{tmp}/s" + suffix if names is None else names)


def _lines(edit: Callable[[list[bytes]], list[bytes]]) -> Callable[[Path], None]:
    def damage(path: Path) -> None:
        lines = path.read_bytes().splitlines(keepends=True)
        path.write_bytes(b"".join(edit(lines)))

    return damage


def _sql(statement: str) -> Callable[[Path], None]:
    def damage(path: Path) -> None:
        import sqlite3

        with sqlite3.connect(path) as connection:
            connection.execute(statement)

    return damage


def file_cases() -> list[Case]:
    csv_damage: dict[str, Callable[[Path], None]] = {
        "repeated header": _lines(lambda ls: [*ls, ls[0]]),
        "a line of commas": _lines(lambda ls: [*ls[:2], b"," * ls[1].count(b",") + b"\n", *ls[2:]]),
        "unit zz": _lines(lambda ls: [*ls, ls[1].replace(b",0,", b",zz,", 1)]),
        "non-UTF-8 bytes": _lines(lambda ls: [*ls[:2], b"\xff\xfe\x00garbage\n", *ls[2:]]),
        "binary": lambda p: p.write_bytes(bytes(range(256)) * 8),
        "a unit twice": _lines(lambda ls: [*ls, *ls[1:3]]),
        "a row cut short": _lines(lambda ls: [ls[0], ls[1][: len(ls[1]) // 2] + b"\n", *ls[2:]]),
        "other settings": _lines(lambda ls: [ls[0], *(line.replace(b",cubic,", b",quintic,") for line in ls[1:])]),
        "a directory": lambda p: (p.unlink(), p.mkdir()),
    }
    cases = [_resume_case(label, damage) for label, damage in csv_damage.items()]
    cases.append(Case("sweep files (resume)", "a whole unit deleted mid-file (recomputed: units may finish out of "
                      "order)", _resume_case("", _lines(lambda ls: [ls[0], *ls[3:]])).run, EXTREME))
    store_damage: dict[str, Callable[[Path], None]] = {
        "store: unit entry lost": _sql("DELETE FROM units WHERE unit = 1"),
        "store: a row lost": _sql("DELETE FROM rows WHERE rowid = 1"),
        "store: meta dropped": _sql("DROP TABLE meta"),
        "store: foreign unit": _sql("INSERT INTO units VALUES ('nominal', 7, 2)"),
        "store: meta damaged": _sql("UPDATE meta SET value = 'not json' WHERE key = 'columns'"),
        "store: text in a .sqlite": lambda p: p.write_text("family,scenario\n"),
        "store: truncated": lambda p: p.write_bytes(p.read_bytes()[:2000]),
        "store: binary": lambda p: p.write_bytes(bytes(range(256)) * 64),
    }
    cases += [_resume_case(label, damage, ".sqlite") for label, damage in store_damage.items()]
    read_damage: dict[str, Callable[[Path], None]] = {
        "truncated (torn last row)": lambda p: p.write_bytes(p.read_bytes()[:-30]),
        "a row cut early": _lines(lambda ls: [ls[0], ls[1][:40] + b"\n", *ls[2:]]),
        "header only": _lines(lambda ls: ls[:1]),
        "empty": lambda p: p.write_bytes(b""),
        "binary": lambda p: p.write_bytes(bytes(range(256)) * 8),
        "unfinished": _lines(lambda ls: ls[:-1]),
        "not a sweep": lambda p: p.write_text("a,b\n1,2\n"),
        "a directory": lambda p: (p.unlink(), p.mkdir()),
        "missing": lambda p: p.unlink(),
    }
    # the audit reads cells, not files: its refusal of a file that is not a sweep cannot name the file
    unnamed = {("audit", "not a sweep"): "sweep: not a sweep results file"}
    for command in ("audit", "export"):
        cases += [_read_case("sweep files (read)", label, damage, command, names=unnamed.get((command, label)))
                  for label, damage in read_damage.items()]
        cases += [_read_case("sweep files (read)", label, damage, command, ".sqlite")
                  for label, damage in store_damage.items() if "unit entry" not in label]
    cases += [_read_case("sweep files (read)", "one scenario: no verdict", lambda p: None, "audit", scenarios=1,
                         expect=EXTREME)]
    cases += [Case("sweep files (read)", f"export --out {o}", cli(["export", "/dev/null", "--out", o]),
                   names=f"out: expected a file ending in .sqlite, .db, .jsonl, .csv, got '{o}'")
              for o in ("{tmp}/x.parquet", "{tmp}/x")]
    return cases


def _env(**kwargs: Any) -> Callable[[Path], Any]:
    def run(tmp: Path) -> Any:
        import gymnasium as gym

        env = gym.make("UR5Track-v0", **kwargs)
        try:
            env.reset(seed=0)
            env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        finally:
            env.close()

    return run


def _step(mode: str, action: Any) -> Callable[[Path], Any]:
    def run(tmp: Path) -> Any:
        import gymnasium as gym

        env = gym.make("UR5Track-v0", action_mode=mode, disable_env_checker=True)
        try:
            env.reset(seed=0)
            env.step(action)
        finally:
            env.close()

    return run


def _reset(options: Any) -> Callable[[Path], Any]:
    def run(tmp: Path) -> Any:
        import gymnasium as gym

        env = gym.make("UR5Track-v0", task="random")
        try:
            env.reset(seed=0, options=options)
        finally:
            env.close()

    return run


def env_cases() -> list[Case]:
    nan = math.nan
    arguments: dict[str, list[Any]] = {
        "planner": ["spline", 3, None], "action_mode": ["velocity", 1], "residual_scale": [0, -1, nan, "a"],
        "task": ["circle"], "max_displacement": [0, -1, nan], "duration": [0, -1, 1.01, nan, "2"],
        "dt": [0, -0.02, nan], "preview": [-1, 1.5, "a"], "plant_randomization": ["heavy"],
        "measurement_noise": [-1, nan], "reward_baseline": ["x"], "width": [0, -1, 5000, 1.5],
        "height": [0, 5000], "camera": ["wrist"], "render_quality": ["ultra"], "render_mode": ["ansi", "rgb"],
        "torque_limit": [5.0],
        "controller": ["pd"], "feedforward": ["x"], "substeps": [0, -1], "divergence_bound": [0, -1],
        "delay": [2, -1], "anti_windup": ["x"], "bogus": [1], "observe_control": ["yes"],
    }
    cases = [Case("env arguments", f"{name}={value!r}", _env(**{name: value}), names=name)
             for name, values in arguments.items() for value in values]
    cases += [Case("env arguments", label, _env(**kwargs), names=named) for label, kwargs, named in (
        ("Q_exec short", {"Q_exec": [1, 1], "R_exec": [1, 1, 1]}, "Q_exec: expected 6 values"),
        ("R_exec without Q_exec", {"R_exec": [1, 1, 1]}, "Q_exec, R_exec"),
        ("xml_file missing", {"xml_file": "/nonexistent.xml"}, "/nonexistent.xml"),
        ("q0 with the paper task", {"q0": [0, 0, 0], "qg": [0, 0, 1]}, "q0, qg"),
        ("explicit without qg", {"task": "explicit", "q0": [0, 0, 0]}, "qg"),
        ("explicit out of range", {"task": "explicit", "q0": [0, 0, 4], "qg": [0, 0, 0]}, "q0"),
        ("explicit nan", {"task": "explicit", "q0": [nan, 0, 0], "qg": [0, 0, 0]}, "q0"),
        ("Q_exec nan", {"Q_exec": [nan] * 6, "R_exec": [1, 1, 1]}, "Q_exec"),
    )]
    actions: list[Any] = [np.zeros(2), np.zeros((3, 1)), np.full(3, nan), np.full(3, np.inf), ["a", "b", "c"],
                          None, "x", np.zeros(0), 1.0]
    cases += [Case("env actions", f"{mode}: {a!r}"[:60], _step(mode, a), names="action")
              for mode in ("pid", "residual", "torque") for a in actions]
    move = {"q0": [0.0, -1.5, 0.0], "qg": [0.5, -1.0, 0.5]}  # a valid task, so that only the duration is wrong
    cases += [Case("env reset options", repr(o), _reset(o), names=named) for o, named in (
        ({"q0": [9, 9, 9], "qg": [0, 0, 0]}, "q0"), ({**move, "duration": -1}, "duration"), ({"bogus": 1}, "'bogus'"),
        ({"q0": "a", "qg": [0, 0, 0]}, "q0"), ({"q0": [0, 0, 0]}, "qg"), ({**move, "duration": 1.013}, "duration"),
        ("q0", "options"), ({"qg": [nan, 0, 0], "q0": [0, 0, 0]}, "qg"))]
    return cases


def api_cases() -> list[Case]:
    from mjtraj.core import PIDGains, Task, make

    nan = math.nan
    cases = [Case("library calls", f"Task.create{args}", (lambda a: lambda tmp: Task.create(*a))(args), names=named)
             for args, named in ((([nan, 0, 0], [0, 0, 0], 2.0, 0.02), "q0"), (([0, 0, 0], [0, 0], 2.0, 0.02), "qg"),
                                 (([0, 0, 0], [0, 0, 0], -2.0, 0.02), "duration"),
                                 (([0, 0, 0], [0, 0, 0], 2.0, 0.0), "dt"),
                                 (([0, 0, 0], [0, 0, 0], 2.0, 0.03), "dt=0.03"),
                                 (("a", [0, 0, 0], 2.0, 0.02), "q0"),
                                 (([0, 0, 0], [0, 0, 0], 1e9, 0.02), "duration, dt"))]
    cases += [Case("library calls", f"PIDGains.create{args}", (lambda a: lambda tmp: PIDGains.create(*a, n=3))(args),
                   names="kp")
              for args in (([1, 1], [1, 1, 1], [1, 1, 1]), ([-1, 1, 1], [1, 1, 1], [1, 1, 1]),
                           ([nan, 1, 1], [1, 1, 1], [1, 1, 1]))]
    options = {"optimal": [{"torque_bound": -1}, {"q_bar": (0, 0)}, {"linearization": "end"}, {"bogus": 1},
                           {"state_weight": (1, 1)}, {"input_weight": (-1, 1, 1)}],
               "trapezoidal": [{"cruise_factor": 0}, {"cruise_factor": 3}, {"cruise_factor": "a"}],
               "scurve": [{"jerk_factor": 0}, {"speed_limit": -1}],
               "nonlinear_min_effort": [{"speed_limit": 0}, {"bogus": 1}], "cubic": [{"bogus": 1}]}

    def plan(name: str, opts: dict[str, Any]) -> Callable[[Path], Any]:
        def run(tmp: Path) -> Any:
            from mjtraj.study import load_scenario

            scenario = load_scenario()
            return make(name, **opts).plan(scenario.task, scenario.model)

        return run

    cases += [Case("library calls", f"make({name!r}, **{o}).plan(paper task)", plan(name, o),
                   names=f"'{key}'" if key == "bogus" else key)
              for name, opts in options.items() for o in opts for key in o]
    return cases


def catalogue() -> list[Case]:
    """Every case, in table order."""
    return [*cli_cases(), *config_cases(), *model_cases(), *file_cases(), *env_cases(), *api_cases()]


def run_catalogue(cases: list[Case], folder: Path) -> list[Outcome]:
    """Run every case in a fresh sub-folder of `folder` (with a plain file, file.txt, to misuse as a folder)."""
    outcomes = []
    for i, case in enumerate(cases):
        tmp = folder / f"case{i:04d}"
        tmp.mkdir()
        (tmp / "file.txt").write_text("a file, not a folder\n")
        outcomes.append(classify(case, tmp))
        shutil.rmtree(tmp, ignore_errors=True)
    return outcomes


def table(outcomes: list[Outcome]) -> str:
    """Markdown: per kind, the cases run, bad and extreme, refused in one line, run, tracebacks, and bad inputs
    silently accepted."""
    kinds = list(dict.fromkeys(o.case.kind for o in outcomes))
    lines = ["| kind | cases | bad | extreme | refused in one line | ran | tracebacks | bad inputs accepted |",
             "|---|---|---|---|---|---|---|---|"]
    total: Counter[str] = Counter()
    for kind in [*kinds, "all"]:
        mine = [o for o in outcomes if kind in ("all", o.case.kind)]
        c = Counter({"cases": len(mine), "bad": sum(o.case.expect == BAD for o in mine),
                     "extreme": sum(o.case.expect == EXTREME for o in mine),
                     "refused": sum(o.result == "refused" for o in mine), "ran": sum(o.result == "ran" for o in mine),
                     "traceback": sum(o.result == "traceback" for o in mine),
                     "accepted": sum(o.result == "ran" and o.case.expect == BAD for o in mine)})
        if kind != "all":
            total.update(c)
        name = "**all**" if kind == "all" else kind
        lines.append(f"| {name} | {c['cases']} | {c['bad']} | {c['extreme']} | {c['refused']} | {c['ran']} | "
                     f"{c['traceback']} | {c['accepted']} |")
    return "\n".join(lines)
