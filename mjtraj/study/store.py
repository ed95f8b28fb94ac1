"""A sweep's results file: CSV, one row per scenario, controller variant and planner, appended unit by unit.

Each unit's rows go out in one write, flushed and fsynced, so an interrupted sweep leaves whole units and at most
one torn unit at the end. Resuming checks that the file was written by the same versions with the same
settings, cuts the torn tail, and reports which units are done. Floats are written as repr(), which reads back
to the same bits.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections import Counter
from pathlib import Path
from typing import Any

from mjtraj.exceptions import InvalidInputError

SETTING_PREFIXES = ("sweep_", "sensor_noise", "delay", "model_error_measured", "config", "feedforward", "anti_windup",
                    "substeps", "dt", "kp_", "ki_", "kd_")
VERSION_COLUMNS = ("mjtraj", "mujoco", "numpy")


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    return str(value)


def format_rows(columns: list[str], rows: list[dict[str, Any]]) -> str:
    """CSV text of `rows` (no header)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    for row in rows:
        writer.writerow([_cell(row[c]) for c in columns])
    return buffer.getvalue()


def csv_text(columns: list[str], rows: list[dict[str, Any]]) -> str:
    """CSV text of the header `columns` and `rows`."""
    return format_rows(columns, [dict(zip(columns, columns, strict=True)), *rows])


def append_rows(path: Path, columns: list[str], rows: list[dict[str, Any]]) -> None:
    """Append `rows` to the CSV file `path` in one write, flushed and fsynced (durable when this returns)."""
    with open(path, "a", newline="") as f:
        f.write(format_rows(columns, rows))
        f.flush()
        os.fsync(f.fileno())


def read_rows(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """The rows of a results file as dicts of strings (use `numeric` for the numbers).

    Raises:
      InvalidInputError: the file is not text, or a row has more or fewer cells than the header (a torn write:
        the message names the line).
    """
    with open(path, "rb") as raw:
        size = raw.seek(0, os.SEEK_END)
        if size:
            raw.seek(size - 1)
            if raw.read(1) != b"\n":
                raise InvalidInputError(f"sweep: {path} ends inside a row (a torn write); resume the sweep to repair "
                                        f"it")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            rows = []
            for row in reader:
                if None in row or None in row.values():
                    raise InvalidInputError(f"sweep: {path} line {reader.line_num} has "
                                            f"{'more' if None in row else 'fewer'} cells than the header (a torn or "
                                            f"damaged file); resume the sweep to repair it")
                rows.append(row)
            return rows
    except UnicodeDecodeError as e:
        raise InvalidInputError(f"sweep: {path} is not a text results file (not UTF-8 at byte {e.start})") from e


def numeric(value: str) -> float:
    """A cell as a float (NaN for '' or 'nan')."""
    return float(value) if value not in ("", "nan") else math.nan


class ResultsFile:
    """Append-only writer of one sweep's rows; create with `open`."""

    def __init__(self, path: Path, columns: list[str], done: set[tuple[str, int]]) -> None:
        self.path = path
        self.columns = columns
        self.done = done
        """(family, unit) already in the file."""

    @classmethod
    def open(cls, path: str | os.PathLike[str], columns: list[str], settings: dict[str, Any],
             unit_rows: dict[tuple[str, int], int], *, resume: bool) -> ResultsFile:
        """Start `path` afresh (it must not exist unless `resume`), or continue it.

        Args:
          columns: the header.
          settings: the setting and version columns every row of this sweep carries, name -> value.
          unit_rows: rows of each complete unit.

        Raises:
          InvalidInputError: the file exists without resume; or it was written by other versions, with other
            settings or other columns (the message names the first difference).
        """
        file = Path(path)
        if file.exists() and not resume:
            raise InvalidInputError(f"out: {file} exists; pass --resume to continue that sweep, or choose another "
                                    f"path")
        if not file.exists() or file.stat().st_size == 0:
            file.parent.mkdir(parents=True, exist_ok=True)
            append_rows(file, columns, [dict(zip(columns, columns, strict=True))])  # absent or empty: the header
            return cls(file, columns, set())
        done, keep = _check(file, columns, settings, unit_rows)
        with open(file, "r+b") as f:
            f.truncate(keep)
        return cls(file, columns, done)

    def append(self, rows: list[dict[str, Any]]) -> None:
        """Write a unit's rows at once and make them durable."""
        append_rows(self.path, self.columns, rows)


def _check(file: Path, columns: list[str], settings: dict[str, Any], unit_rows: dict[tuple[str, int], int]
           ) -> tuple[set[tuple[str, int]], int]:
    """Validate a file to resume; return its complete units and the byte length that holds them."""
    data = file.read_bytes()
    lines = data.split(b"\n")
    header = next(csv.reader([lines[0].decode()]))
    if header != columns:
        missing = [c for c in columns if c not in header]
        extra = [c for c in header if c not in columns]
        raise InvalidInputError(f"out: cannot resume {file}: its columns differ from this version's "
                                f"(missing {missing[:5]}, unexpected {extra[:5]}); it was written by another "
                                f"mjtraj version; start a new file")
    index = {c: i for i, c in enumerate(columns)}
    counts: Counter[tuple[str, int]] = Counter()
    offset = len(lines[0]) + 1
    keep = offset
    order: list[tuple[str, int]] = []
    complete = lines[-1] == b""  # the last line ended with a newline
    body = lines[1:-1] if complete else lines[1:]
    for number, raw in enumerate(body, start=2):
        offset += len(raw) + 1
        if not complete and number == len(body) + 1:
            break  # a torn last line
        cells = next(csv.reader([raw.decode()]))
        if len(cells) != len(columns):
            break
        if number == 2:
            for name in VERSION_COLUMNS:
                if cells[index[name]] != str(settings[name]):
                    raise InvalidInputError(f"out: cannot resume {file}: it was written by {name} "
                                            f"{cells[index[name]]}, this is {name} {settings[name]}; start a new "
                                            f"file")
            for name, value in settings.items():
                if name not in VERSION_COLUMNS and cells[index[name]] != _cell(value):
                    raise InvalidInputError(f"out: cannot resume {file}: setting {name!r} differs (file: "
                                            f"{cells[index[name]]!r}, now: {_cell(value)!r}); resume with the same "
                                            f"settings or start a new file")
        unit = (cells[index["family"]], int(cells[index["unit"]]))
        if not order or order[-1] != unit:
            order.append(unit)
        counts[unit] += 1
        if counts[unit] == unit_rows.get(unit, -1):
            keep = offset
    done = {unit for unit in order if counts[unit] == unit_rows.get(unit, -1)}
    return done, keep
