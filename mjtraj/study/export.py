"""`mjtraj export`: a sweep's results (a SQLite store or a CSV file) as a typed SQLite table, JSON Lines, or CSV.

The sweep's own store (`mjtraj.study.sweep_store`, or the CSV results file) is what a sweep appends to, unit by
unit, and resumes; export turns a complete one into the formats analysis tools read directly (pandas:
`pd.read_csv`, `pd.read_sql("SELECT * FROM rows", connection)`, `pd.read_json(..., lines=True)`). CSV output is
the CSV results file's text, byte for byte. A column is text when it is one of TEXT_COLUMNS (names, reasons,
versions: '3.10' is not 3.1) or a present cell of it is not a number; else a number ('' and 'nan' are missing
values: SQL NULL, JSON null), whole when every present cell is written as a whole number. Only complete sweeps are
exported (a torn or unfinished file is refused, as the audit refuses it); the output is written atomically.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path
from mjtraj.study.audit import expected_rows
from mjtraj.study.store import VERSION_COLUMNS, iter_rows
from mjtraj.study.sweep_store import is_sqlite_file

FORMATS = {".sqlite": "sqlite", ".db": "sqlite", ".jsonl": "jsonl", ".csv": "csv"}
TEXT_COLUMNS = ("family", "planner", "ff_accel", "gravity_comp", "status", "reason", "solver", "config",
                "config_sha256", *VERSION_COLUMNS)
SWEEP_KEYS = ("family", "scenario", "unit", "planner", "status", "sweep_scenarios", "sweep_batch")
"""Columns every sweep results file has."""
TABLE = "rows"
"""The SQLite table that holds the rows (indexed by family, scenario and planner)."""


def _number(cell: str) -> float | None:
    """The cell as a float, None for a missing value; raises ValueError for text."""
    if cell in ("", "nan"):
        return None
    value = float(cell)
    return None if math.isnan(value) else value


class ColumnKinds:
    """Each column's kind ('REAL', 'INTEGER' or 'TEXT', by the module's rule), gathered one row at a time."""

    def __init__(self, columns: list[str]) -> None:
        self.columns = columns
        self._text = {c: c in TEXT_COLUMNS for c in columns}
        self._present = dict.fromkeys(columns, False)
        self._whole = dict.fromkeys(columns, True)

    def add(self, row: dict[str, str]) -> None:
        """Account for one row of cells."""
        for column in self.columns:
            if self._text[column]:
                continue
            cell = row[column]
            try:
                value = _number(cell)
            except ValueError:
                self._text[column] = True
                continue
            if value is not None:
                self._present[column] = True
                if "." in cell or "e" in cell.lower():
                    self._whole[column] = False

    def kinds(self) -> dict[str, str]:
        """column -> 'TEXT', 'INTEGER' (every present cell written whole) or 'REAL'."""
        return {c: "TEXT" if self._text[c] else "INTEGER" if self._present[c] and self._whole[c] else "REAL"
                for c in self.columns}


def typed(row: dict[str, str], kinds: dict[str, str]) -> dict[str, Any]:
    """`row` with its cells as the values of their columns' kinds (None for a missing number)."""
    out: dict[str, Any] = {}
    for column, kind in kinds.items():
        cell = row[column]
        if kind == "TEXT":
            out[column] = cell
        else:
            value = _number(cell)
            out[column] = None if value is None else int(value) if kind == "INTEGER" else value
    return out


def typed_rows(rows: list[dict[str, str]]) -> tuple[list[str], dict[str, str], list[dict[str, Any]]]:
    """(columns, column -> 'REAL' | 'INTEGER' | 'TEXT', the rows with typed values)."""
    columns = list(rows[0]) if rows else []
    gathered = ColumnKinds(columns)
    for row in rows:
        gathered.add(row)
    kinds = gathered.kinds()
    return columns, kinds, [typed(r, kinds) for r in rows]


CHUNK = 1_000
"""Rows written at a time: export holds at most this many in memory, whatever the sweep's size."""


def _checked_pass(sweep: str | os.PathLike[str], kinds_needed: bool) -> tuple[list[str], ColumnKinds | None, int]:
    """The first pass over `sweep`: its columns, their kinds (if `kinds_needed`) and its row count, refusing a
    sweep that is not one, or is torn or unfinished (the rule of `complete_units` and `expected_rows`, counted
    unit by unit)."""
    columns: list[str] = []
    gathered: ColumnKinds | None = None
    counts: dict[tuple[str, str], int] = {}
    total = 0
    first: dict[str, str] = {}
    for row in iter_rows(sweep):
        if not total:
            first, columns = row, list(row)
            missing = [c for c in SWEEP_KEYS if c not in row]
            if missing:
                raise InvalidInputError(f"sweep: {sweep} is not a sweep results file (missing columns "
                                        f"{', '.join(missing)})")
            planners = set(row["sweep_planners"].split("+"))
            gathered = ColumnKinds(columns) if kinds_needed else None
        total += 1
        if row["planner"] in planners:  # rows of other controllers ride along with their unit
            counts[(row["family"], row["unit"])] = counts.get((row["family"], row["unit"]), 0) + 1
        if gathered is not None:
            gathered.add(row)
    if not total:
        raise InvalidInputError(f"sweep: no rows in {sweep}")
    try:
        per_scenario = int(np.prod([len(first[k].split("+")) for k in ("sweep_planners", "sweep_ff_accel",
                                                                       "sweep_gravity_comp")]))
        batch, scenarios = int(first["sweep_batch"]), int(first["sweep_scenarios"])
        torn = any(n != per_scenario * min(batch, scenarios - int(unit) * batch) for (_, unit), n in counts.items())
    except (KeyError, ValueError) as e:
        raise InvalidInputError(f"sweep: a row's settings are malformed ({e}); not a sweep results file") from e
    if torn or total < expected_rows(first):
        raise InvalidInputError(f"sweep: {sweep} is unfinished; finish it with the same mjtraj sweep command and "
                                f"--resume before exporting it")
    return columns, gathered, total


def _chunks(sweep: str | os.PathLike[str]) -> Iterator[list[dict[str, str]]]:
    """The rows of `sweep` in lists of at most CHUNK."""
    chunk: list[dict[str, str]] = []
    for row in iter_rows(sweep):
        chunk.append(row)
        if len(chunk) == CHUNK:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


def export(sweep: str | os.PathLike[str], out: str | os.PathLike[str]) -> int:
    """Write the complete sweep `sweep` (store or CSV file) to `out` (format by suffix: .sqlite or .db, .jsonl,
    .csv); return the rows. Two passes over the sweep (checks and column kinds, then the output), CHUNK rows in
    memory at a time: bounded memory, time proportional to the rows.

    Raises:
      InvalidInputError: unknown output suffix, no such sweep file, or a torn or unfinished sweep.
    """
    target = Path(out)
    kind = FORMATS.get(target.suffix.lower())
    if kind is None:
        raise InvalidInputError(f"out: expected a file ending in {', '.join(FORMATS)}, got {str(out)!r}")
    if not Path(sweep).is_file():
        raise InvalidInputError(f"sweep: file not found: {sweep}")
    if Path(sweep).resolve() == target.resolve():
        raise InvalidInputError(f"out: {out} is the sweep itself; choose another path")
    columns, gathered, total = _checked_pass(sweep, kinds_needed=kind != "csv")
    with atomic_path(target) as tmp:
        if kind == "csv" and not is_sqlite_file(sweep):  # checked complete: its text is the output, byte for byte
            shutil.copyfile(sweep, tmp)
        elif kind == "csv":
            with open(tmp, "w", encoding="utf-8", newline="") as f:
                writer = csv.writer(f, lineterminator="\n")
                writer.writerow(columns)
                for chunk in _chunks(sweep):  # a store's cells are already text (iter_store_rows)
                    writer.writerows([row[c] for c in columns] for row in chunk)
        elif kind == "jsonl":
            assert gathered is not None
            kinds = gathered.kinds()
            with open(tmp, "w", encoding="utf-8") as f:
                for chunk in _chunks(sweep):
                    f.write("".join(json.dumps(typed(row, kinds), allow_nan=False) + "\n" for row in chunk))
        else:
            assert gathered is not None
            _write_sqlite(tmp, columns, gathered.kinds(), sweep)
    return total


def _write_sqlite(path: Path, columns: list[str], kinds: dict[str, str], sweep: str | os.PathLike[str]) -> None:
    quoted = ", ".join(f'"{c}" {kinds[c]}' for c in columns)
    connection = sqlite3.connect(path)
    try:
        with connection:
            connection.execute(f"CREATE TABLE {TABLE} ({quoted})")
            marks = ", ".join("?" for _ in columns)
            for chunk in _chunks(sweep):
                connection.executemany(f"INSERT INTO {TABLE} VALUES ({marks})",
                                       (list(typed(row, kinds).values()) for row in chunk))  # in column order
            keys = [c for c in ("family", "scenario", "planner") if c in columns]
            if keys:
                connection.execute(f"CREATE INDEX {TABLE}_keys ON {TABLE} ({', '.join(keys)})")
    finally:
        connection.close()
