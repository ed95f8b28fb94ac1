"""Print the declared floor of every dependency of mjtraj and of its `test` extra as an exact pin, one per line,
read from pyproject.toml (the one source of the floors). Left out, with the reason printed to stderr: markers for
other Pythons, and torch, whose CPU build on this machine's disk is the one CI installs (torch 2.3 would be a CUDA
download)."""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

LEFT_OUT = {"torch": "the CPU build 2.13.0 is installed first (torch 2.3 would be a CUDA download of gigabytes)"}

project = tomllib.loads((Path(__file__).parent.parent / "pyproject.toml").read_text())["project"]
for requirement in [*project["dependencies"], *project["optional-dependencies"]["test"]]:
    if ";" in requirement:
        continue
    match = re.fullmatch(r"([A-Za-z0-9_.-]+)(?:>=([0-9][0-9A-Za-z.]*))?,?(<[0-9][0-9.]*)?", requirement)
    if match is None:
        sys.exit(f"floors: cannot read the requirement {requirement!r}")
    name, floor, ceiling = match.groups()
    if name in LEFT_OUT:
        print(f"floors: {name} left out: {LEFT_OUT[name]}", file=sys.stderr)
    elif floor is not None:
        print(f"{name}=={floor}")
    else:
        print(f"{name}{ceiling or ''}")
