"""What the commands share: the parser class, value types, shared options, progress bars and the scenario a
command's flags describe."""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from mjtraj.exceptions import InvalidInputError


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        self.exit(2, f"mjtraj: error: {message}\n")


def floats(text: str) -> list[float]:
    try:
        return [float(x) for x in text.replace(",", " ").split()]
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from e


def counts(text: str) -> list[int]:
    """Whole numbers >= 1, comma-separated."""
    try:
        values = [int(x) for x in text.split(",")]
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected whole numbers separated by commas, got {text!r}") from e
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected whole numbers >= 1, got {text!r}")
    return values


def widths(text: str) -> list[int]:
    """A network's hidden layer widths: whole numbers >= 1, comma-separated, or none (no hidden layer)."""
    return [] if text.strip().lower() == "none" else counts(text)


def names(text: str) -> list[str]:
    names = [x.strip() for x in text.split(",")]
    if not text.strip() or any(not x for x in names):
        raise argparse.ArgumentTypeError(f"expected comma-separated names without empty ones, got {text!r}")
    return names


def figure_formats(text: str) -> list[str]:
    from mjtraj.study.plots import FIGURE_FORMATS

    kinds = [k.strip() for k in text.split(",")]
    unknown = [k for k in kinds if k not in FIGURE_FORMATS]
    if unknown or not text:
        raise argparse.ArgumentTypeError(f"expected {', '.join(FIGURE_FORMATS)} (comma-separated), got {text!r}")
    return list(dict.fromkeys(kinds))


def scenario_range(text: str) -> range:
    """--scenarios of `mjtraj floor`: K (0..K-1) or A:B."""
    first, sep, last = text.partition(":")
    try:
        span = range(int(first), int(last)) if sep else range(int(first))
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected K or A:B (integers), got {text!r}") from e
    if len(span) == 0 or span.start < 0:
        raise argparse.ArgumentTypeError(f"expected a non-empty range of indices >= 0, got {text!r}")
    return span


NEGATIVE = re.compile(r"-\.?\d")
"""A value that starts like a negative number ('-6.28,0,0'), which argparse would take for an option."""


def join_negative_values(argv: Sequence[str]) -> list[str]:
    """`--q0 -6.28,0,0` as `--q0=-6.28,0,0`, so that argparse reads the value as one."""
    out: list[str] = []
    for token in argv:
        if out and out[-1].startswith("--") and "=" not in out[-1] and NEGATIVE.match(token):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def overrides(file: Path | None, pairs: list[str], what: str = "hyperparameter") -> dict[str, Any]:
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


class Progress:
    """A tqdm bar on stderr driven by progress(done, total) callbacks; off with --no-progress or when stderr is
    not a terminal."""

    def __init__(self, desc: str, unit: str, enabled: bool) -> None:
        from tqdm import tqdm

        self.bar = tqdm(desc=desc, unit=unit, file=sys.stderr, leave=False, disable=None if enabled else True)

    def __call__(self, done: int, total: int) -> None:
        self.bar.total = total
        self.bar.update(done - self.bar.n)

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.bar.close()


def loop_flags(parser: argparse.ArgumentParser) -> None:
    """A flag per declared loop option (mjtraj.core.closed_loop.LoopConfig), overriding the scenario's value."""
    from mjtraj.core import LoopConfig, declared_options

    for f, declaration, kind in declared_options(LoopConfig, scenario_only=True):
        flags = [f"--{f.name.replace('_', '-')}"] + ([declaration.flag] if declaration.flag else [])
        valid = declaration.choices if isinstance(declaration.choices, tuple) else None  # not plug-ins: no import
        choices = f" ({' | '.join(map(str, valid))})" if valid else ""
        parser.add_argument(*flags, dest=f.name, type=kind, help=f"{declaration.help}{choices}; default: the "
                            "scenario's")


def arm_options(parser: argparse.ArgumentParser, *, config: str = "scenario TOML (default: the shipped paper "
                "scenario)") -> None:
    """--config, --model and --torque-limit: the scenario file, or an MJCF arm and its saturation."""
    parser.add_argument("--config", type=Path, help=config)
    parser.add_argument("--model", type=Path, help="your MJCF arm instead of the UR5 (its scenario follows the "
                        "stated rules: mjtraj.core.arm.ARM_RULES, mjtraj.domain.scenario.ARM_TASK_RULE; docs/arms.md)")
    torque_limit_option(parser)


def torque_limit_option(parser: argparse.ArgumentParser) -> None:
    """--torque-limit: an arm file's corrective saturation."""
    parser.add_argument("--torque-limit", type=floats, help="with --model: the corrective saturation, N m: one "
                        "value for every joint, or one per joint, comma-separated (default: from the model's "
                        "actuators)")


def task_options(parser: argparse.ArgumentParser) -> None:
    """--q0, --qg and --duration: the scenario's task, changed."""
    parser.add_argument("--q0", type=floats, help="start, rad, comma-separated (default: the scenario's)")
    parser.add_argument("--qg", type=floats, help="goal, rad, comma-separated (default: the scenario's)")
    parser.add_argument("--duration", type=float, help="T, s (a whole number of dt; default: the scenario's)")


def figure_format_option(parser: argparse.ArgumentParser) -> None:
    """--figure-format: the formats every figure the command draws is written in."""
    parser.add_argument("--figure-format", dest="figure_format", type=figure_formats, default=["png"],
                        help="figure formats, comma-separated: png, pdf, svg (default png)")


def no_progress_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def command_line(args: argparse.Namespace) -> str:
    """The command line that ran, as a shell would read it (written into the files a command makes)."""
    import shlex

    return "mjtraj " + " ".join(shlex.quote(a) for a in args.argv)


def json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


def scenario_of(args: argparse.Namespace, *, workspace: bool = False):  # noqa: ANN202
    """The command's scenario: --config or --model, with the task and loop flags the command has applied."""
    from mjtraj.core import LoopConfig, option_names

    task = {k: getattr(args, k) for k in ("q0", "qg", "duration", "dt") if getattr(args, k, None) is not None}
    loop = {k: getattr(args, k) for k in option_names(LoopConfig) if getattr(args, k, None) is not None}
    if getattr(args, "model", None) is not None:
        scenario = base_scenario(args, workspace=workspace, **task)
        return scenario.replace(loop=loop) if loop else scenario
    scenario = base_scenario(args)
    return scenario.replace(task=task, loop=loop) if task or loop else scenario


def base_scenario(args: argparse.Namespace, *, workspace: bool = False, **task: Any):  # noqa: ANN202
    """The scenario of --config, or of --model PATH by the arm rules (with `task` overrides), never both."""
    from mjtraj.domain.scenario import load_scenario, scenario_for_model

    if getattr(args, "model", None) is None:
        if getattr(args, "torque_limit", None) is not None:
            raise InvalidInputError("torque-limit: only with --model (a scenario file sets torque_limit beside "
                                    "model)")
        return load_scenario(args.config)
    if args.config is not None:
        raise InvalidInputError("model, config: give one (a scenario file names its arm with model = \"PATH\")")
    return scenario_for_model(args.model, torque_limit=args.torque_limit, workspace=workspace, **task)
