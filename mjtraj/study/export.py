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

import collections
import csv
import io
import itertools
import json
import math
import os
import shutil
import sqlite3
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path
from mjtraj.study.audit import expected_rows
from mjtraj.study.store import VERSION_COLUMNS, iter_cells, iter_rows
from mjtraj.study.sweep_store import is_sqlite_file, planner_row_counts

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

    def add(self, row: Sequence[str]) -> None:
        """Account for one row of cells, in the columns' order."""
        for column, cell in zip(self.columns, row, strict=True):
            if self._text[column]:
                continue
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


CHUNK = 1_000
"""Rows written at a time: export holds at most this many in memory, whatever the sweep's size."""


def csv_lines(rows: Iterable[Sequence[str]]) -> Iterator[str]:
    """Each row of text cells as the line csv.writer writes for it (QUOTE_MINIMAL, '\\n' line ends): the cells
    joined by commas when none holds a comma, a quote or a line break (a row of numbers), else csv.writer's line."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    for row in rows:
        line = ",".join(row)
        if line.count(",") == len(row) - 1 and '"' not in line and "\n" not in line and "\r" not in line and line:
            yield line + "\n"
        else:
            writer.writerow(row)
            yield buffer.getvalue()
            buffer.seek(0)
            buffer.truncate()


def _checked_pass(sweep: str | os.PathLike[str], kinds_needed: bool) -> tuple[list[str], ColumnKinds | None, int]:
    """The first pass over `sweep`: its columns, their kinds (if `kinds_needed`) and its row count, refusing a
    sweep that is not one, or is torn or unfinished (the rule of `complete_units` and `expected_rows`, counted
    unit by unit). Reads cells, not dicts: only the key columns are looked at unless kinds are needed."""
    cells = iter_cells(sweep)
    columns = list(next(cells))
    first_values = next(cells, None)
    if first_values is None:
        raise InvalidInputError(f"sweep: no rows in {sweep}")
    first = dict(zip(columns, first_values, strict=True))
    missing = [c for c in SWEEP_KEYS if c not in first]
    if missing:
        raise InvalidInputError(f"sweep: {sweep} is not a sweep results file (missing columns {', '.join(missing)})")
    planners = set(first["sweep_planners"].split("+"))
    gathered = ColumnKinds(columns) if kinds_needed else None
    at_family, at_unit, at_planner = (columns.index(c) for c in ("family", "unit", "planner"))
    if gathered is None and is_sqlite_file(sweep):  # a store's counts by SQLite: no row reaches Python
        cells.close()
        total, counts = planner_row_counts(sweep, planners)
    else:
        total, counts = 0, collections.Counter()
        for values in itertools.chain([first_values], cells):
            total += 1
            if values[at_planner] in planners:  # rows of other controllers ride along with their unit
                counts[(values[at_family], values[at_unit])] += 1
            if gathered is not None:
                gathered.add(values)
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
                cells = iter_cells(sweep)  # the header, then each row's text cells in the header's order
                lines = csv_lines(cells)
                while text := "".join(itertools.islice(lines, CHUNK)):
                    f.write(text)
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
