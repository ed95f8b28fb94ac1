"""The published benchmark protocol, by name: the scenarios and resamples every published number is scored on."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

PROTOCOL = "v1"
"""The published protocol's name (PROTOCOL_V1)."""
PROTOCOL_V1: dict[str, Any] = {"families": ("nominal", "aggressive", "mismatch"), "scenarios": 200, "seed": 1,
                               "reps": 2000}
"""Protocol v1: held-out scenarios 0..199 of each family under seed 1 (sweeps and training use seed 0; validation
streams are disjoint), intervals from 2,000 bootstrap resamples. `mjtraj rl eval`'s defaults; a run that departs
from any of them is stamped off-protocol in summary.json and SUMMARY.md."""


def departures(families: Sequence[str], scenarios: int, seed: int, reps: int) -> list[str]:
    """How a run's scenarios and resamples depart from PROTOCOL_V1 (empty: none), e.g. ['seed 0 (v1: 1)']."""
    got = {"families": tuple(families), "scenarios": scenarios, "seed": seed, "reps": reps}
    return [f"{key} {_shown(got[key])} (v1: {_shown(want)})" for key, want in PROTOCOL_V1.items() if got[key] != want]


def _shown(value: Any) -> str:
    return ",".join(value) if isinstance(value, tuple) else str(value)
