"""`mjtraj gains`: the default PID gains and optimal weights derived by their stated rules."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def add(sub: Any, laws: str) -> None:
    """Declare `mjtraj gains`."""
    p = sub.add_parser("gains", help="derive the default PID gains and optimal weights by their stated rules")
    p.add_argument("--config", type=Path, help="scenario TOML whose task to use (default: the paper scenario)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from mjtraj.core.gains import GAIN_RULE, gain_rule
    from mjtraj.core.scoring import bryson_weights
    from mjtraj.domain.scenario import load_scenario

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
