"""The `mjtraj` command: parses, calls the library, writes files. `main(argv) -> exit code`.

One module per command (its parser and its handler together): compare, frontier, tune, gains, floor, render, doctor,
bench, sweep, export, audit, reproduce, rl and golden; what they share (value types, the options several take, progress
bars, the scenario their flags describe) is in `common`.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence

from mjtraj.cli import (
    audit,
    bench,
    common,
    compare,
    doctor,
    export,
    floor,
    frontier,
    gains,
    golden,
    render,
    reproduce,
    rl,
    sweep,
    tune,
)
from mjtraj.exceptions import MjtrajError

COMMANDS = (compare, frontier, tune, bench, sweep, export, audit, reproduce, render, doctor, rl, gains, floor, golden)
"""The commands' modules, in the order `mjtraj --help` lists them."""


def build_parser() -> common.Parser:
    """The whole command line: every command's parser, help drawn from the registries where it lists names."""
    from mjtraj.core import controller_names
    from mjtraj.versions import __version__

    laws = ", ".join(controller_names())  # help from the registry: it cannot drift from what runs
    parser = common.Parser(prog="mjtraj", description="How the trajectory planner changes closed-loop execution.")
    parser.add_argument("--version", action="version", version=f"mjtraj {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=common.Parser)
    for command in COMMANDS:
        command.add(sub, laws)
    _describe(parser)
    return parser


def _describe(parser: argparse.ArgumentParser) -> None:
    """Give every command's own --help its one-line summary (the help the command list shows) where it has no
    description of its own, down the nested commands (`mjtraj rl eval --help`)."""
    for action in parser._actions:  # noqa: SLF001 - argparse keeps subcommands there
        if not isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            continue
        helps = {choice.dest: choice.help for choice in action._choices_actions}  # noqa: SLF001
        for name, child in action.choices.items():
            if child.description is None and helps.get(name):
                child.description = helps[name]
            _describe(child)


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
    words = common.join_negative_values(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(words)
    if args.command is None:  # a bare `mjtraj`: what it can do
        parser.print_help()
        return 0
    args.argv = words
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.handler(args))
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
