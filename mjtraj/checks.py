"""Argument checks shared by the public entry points; each raises InvalidInputError naming the argument."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.exceptions import InvalidInputError


def vector(name: str, value: npt.ArrayLike, size: int) -> NDArray[np.float64]:
    """Return `value` as a finite float64 vector of length `size`, or raise naming `name`."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InvalidInputError(f"{name}: expected {size} numbers, got {value!r}") from e
    if array.ndim == 0:
        array = np.full(size, float(array))
    if array.shape != (size,):
        raise InvalidInputError(f"{name}: expected {size} values, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InvalidInputError(f"{name}: expected finite values, got {array.tolist()}")
    return array


def positive(name: str, value: float) -> float:
    """Return `value` as a finite float > 0, or raise naming `name`."""
    try:
        number = float(value)
    except (TypeError, ValueError) as e:
        raise InvalidInputError(f"{name}: expected a positive number, got {value!r}") from e
    if not np.isfinite(number) or number <= 0:
        raise InvalidInputError(f"{name}: expected a positive number, got {value!r}")
    return number


def in_range(name: str, value: float, low: float, high: float, *, low_open: bool = True,
             high_open: bool = True) -> float:
    """Return `value` as a float within low..high (each end open or closed; an infinite end is open), or raise naming
    `name` and the interval."""
    interval = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open or np.isinf(high) else ']'}"
    try:
        number = float(value)
    except (TypeError, ValueError) as e:
        raise InvalidInputError(f"{name}: expected a number in {interval}, got {value!r}") from e
    above = number > low if low_open else number >= low
    below = number < high if high_open else number <= high
    if not (np.isfinite(number) and above and below):
        raise InvalidInputError(f"{name}: expected a number in {interval}, got {value!r}")
    return number


def choice(name: str, value: str, valid: Iterable[str]) -> str:
    """Return `value` if it is one of `valid`, or raise listing the valid choices."""
    options = list(valid)
    if value not in options:
        raise InvalidInputError(f"{name}: unknown value {value!r}; valid: {', '.join(options)}")
    return value


def seed_value(name: str, value: int) -> int:
    """Return `value` as an int >= 0 (a seed), or raise naming `name`."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InvalidInputError(f"{name}: expected a whole number >= 0, got {value!r}")
    return int(value)


def positive_int(name: str, value: int) -> int:
    """Return `value` as an int >= 1, or raise naming `name`."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InvalidInputError(f"{name}: expected a whole number >= 1, got {value!r}")
    return int(value)


def nonnegative_int(name: str, value: int) -> int:
    """Return `value` as an int >= 0, or raise naming `name`."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InvalidInputError(f"{name}: expected a whole number >= 0, got {value!r}")
    return int(value)


def frozen(array: NDArray[np.float64]) -> NDArray[np.float64]:
    """Make `array` read-only and return it."""
    array.setflags(write=False)
    return array
