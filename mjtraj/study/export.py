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
import math
import os
import shutil
import sqlite3
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from json.encoder import encode_basestring_ascii  # type: ignore[attr-defined]
from pathlib import Path
from typing import Any

import numpy as np

from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path
from mjtraj.study.audit import expected_rows
from mjtraj.study.store import VERSION_COLUMNS, iter_cells
from mjtraj.study.sweep_store import is_sqlite_file, planner_row_counts

FORMATS = {".sqlite": "sqlite", ".db": "sqlite", ".jsonl": "jsonl", ".csv": "csv"}
TEXT_COLUMNS = ("family", "planner", "ff_accel", "gravity_comp", "status", "reason", "solver", "config",
                "config_sha256", *VERSION_COLUMNS)
SWEEP_KEYS = ("family", "scenario", "unit", "planner", "status", "sweep_scenarios", "sweep_batch")
"""Columns every sweep results file has."""
TABLE = "rows"
"""The SQLite table that holds the rows (indexed by family, scenario and planner)."""


class ColumnKinds:
    """Each column's kind ('REAL', 'INTEGER' or 'TEXT', by the module's rule), gathered a chunk of rows at a time."""

    def __init__(self, columns: list[str]) -> None:
        self.columns = columns
        self._text = {c: c in TEXT_COLUMNS for c in columns}
        self._present = dict.fromkeys(columns, False)
        self._whole = dict.fromkeys(columns, True)

    def add(self, rows: Sequence[Sequence[str]]) -> list[Numbers | None]:
        """Account for rows of cells, each in the columns' order, and return each column's `Numbers` (None for a
        text column). Column by column over its distinct cells: a cell that float() refuses makes the column text;
        '.', 'e' or 'E' in a number makes it not whole (no spelling of nan or infinity holds one, so the missing
        cells need not be told apart here)."""
        out: list[Numbers | None] = []
        for column, cells in zip(self.columns, zip(*rows, strict=True), strict=True) if rows else ():
            numbers = None if self._text[column] else Numbers.of(cells)
            out.append(numbers)
            if numbers is None:
                self._text[column] = True
            elif numbers.present:
                self._present[column] = True
                text = "".join(numbers.cells)
                if "." in text or "e" in text or "E" in text:
                    self._whole[column] = False
        return out

    def kinds(self) -> dict[str, str]:
        """column -> 'TEXT', 'INTEGER' (every present cell written whole) or 'REAL'."""
        return {c: "TEXT" if self._text[c] else "INTEGER" if self._present[c] and self._whole[c] else "REAL"
                for c in self.columns}


MISSING = frozenset(("", "nan"))
"""Cells that are missing values (as is any that float() reads as nan)."""


@dataclass(frozen=True)
class Numbers:
    """The distinct cells of a column's chunk that are not MISSING, and their values (float(); nan among them for
    other spellings of it), in the same order; `present`: whether one is not nan."""

    cells: tuple[str, ...]
    values: tuple[float, ...]
    present: bool

    @classmethod
    def of(cls, cells: Iterable[str]) -> Numbers | None:
        """The Numbers of `cells`, or None if float() refuses one (a text column)."""
        distinct = tuple(set(cells) - MISSING)
        try:
            values = tuple(map(float, distinct))
        except ValueError:
            return None
        return cls(distinct, values, not all(map(math.isnan, values)))

    def texts(self, kind: str) -> Iterator[str | None]:
        """Each cell's value as JSON text in a column of `kind` ('INTEGER' or 'REAL'), None for a missing one.

        Raises:
          ValueError: an infinity, which JSON cannot hold.
        """
        if all(map(math.isfinite, self.values)):  # the common case, without a Python call per cell
            return map(int.__repr__, map(int, self.values)) if kind == "INTEGER" else map(float.__repr__,
                                                                                          self.values)
        return (None if math.isnan(v) else _finite_text(v, kind) for v in self.values)

    def typed(self, kind: str) -> Iterator[int | float | None]:
        """Each cell's value in a column of `kind` ('INTEGER' or 'REAL'), None for a missing one."""
        whole = kind == "INTEGER"
        return (None if math.isnan(v) else int(v) if whole else v for v in self.values)


def _finite_text(value: float, kind: str) -> str:
    if not math.isfinite(value):
        raise ValueError(f"{value!r} is not a finite number")
    return repr(int(value)) if kind == "INTEGER" else repr(value)


def typed_columns(rows: Sequence[Sequence[str]], kinds: Sequence[str],
                  numbers: Sequence[Numbers | None] | None = None) -> list[list[Any]]:
    """The rows' cells, column by column, as the values of their columns' `kinds` (None for a missing number);
    each distinct cell of a column is converted once (`numbers`: each column's, if already read)."""
    out = []
    for i, (kind, cells) in enumerate(zip(kinds, zip(*rows, strict=True), strict=True)):
        if kind == "TEXT":
            out.append(list(cells))
            continue
        read = numbers[i] if numbers is not None else Numbers.of(cells)
        if read is None:
            raise InvalidInputError(f"sweep: a cell of a {kind} column is not a number")
        values: dict[str, Any] = dict.fromkeys(MISSING)
        values.update(zip(read.cells, read.typed(kind), strict=True))
        out.append(list(map(values.__getitem__, cells)))
    return out


def jsonl_text(columns: Sequence[str], kinds: Sequence[str], rows: Sequence[Sequence[str]],
               numbers: Sequence[Numbers | None] | None = None) -> str:
    """The rows as JSON Lines: for each row the line `json.dumps(dict(zip(columns, typed values)), allow_nan=False)`
    writes (then a line end), built column by column from each distinct cell's JSON text (`numbers`: each
    column's, if already read).

    Raises:
      InvalidInputError: a number that JSON cannot hold (an infinity), naming its column, or a cell of a number
        column that is not a number.
    """
    if not rows:
        return ""
    pieces: list[Iterable[str]] = []
    for i, (column, kind, cells) in enumerate(zip(columns, kinds, zip(*rows, strict=True), strict=True)):
        key = ("{" if i == 0 else ", ") + encode_basestring_ascii(column) + ": "
        if kind == "TEXT":
            distinct = set(cells)
            parts = dict(zip(distinct, map(key.__add__, map(encode_basestring_ascii, distinct)), strict=True))
        else:
            read = numbers[i] if numbers is not None else Numbers.of(cells)
            if read is None:
                raise InvalidInputError(f"sweep: column {column!r} is a number column with a cell that is not")
            parts = dict.fromkeys(MISSING, key + "null")
            try:
                parts.update((cell, key + ("null" if text is None else text))
                             for cell, text in zip(read.cells, read.texts(kind), strict=True))
            except ValueError as e:
                raise InvalidInputError(f"sweep: column {column!r} holds a number JSON cannot hold ({e})") from None
        pieces.append(map(parts.__getitem__, cells))
    pieces.append(itertools.repeat("}\n"))
    return "".join(map("".join, zip(*pieces, strict=False)))  # the line ends repeat without end


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
    rows = itertools.chain([first_values], cells)
    if is_sqlite_file(sweep):  # a store's counts by SQLite: no row reaches Python for them
        total, counts = planner_row_counts(sweep, planners)
        if gathered is not None:
            for chunk in _batched(rows):
                gathered.add(chunk)
        cells.close()
    else:
        total, counts = 0, collections.Counter()
        for chunk in _batched(rows):
            total += len(chunk)  # rows of other controllers ride along with their unit
            counts.update((values[at_family], values[at_unit]) for values in chunk if values[at_planner] in planners)
            if gathered is not None:
                gathered.add(chunk)
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


def _batched(rows: Iterator[tuple[str, ...]]) -> Iterator[list[tuple[str, ...]]]:
    """`rows` in lists of at most CHUNK."""
    while chunk := list(itertools.islice(rows, CHUNK)):
        yield chunk


def _cell_chunks(sweep: str | os.PathLike[str]) -> Iterator[list[tuple[str, ...]]]:
    """The rows of `sweep` as cells in the header's order, in lists of at most CHUNK."""
    cells = iter_cells(sweep)
    next(cells)
    yield from _batched(cells)


def export(sweep: str | os.PathLike[str], out: str | os.PathLike[str],
           progress: Callable[[int, int], None] | None = None) -> int:
    """Write the complete sweep `sweep` (store or CSV file) to `out` (format by suffix: .sqlite or .db, .jsonl,
    .csv); return the rows. CHUNK rows in memory at a time: bounded memory, time proportional to the rows.
    `progress(rows written, rows)` is called after each chunk written (again from 0 if the output is rewritten).

    A CSV file is read twice (checks and column kinds, then the output). A store is checked by SQLite and read
    once where it can be: the typed formats are written under the kinds of the rows read so far, which is the
    output of two passes as long as no later row changes a column's kind (a column whose first cells are all
    missing and whose later ones are whole numbers, a number column that turns to text); when one does, the
    output is written again under the kinds of every row.

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
    store = is_sqlite_file(sweep)
    columns, gathered, total = _checked_pass(sweep, kinds_needed=kind != "csv" and not store)
    written = _Written(total, progress)
    with atomic_path(target) as tmp:
        if kind == "csv" and not store:  # checked complete: its text is the output, byte for byte
            shutil.copyfile(sweep, tmp)
        elif kind == "csv":
            with open(tmp, "w", encoding="utf-8", newline="") as f:
                cells = iter_cells(sweep)  # the header, then each row's text cells in the header's order
                lines = csv_lines(cells)
                while text := "".join(itertools.islice(lines, CHUNK)):
                    f.write(text)
                    written.add(CHUNK)
        else:
            write = _write_jsonl if kind == "jsonl" else _write_sqlite
            if gathered is None and not write(tmp, columns, None, sweep, written):
                gathered = ColumnKinds(columns)  # a later row changed a kind: every row's kinds, then again
                for chunk in _cell_chunks(sweep):
                    gathered.add(chunk)
            if gathered is not None:
                write(tmp, columns, gathered.kinds(), sweep, written.restart())
    written.add(total)
    return total


class _Written:
    """The rows written so far, reported to `progress(done, total)` (None: to no one)."""

    def __init__(self, total: int, progress: Callable[[int, int], None] | None) -> None:
        self.total, self.progress, self.done = total, progress, 0

    def add(self, rows: int) -> None:
        self.done = min(self.done + rows, self.total)
        if self.progress is not None:
            self.progress(self.done, self.total)

    def restart(self) -> _Written:
        self.done = 0
        self.add(0)
        return self


def _kinds_as_read(columns: list[str], kinds: dict[str, str] | None, sweep: str | os.PathLike[str]
                   ) -> Iterator[tuple[list[tuple[str, ...]], list[str], list[Numbers | None] | None]]:
    """Each chunk of `sweep` with the kinds to write it under and its columns' Numbers if read: `kinds` if given,
    else those of the rows read so far; stops (the caller's output is then incomplete) at the first chunk that
    changes them."""
    gathered = ColumnKinds(columns)
    first: dict[str, str] | None = None
    for chunk in _cell_chunks(sweep):
        numbers = None
        if kinds is None:
            numbers = gathered.add(chunk)
            now = gathered.kinds()
            first = now if first is None else first
            if now != first:
                raise _KindsChanged
        yield chunk, list((kinds or first or {}).values()), numbers


class _KindsChanged(Exception):
    """A row read later changed a column's kind: what was written under the earlier kinds is not the output."""


def _write_jsonl(path: Path, columns: list[str], kinds: dict[str, str] | None, sweep: str | os.PathLike[str],
                 written: _Written) -> bool:
    """Write `sweep` as JSON Lines under `kinds` (None: as read, see `_kinds_as_read`); False if the kinds as read
    changed (the file is then incomplete)."""
    with open(path, "w", encoding="utf-8") as f:
        try:
            for chunk, chunk_kinds, numbers in _kinds_as_read(columns, kinds, sweep):
                f.write(jsonl_text(columns, chunk_kinds, chunk, numbers))
                written.add(len(chunk))
        except _KindsChanged:
            return False
    return True


def _write_sqlite(path: Path, columns: list[str], kinds: dict[str, str] | None, sweep: str | os.PathLike[str],
                  written: _Written) -> bool:
    """Write `sweep` as a typed SQLite table under `kinds` (None: as read, see `_kinds_as_read`); False if the kinds
    as read changed (nothing is then written)."""
    path.unlink(missing_ok=True)
    connection = sqlite3.connect(path)
    try:
        with connection:
            marks = ", ".join("?" for _ in columns)
            for chunk, chunk_kinds, numbers in _kinds_as_read(columns, kinds, sweep):
                if connection.total_changes == 0:
                    quoted = ", ".join(f'"{c}" {k}' for c, k in zip(columns, chunk_kinds, strict=True))
                    connection.execute(f"CREATE TABLE {TABLE} ({quoted})")
                connection.executemany(f"INSERT INTO {TABLE} VALUES ({marks})",
                                       zip(*typed_columns(chunk, chunk_kinds, numbers), strict=True))
                written.add(len(chunk))
            keys = [c for c in ("family", "scenario", "planner") if c in columns]
            if keys:
                connection.execute(f"CREATE INDEX {TABLE}_keys ON {TABLE} ({', '.join(keys)})")
    except _KindsChanged:
        return False
    finally:
        connection.close()
    return True
