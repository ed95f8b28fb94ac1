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

import json
import math
import os
import sqlite3
from pathlib import Path
from typing import Any

from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path
from mjtraj.study.audit import complete_units, expected_rows
from mjtraj.study.store import VERSION_COLUMNS, csv_text, read_rows

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


def typed_rows(rows: list[dict[str, str]]) -> tuple[list[str], dict[str, str], list[dict[str, Any]]]:
    """(columns, column -> 'REAL' | 'INTEGER' | 'TEXT', the rows with typed values)."""
    columns = list(rows[0]) if rows else []
    kinds: dict[str, str] = {}
    for column in columns:
        cells = [r[column] for r in rows]
        try:
            values = [_number(c) for c in cells]
        except ValueError:
            values = []
        if column in TEXT_COLUMNS or not values:
            kinds[column] = "TEXT"
            continue
        present = [c for c, v in zip(cells, values, strict=True) if v is not None]
        whole = bool(present) and all("." not in c and "e" not in c.lower() for c in present)
        kinds[column] = "INTEGER" if whole else "REAL"
    out = []
    for r in rows:
        row: dict[str, Any] = {}
        for column in columns:
            cell = r[column]
            if kinds[column] == "TEXT":
                row[column] = cell
            else:
                value = _number(cell)
                row[column] = None if value is None else int(value) if kinds[column] == "INTEGER" else value
        out.append(row)
    return columns, kinds, out


def export(sweep: str | os.PathLike[str], out: str | os.PathLike[str]) -> int:
    """Write the complete sweep `sweep` (store or CSV file) to `out` (format by suffix: .sqlite or .db, .jsonl,
    .csv); return the rows.

    Raises:
      InvalidInputError: unknown output suffix, no such sweep file, or a torn or unfinished sweep.
    """
    target = Path(out)
    kind = FORMATS.get(target.suffix.lower())
    if kind is None:
        raise InvalidInputError(f"out: expected a file ending in {', '.join(FORMATS)}, got {str(out)!r}")
    if not Path(sweep).is_file():
        raise InvalidInputError(f"sweep: file not found: {sweep}")
    rows = read_rows(sweep)
    if not rows:
        raise InvalidInputError(f"sweep: no rows in {sweep}")
    missing = [c for c in SWEEP_KEYS if c not in rows[0]]
    if missing:
        raise InvalidInputError(f"sweep: {sweep} is not a sweep results file (missing columns {', '.join(missing)})")
    if len(complete_units(rows)) < len(rows) or len(rows) < expected_rows(rows[0]):
        raise InvalidInputError(f"sweep: {sweep} is unfinished; finish it with the same mjtraj sweep command and "
                                f"--resume before exporting it")
    if Path(sweep).resolve() == target.resolve():
        raise InvalidInputError(f"out: {out} is the sweep itself; choose another path")
    columns, kinds, typed = typed_rows(rows)
    with atomic_path(target) as tmp:
        if kind == "csv":
            tmp.write_text(csv_text(columns, rows), encoding="utf-8")
        elif kind == "jsonl":
            with open(tmp, "w", encoding="utf-8") as f:
                for row in typed:
                    f.write(json.dumps(row, allow_nan=False) + "\n")
        else:
            _write_sqlite(tmp, columns, kinds, typed)
    return len(typed)


def _write_sqlite(path: Path, columns: list[str], kinds: dict[str, str], rows: list[dict[str, Any]]) -> None:
    quoted = ", ".join(f'"{c}" {kinds[c]}' for c in columns)
    connection = sqlite3.connect(path)
    try:
        with connection:
            connection.execute(f"CREATE TABLE {TABLE} ({quoted})")
            marks = ", ".join("?" for _ in columns)
            connection.executemany(f"INSERT INTO {TABLE} VALUES ({marks})", ([r[c] for c in columns] for r in rows))
            keys = [c for c in ("family", "scenario", "planner") if c in columns]
            if keys:
                connection.execute(f"CREATE INDEX {TABLE}_keys ON {TABLE} ({', '.join(keys)})")
    finally:
        connection.close()
