"""The trained policies the benchmark's summary reports, shipped so that anyone can score them again.

Each baseline is a folder NAME/ with the SB3 zip and its record (policy.zip, policy.json) and the training run's
run.json; `baseline:NAME` loads it wherever a policy is accepted, `mjtraj rl baselines` lists them, and
TRAINING.md beside this file gives the command that trained each.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path
from typing import Any

from mjtraj.exceptions import InvalidInputError


def baselines_folder() -> Path:
    """Where the shipped baselines live."""
    return Path(str(resources.files("mjtraj.rl.baselines")))


def baseline_names() -> list[str]:
    """The shipped baselines, sorted."""
    return sorted(p.parent.name for p in baselines_folder().glob("*/policy.zip"))


def baseline_path(name: str) -> Path:
    """The zip of baseline `name`.

    Raises:
      InvalidInputError: no such baseline (the message lists them).
    """
    path = baselines_folder() / name / "policy.zip"
    if not name or "/" in name or not path.is_file():
        raise InvalidInputError(f"policy: no baseline {name!r}; shipped: {', '.join(baseline_names()) or 'none'}")
    return path


def describe(name: str) -> dict[str, Any]:
    """A baseline's facts from its record: configuration settings, seed, steps, training wall time."""
    record = json.loads((baseline_path(name).parent / "policy.json").read_text())
    run = record["run"]
    return {"name": name, "algo": run["settings"]["algo"], "seed": run["settings"]["seed"],
            "timesteps": record["timesteps"], "env": run["env"], "settings": run["settings"]}
