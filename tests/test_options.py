"""Declared options: validation, typed parsing and the lists generated from one declaration."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from mjtraj.core.closed_loop import LoopConfig
from mjtraj.core.options import check_options, choices, declared_options, from_mapping, option, option_names
from mjtraj.exceptions import InvalidInputError


@dataclass(frozen=True)
class Toy:
    mode: str = option("a", "a mode", choices=("a", "b"))
    count: int = option(1, "a count", minimum=1)
    scale: float = option(1.0, "a scale", positive=True)
    hidden: int = option(0, "not in files", scenario=False)

    def __post_init__(self) -> None:
        check_options(self)


def test_declarations_drive_names_and_choices():
    assert option_names(Toy) == ("mode", "count", "scale")
    assert option_names(Toy, scenario_only=False) == ("mode", "count", "scale", "hidden")
    assert choices(Toy, "mode") == ("a", "b")
    assert [f.name for f, _, kind in declared_options(LoopConfig) if kind is str] == [
        "controller", "feedforward", "ff_accel", "gravity_comp", "anti_windup"]
    assert option_names(LoopConfig) == ("controller", "feedforward", "ff_accel", "gravity_comp", "anti_windup",
                                        "adaptation_rate", "substeps")


def test_an_int_is_accepted_as_a_float_and_normalised():
    toy = Toy(scale=2)
    assert toy.scale == 2.0 and isinstance(toy.scale, float)


@pytest.mark.parametrize(("values", "message"), [
    ({"mode": "c"}, r"^mode: unknown value 'c' in \[t\]; valid: a, b$"),
    ({"mode": 1}, r"^mode: expected a string in \[t\], got 1$"),
    ({"count": True}, r"^count: expected a whole number in \[t\], got True$"),
    ({"count": 1.5}, r"^count: expected a whole number in \[t\], got 1.5$"),
    ({"count": 0}, r"^count: expected a value >= 1 in \[t\], got 0$"),
    ({"scale": "big"}, r"^scale: expected a number in \[t\], got 'big'$"),
    ({"scale": float("nan")}, r"^scale: expected a finite number in \[t\], got nan$"),
    ({"scale": -1}, r"^scale: expected a positive number in \[t\], got -1.0$"),
    ({"hidden": 1}, r"^hidden: unknown option in \[t\]; valid: mode, count, scale$"),
])
def test_typed_parsing_names_the_option(values, message):
    with pytest.raises(InvalidInputError, match=message):
        from_mapping(Toy, values, where=" in [t]")


def test_construction_validates():
    with pytest.raises(InvalidInputError, match=r"^count: expected a value >= 1, got 0$"):
        Toy(count=0)
