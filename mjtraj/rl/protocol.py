"""The published benchmark protocols, by name: the scenarios, the score and the resamples every published number is
scored on (docs/benchmark.md).

- v1: J_exec over the motion; success is the goal rule (the terminal position within a fifth of the move). Its
  published numbers are kept and reproduce from their commands (`mjtraj rl eval --protocol v1`).
- v2 (the default since it was defined): every episode goes on for the settle window after the motion, the
  reference holding the goal, and is scored over the whole episode (J_settle, `mjtraj.core.settle`); success means
  at rest at the goal when the window ends. It adds the noisy family, the mismatch family's scenarios measured with
  noise, and its reference method is the adaptive law, the classical law that is at rest at the goal on every
  scenario of the validation draws (cubic + PID is not on most aggressive and mismatched ones).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from mjtraj.core import SETTLE_WINDOW
from mjtraj.exceptions import InvalidInputError

NOISY_FAMILY = "noisy"
"""Protocol v2's family of mismatched plants measured with noise: the mismatch family's scenarios (the same draws,
so the two read paired) with measurement noise of NOISY_SIGMA, drawn from each scenario's own seed."""
NOISY_SIGMA = 1e-3
"""rad: the noisy family's measurement noise on q (sqrt(2) sigma / dt on qd): an encoder of about 13 bits per turn
read through a finite-difference velocity, the level at which the issue that defined v2 measured the predictive
laws."""
PROTOCOL_V1: dict[str, Any] = {"families": ("nominal", "aggressive", "mismatch"), "scenarios": 200, "seed": 1,
                               "reps": 2000}
"""Protocol v1: held-out scenarios 0..199 of each family under seed 1 (sweeps and training use seed 0; validation
streams are disjoint), intervals from 2,000 bootstrap resamples; J_exec, the goal rule, reference cubic+PID."""
PROTOCOL_V2: dict[str, Any] = {**PROTOCOL_V1, "families": ("nominal", "aggressive", "mismatch", NOISY_FAMILY)}
"""Protocol v2: v1's scenarios, seed and resamples, the noisy family added, each episode with its settle window
(SETTLE_WINDOW, held to the at-rest rule and scored by J_settle) and the adaptive law as reference."""
PROTOCOLS: dict[str, dict[str, Any]] = {"v1": PROTOCOL_V1, "v2": PROTOCOL_V2}
PROTOCOL = "v2"
"""The default protocol of `mjtraj rl eval`."""
SETTLE = {"v1": 0.0, "v2": SETTLE_WINDOW}
"""Each protocol's settle window, s."""
REFERENCES = {"v1": "cubic+PID", "v2": "cubic+adaptive CT"}
"""Each protocol's reference method: every ratio and improvement of its summaries is against it."""
SCORE_NAMES = {"v1": "J_exec", "v2": "J_settle"}
"""What each protocol's `cost` column holds: J_exec over the motion, or J_settle over the motion and the window."""


def check_protocol(protocol: str) -> dict[str, Any]:
    """The settings of protocol `protocol` ('v1' or 'v2'), or InvalidInputError naming the valid ones."""
    if protocol not in PROTOCOLS:
        raise InvalidInputError(f"protocol: expected one of {', '.join(PROTOCOLS)}, got {protocol!r}")
    return PROTOCOLS[protocol]


def departures(families: Sequence[str], scenarios: int, seed: int, reps: int, protocol: str = "v1") -> list[str]:
    """How a run's scenarios and resamples depart from `protocol`'s (empty: none), e.g. ['seed 0 (v1: 1)']."""
    got = {"families": tuple(families), "scenarios": scenarios, "seed": seed, "reps": reps}
    return [f"{key} {_shown(got[key])} ({protocol}: {_shown(want)})"
            for key, want in check_protocol(protocol).items() if got[key] != want]


def sweep_family(family: str) -> str:
    """The sweep family whose scenarios a protocol family draws (the noisy family: the mismatch family's)."""
    return "mismatch" if family == NOISY_FAMILY else family


def _shown(value: Any) -> str:
    return ",".join(value) if isinstance(value, tuple) else str(value)
