"""Scenario files out: the TOML text of nested tables of strings, numbers, booleans and lists (what
`Scenario.as_dict` holds), read back by tomllib to the same values."""

from __future__ import annotations

import json
import math
from typing import Any

from mjtraj.exceptions import InvalidInputError


def _value(key: str, value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InvalidInputError(f"{key}: TOML has no place for {value!r}")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(key, v) for v in value) + "]"
    raise InvalidInputError(f"{key}: cannot write {type(value).__name__} {value!r} to a scenario file")


def dumps(data: dict[str, Any], *, header: str = "") -> str:
    """TOML text of `data`: its plain keys first, then each table (nested tables as [a.b]); `header` as comments."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]

    def table(path: str, body: dict[str, Any]) -> None:
        plain = {k: v for k, v in body.items() if not isinstance(v, dict)}
        nested = {k: v for k, v in body.items() if isinstance(v, dict)}
        if path and (plain or not nested):
            lines.extend(["", f"[{path}]"])
        lines.extend(f"{k} = {_value(k, v)}" for k, v in plain.items())
        for k, v in nested.items():
            table(f"{path}.{k}" if path else k, v)

    table("", data)
    return "\n".join(lines).lstrip("\n") + "\n"
