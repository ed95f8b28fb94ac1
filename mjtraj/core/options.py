"""Declared options: a dataclass field states its type, default, choices, bounds and help once; validation, typed
parsing (scenario files, keyword arguments) and command-line flags are generated from that declaration.

    feedforward: str = option("inverse", "feedforward torque", choices=("inverse", "planned", "none"), flag="--ff")

Adding an option to a configuration dataclass is that one line: `check` validates it, `from_mapping` reads it from
a scenario file or keyword arguments with its type enforced, and `mjtraj.cli` adds its flag.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mjtraj.exceptions import InvalidInputError


@dataclass(frozen=True)
class Option:
    """What a field declares about itself (see `option`)."""

    help: str
    choices: tuple[Any, ...] | Callable[[], tuple[Any, ...]] | None = None
    """The valid values, or a function giving them when asked (values that plug-ins extend)."""
    minimum: float | None = None
    """Smallest valid value (inclusive)."""
    positive: bool = False
    """The value must be > 0."""
    flag: str | None = None
    """A short command-line flag besides --<name-with-dashes>."""
    scenario: bool = True
    """Part of scenario files, the command line and env arguments; False: a programmatic setting only."""


def option(default: Any, help: str, *, choices: tuple[Any, ...] | Callable[[], tuple[Any, ...]] | None = None,
           minimum: float | None = None, positive: bool = False, flag: str | None = None, scenario: bool = True
           ) -> Any:
    """A dataclass field with a default and its declaration (see the module docstring)."""
    return dataclasses.field(default=default, metadata={"option": Option(help, choices, minimum, positive, flag,
                                                                         scenario)})


def declared_options(cls: type, *, scenario_only: bool = False) -> list[tuple[dataclasses.Field[Any], Option, type]]:
    """(field, declaration, type) of each declared option of the dataclass `cls`, in declaration order."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        declaration = f.metadata.get("option")
        if declaration is not None and (declaration.scenario or not scenario_only):
            out.append((f, declaration, hints[f.name]))
    return out


def option_names(cls: type, *, scenario_only: bool = True) -> tuple[str, ...]:
    """Names of the declared options of `cls`."""
    return tuple(f.name for f, _, _ in declared_options(cls, scenario_only=scenario_only))


def _typed(name: str, value: Any, kind: type, where: str) -> Any:
    """`value` if it has the type `kind` (an int passes as a float; a bool never passes as a number)."""
    label = {str: "a string", int: "a whole number", float: "a number", bool: "true or false"}[kind]
    ok = isinstance(value, bool) if kind is bool else (
        not isinstance(value, bool) and (isinstance(value, (int, np.integer)) if kind is int else
                                         isinstance(value, (int, float, np.integer, np.floating)) if kind is float
                                         else isinstance(value, kind)))
    if not ok:
        raise InvalidInputError(f"{name}: expected {label}{where}, got {value!r}")
    return float(value) if kind is float else int(value) if kind is int else value


def check_value(name: str, declaration: Option, kind: type, value: Any, where: str = "") -> Any:
    """Validate one option value (type, choices, bounds); return it normalised."""
    value = _typed(name, value, kind, where)
    valid = resolved_choices(declaration)
    if valid is not None and value not in valid:
        raise InvalidInputError(f"{name}: unknown value {value!r}{where}; valid: {', '.join(str(c) for c in valid)}")
    if kind in (int, float):
        if not math.isfinite(value):
            raise InvalidInputError(f"{name}: expected a finite number{where}, got {value!r}")
        if declaration.positive and value <= 0:
            raise InvalidInputError(f"{name}: expected a positive number{where}, got {value!r}")
        if declaration.minimum is not None and value < declaration.minimum:
            raise InvalidInputError(f"{name}: expected a value >= {declaration.minimum:g}{where}, got {value!r}")
    return value


def resolved_choices(declaration: Option) -> tuple[Any, ...] | None:
    """The declaration's valid values now (calling its function, if it gives one)."""
    return declaration.choices() if callable(declaration.choices) else declaration.choices


def check_options(instance: Any) -> None:
    """Validate every declared option of a dataclass instance (call it from `__post_init__`); normalises
    numbers in place (an int given for a float option becomes a float)."""
    for f, declaration, kind in declared_options(type(instance)):
        value = check_value(f.name, declaration, kind, getattr(instance, f.name))
        object.__setattr__(instance, f.name, value)


def from_mapping(cls: type, values: dict[str, Any], *, where: str = "", scenario_only: bool = True
                 ) -> dict[str, Any]:
    """The declared options of `cls` found in `values`, type-checked; an unknown key is an error listing the valid
    ones. `where` names the source in messages (' in [controller]')."""
    valid = {f.name: (declaration, kind) for f, declaration, kind in declared_options(cls, scenario_only=scenario_only)}
    out = {}
    for key, value in values.items():
        if key not in valid:
            raise InvalidInputError(f"{key}: unknown option{where}; valid: {', '.join(valid)}")
        out[key] = check_value(key, *valid[key], value, where)
    return out


def choices(cls: type, name: str) -> tuple[Any, ...]:
    """The valid values of the declared option `name` of `cls`."""
    for f, declaration, _ in declared_options(cls):
        valid = resolved_choices(declaration)
        if f.name == name and valid is not None:
            return valid
    raise InvalidInputError(f"{name}: not a declared option with choices of {cls.__name__}")
