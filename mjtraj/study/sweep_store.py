"""A sweep's results as a SQLite store: one transaction per unit of work, so a unit is stored whole or not at all.

Three tables:
- `meta` (key, value): the file's columns and the settings and provenance every row carries, as JSON;
- `units` (family, unit, rows): the units stored, written in the same transaction as their rows;
- `rows`: one row per scenario, controller variant and planner, keyed (PRIMARY KEY) by family, scenario, ff_accel,
  gravity_comp and planner. Cells are the text the CSV store writes (floats as repr(), so they read back to the
  same bits); `mjtraj export` gives typed tables.

A duplicated, missing or torn unit cannot exist by construction: a unit's rows and its `units` entry commit
together (SQLite's journal undoes an interrupted transaction at the next open), and the key refuses a row twice.
A second sweep on the same store is refused while the first holds its lock. Resume checks the provenance
(`mjtraj.versions.PROVENANCE`: versions, BLAS, CPU, commit) and the settings, and skips the stored units.
"""

from __future__ import annotations

import collections
import contextlib
import errno
import json
import os
import sqlite3
from collections.abc import Collection, Generator, Iterable, Iterator
from pathlib import Path
from typing import IO, Any

from mjtraj.exceptions import InvalidInputError, ProvenanceError
from mjtraj.study.cells import VERSION_COLUMNS, cell_text, setting_cells
from mjtraj.study.locks import lock_file
from mjtraj.versions import difference

STORE_SUFFIXES = (".sqlite", ".sqlite3", ".db")
"""An `--out` ending in one of these is a SQLite store; anything else is the CSV results file."""
MAGIC = b"SQLite format 3\x00"
"""The first 16 bytes of every SQLite database file."""
KEY = ("family", "scenario", "ff_accel", "gravity_comp", "planner")
"""The columns that identify a row: no two rows of a store share them."""


def is_store_path(path: str | os.PathLike[str]) -> bool:
    """Whether `path` names a SQLite store (by its suffix, STORE_SUFFIXES)."""
    return Path(path).suffix.lower() in STORE_SUFFIXES


def is_sqlite_file(path: str | os.PathLike[str]) -> bool:
    """Whether the file at `path` is a SQLite database (by its first bytes)."""
    try:
        with open(path, "rb") as f:
            return f.read(len(MAGIC)) == MAGIC
    except OSError:
        return False


def _quote(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def _connect(file: Path, *, readonly: bool = False) -> sqlite3.Connection:
    if readonly:
        connection = sqlite3.connect(f"{file.resolve().as_uri()}?mode=ro", uri=True, isolation_level=None)
    else:
        connection = sqlite3.connect(file, isolation_level=None)  # transactions are explicit
        connection.execute("PRAGMA synchronous=FULL")
    return connection


def _tables(connection: sqlite3.Connection) -> set[str]:
    return {name for (name,) in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}


def _meta(connection: sqlite3.Connection, file: Path) -> tuple[list[str], dict[str, str]]:
    """(columns, settings as cells) recorded in a store; InvalidInputError if it is not a sweep store."""
    if not {"meta", "units", "rows"} <= _tables(connection):
        raise InvalidInputError(f"sweep: {file} is a SQLite database but not an mjtraj sweep store (it lacks the "
                                f"meta, units and rows tables)")
    meta = dict(connection.execute("SELECT key, value FROM meta"))
    try:
        return list(json.loads(meta["columns"])), dict(json.loads(meta["settings"]))
    except (KeyError, ValueError, TypeError) as e:
        raise InvalidInputError(f"sweep: {file}: its meta table is damaged ({e}); start a new store") from e


def _stored_units(connection: sqlite3.Connection, file: Path) -> dict[tuple[str, int], int]:
    """(family, unit) -> rows of every stored unit, checked against the rows themselves (`_check_units`)."""
    return _check_units(connection, file, connection.execute(
        "SELECT family, CAST(unit AS INTEGER), COUNT(*) FROM rows GROUP BY family, unit"))


def _check_units(connection: sqlite3.Connection, file: Path, counts: Iterable[tuple[Any, Any, int]]
                 ) -> dict[tuple[str, int], int]:
    """(family, unit) -> rows of every stored unit, given the rows counted as (family, unit as an integer, rows)
    (several counts of one unit add up); InvalidInputError if a unit's rows are not all there, or rows lack their
    unit (the store was edited)."""
    counted: collections.Counter[tuple[str, Any]] = collections.Counter()
    for family, unit, n in counts:
        counted[family, unit] += n
    units = {(f, int(u)): int(n) for f, u, n in connection.execute("SELECT family, unit, rows FROM units")}
    for (family, unit), rows in units.items():
        if counted.get((family, unit)) != rows:
            raise InvalidInputError(f"sweep: {file}: unit {family} {unit} has {counted.get((family, unit), 0)} "
                                    f"rows, its entry says {rows}; the store was edited; start a new store")
    if set(counted) - set(units):
        family, unit = sorted(set(counted) - set(units), key=str)[0]
        raise InvalidInputError(f"sweep: {file}: rows of unit {family} {unit} are stored without the unit; the "
                                f"store was edited; start a new store")
    return units


def read_store_rows(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """The rows of a SQLite sweep store as dicts of strings, in the order they were stored.

    Raises:
      InvalidInputError: the file is not a readable sweep store.
    """
    return list(iter_store_rows(path))


def iter_store_rows(path: str | os.PathLike[str]) -> Iterator[dict[str, str]]:
    """`read_store_rows` one row at a time, in bounded memory (SQLite's cursor pages through the table).

    Raises:
      InvalidInputError: the file is not a readable sweep store.
    """
    cells = iter_store_cells(path)
    columns = next(cells)
    for values in cells:
        yield dict(zip(columns, values, strict=True))


@contextlib.contextmanager
def _reading(file: Path) -> Iterator[sqlite3.Connection]:
    """A read-only connection to the store `file`, closed at the end; SQLite's errors as InvalidInputError."""
    try:
        connection = _connect(file, readonly=True)
        try:
            yield connection
        finally:
            connection.close()
    except sqlite3.DatabaseError as e:
        raise InvalidInputError(f"sweep: cannot read the store {file}: {e}") from e


_TEXT = {str}
"""The cell types of a row of text."""


def iter_store_cells(path: str | os.PathLike[str], only: Collection[str] | None = None,
                     rowids: tuple[int | None, int | None] | None = None
                     ) -> Generator[tuple[str, ...], None, None]:
    """The store's column names (those of them in `only`, if given, in the store's order), then each row's cells
    of those columns as text ('' for a missing one), in the order they were stored and in bounded memory:
    `iter_store_rows` without a dict per row (and, with `only`, without reading the other columns). With `rowids`
    (low, high), the rows whose rowid is in [low, high) (None: unbounded), a part of a store read whole before:
    its units are not checked again.

    Raises:
      InvalidInputError: the file is not a readable sweep store.
    """
    file = Path(path)
    with _reading(file) as connection:
        columns, _ = _meta(connection, file)
        if rowids is None:
            _stored_units(connection, file)
        if only is not None:
            columns = [c for c in columns if c in only]
        yield tuple(columns)
        low, high = rowids or (None, None)
        where = " AND ".join([*(["rowid >= :low"] if low is not None else []),
                              *(["rowid < :high"] if high is not None else [])])
        cursor = connection.execute(f"SELECT {', '.join(map(_quote, columns)) or 'NULL'} FROM rows "
                                    f"{'WHERE ' + where if where else ''} ORDER BY rowid", {"low": low, "high": high})
        for values in cursor:  # a store's cells are text (cell_text); an edited one's others as str() has them
            yield values if set(map(type, values)) == _TEXT else tuple("" if v is None else str(v) for v in values)


def store_rows(path: str | os.PathLike[str]) -> int:
    """The rows of the store at `path`, counted by SQLite.

    Raises:
      InvalidInputError: the file is not a readable sweep store.
    """
    file = Path(path)
    with _reading(file) as connection:
        _meta(connection, file)
        (total,) = connection.execute("SELECT COUNT(*) FROM rows").fetchone()
    return int(total)


def rowid_bounds(path: str | os.PathLike[str], parts: int) -> list[tuple[int | None, int | None]]:
    """The store's rows in at most `parts` consecutive ranges of rowids [low, high) that split the span of its
    rowids evenly (None: unbounded), in order: `iter_store_cells(path, rowids=...)` of each, one after another,
    reads every row once. A store's rowids run without gaps (its rows are only ever appended), so the ranges hold
    as many rows each; a range that holds none (an edited store) is merged into the next. Found from the rowids
    alone: no row is read.

    Raises:
      InvalidInputError: the file is not a readable sweep store.
    """
    with _reading(Path(path)) as connection:
        low, high = connection.execute("SELECT MIN(rowid), MAX(rowid) FROM rows").fetchone()
        if low is None:
            return [(None, None)]
        parts = max(1, min(parts, high - low + 1))
        cuts, start = [], low
        for cut in (low + i * (high - low + 1) // parts for i in range(1, parts)):
            if connection.execute("SELECT EXISTS (SELECT 1 FROM rows WHERE rowid >= ? AND rowid < ?)",
                                  (start, cut)).fetchone()[0]:
                cuts.append(cut)
                start = cut
    ends: list[int | None] = [None, *cuts, None]
    return list(zip(ends[:-1], ends[1:], strict=True))


def unit_row_counts(path: str | os.PathLike[str], planners: Collection[str] | None
                    ) -> tuple[int, collections.Counter[tuple[str, str]], collections.Counter[tuple[str, str]]]:
    """(the store's rows, the rows of each (family, unit) whose planner is one of `planners` (all of them for
    None), every row of each (family, unit)), cells as `iter_store_cells` reads them, counted by SQLite in one scan
    of the table without a row reaching Python; the units checked against the rows as `iter_store_cells` checks
    them.

    Raises:
      InvalidInputError: the file is not a readable sweep store, or it was edited.
    """
    file = Path(path)
    names = [] if planners is None else sorted(planners)
    own = "COUNT(*)" if planners is None else f"SUM(planner IN ({', '.join('?' for _ in names)}))"
    with _reading(file) as connection:
        _meta(connection, file)
        grouped = connection.execute(f"SELECT family, unit, CAST(unit AS INTEGER), {own}, COUNT(*) FROM rows "
                                     f"GROUP BY family, unit", names).fetchall()
        _check_units(connection, file, ((family, unit, n) for family, _, unit, _, n in grouped))
    mine: collections.Counter[tuple[str, str]] = collections.Counter()
    every: collections.Counter[tuple[str, str]] = collections.Counter()
    for family, unit, _, n_own, n in grouped:
        key = ("" if family is None else str(family), "" if unit is None else str(unit))
        if n_own:
            mine[key] += n_own
        every[key] += n
    return sum(every.values()), mine, every


class SweepStore:
    """Writer of one sweep's SQLite store; create with `open`, release with `close` (the ResultsFile interface).

    While open it holds an exclusive lock on the file (POSIX `flock`), so a second sweep on the same store is
    refused; the lock dies with the process.
    """

    def __init__(self, path: Path, connection: sqlite3.Connection, columns: list[str], done: set[tuple[str, int]],
                 lock: IO[bytes] | None) -> None:
        self.path = path
        self.columns = columns
        self.done = done
        """(family, unit) already stored."""
        self._connection: sqlite3.Connection | None = connection
        self._lock = lock

    @classmethod
    def open(cls, path: str | os.PathLike[str], columns: list[str], settings: dict[str, Any],
             unit_rows: dict[tuple[str, int], int], *, resume: bool) -> SweepStore:
        """Create the store `path` (it must not exist unless `resume`), or continue it.

        Args:
          columns: the rows' columns.
          settings: the setting and provenance columns every row of this sweep carries, name -> value.
          unit_rows: rows of each unit of this sweep.

        Raises:
          ProvenanceError: its rows' provenance (versions, BLAS, CPU, commit) is not this process's.
          InvalidInputError: the file exists without resume; another sweep holds it; it is not a sweep store; it
            was written with other settings or columns; or it holds a unit this sweep does not have, or a unit
            whose row count is wrong.
        """
        file = Path(path)
        if file.exists() and not resume:
            raise InvalidInputError(f"out: {file} exists; pass --resume to continue that sweep, or choose another "
                                    f"path")
        if file.exists() and file.stat().st_size and not is_sqlite_file(file):
            raise InvalidInputError(f"out: cannot resume {file}: it is not a SQLite sweep store")
        file.parent.mkdir(parents=True, exist_ok=True)
        lock = lock_file(file)
        connection = None
        try:
            connection = _connect(file)
            cells = setting_cells(settings)
            if not _tables(connection):  # new (or a creation that was interrupted and rolled back)
                _create(connection, columns, cells)
                return cls(file, connection, columns, set(), lock)
            done = _check(connection, file, columns, cells, unit_rows)
            return cls(file, connection, columns, done, lock)
        except sqlite3.DatabaseError as e:
            if connection is not None:
                connection.close()
            if lock is not None:
                lock.close()
            raise InvalidInputError(f"out: cannot use {file} as a sweep store: {e}") from e
        except BaseException:
            if connection is not None:
                connection.close()
            if lock is not None:
                lock.close()
            raise

    def append(self, rows: list[dict[str, Any]]) -> None:
        """Store one unit's rows and its `units` entry in one transaction (durable when this returns).

        Raises:
          InvalidInputError: the unit or one of its rows is already stored (nothing of the unit is kept).
        """
        if self._connection is None:
            raise InvalidInputError(f"out: {self.path} is closed")
        if not rows:
            return
        family, unit = str(rows[0]["family"]), int(rows[0]["unit"])
        marks = ", ".join("?" for _ in self.columns)
        connection = self._connection
        connection.execute("BEGIN IMMEDIATE")
        try:
            connection.executemany(f"INSERT INTO rows VALUES ({marks})",
                                   ([cell_text(row[c]) for c in self.columns] for row in rows))
            connection.execute("INSERT INTO units VALUES (?, ?, ?)", (family, unit, len(rows)))
            connection.execute("COMMIT")
        except sqlite3.IntegrityError as e:
            connection.execute("ROLLBACK")
            raise InvalidInputError(f"out: {self.path}: unit {family} {unit} is already stored ({e})") from e
        except sqlite3.Error as e:  # the disk: full, a file-size limit, an I/O error; the unit is not stored
            with contextlib.suppress(sqlite3.Error):
                if connection.in_transaction:
                    connection.execute("ROLLBACK")
            raise OSError(errno.EIO, f"cannot store unit {family} {unit}: {e} (is the disk full?); the units "
                          f"stored before it are whole: resume when there is room", str(self.path)) from e
        except BaseException:
            if connection.in_transaction:
                connection.execute("ROLLBACK")
            raise
        self.done.add((family, unit))

    def close(self) -> None:
        """Close the database and release the lock (idempotent)."""
        if self._connection is not None:
            self._connection.close()
            self._connection = None
        if self._lock is not None:
            self._lock.close()
            self._lock = None


def _create(connection: sqlite3.Connection, columns: list[str], cells: dict[str, str]) -> None:
    missing = [k for k in KEY if k not in columns]
    if missing:
        raise InvalidInputError(f"out: a sweep store needs the key columns {', '.join(KEY)}; missing "
                                f"{', '.join(missing)}")
    connection.execute("BEGIN IMMEDIATE")
    try:
        connection.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
        connection.execute("CREATE TABLE units (family TEXT NOT NULL, unit INTEGER NOT NULL, rows INTEGER NOT NULL, "
                           "PRIMARY KEY (family, unit))")
        connection.execute(f"CREATE TABLE rows ({', '.join(map(_quote, columns))}, "
                           f"PRIMARY KEY ({', '.join(map(_quote, KEY))}))")
        connection.executemany("INSERT INTO meta VALUES (?, ?)", [("columns", json.dumps(columns)),
                                                                  ("settings", json.dumps(cells))])
        connection.execute("COMMIT")
    except BaseException:
        if connection.in_transaction:
            connection.execute("ROLLBACK")
        raise


def _check(connection: sqlite3.Connection, file: Path, columns: list[str], cells: dict[str, str],
           unit_rows: dict[tuple[str, int], int]) -> set[tuple[str, int]]:
    """Validate a store to resume; return its units."""
    stored_columns, stored = _meta(connection, file)
    changed = difference(stored, cells)
    if changed:
        raise ProvenanceError(f"out: cannot resume {file}: its rows {changed}; start a new store (a store holds "
                              f"rows of one provenance)")
    if stored_columns != columns:
        missing = [c for c in columns if c not in stored_columns]
        extra = [c for c in stored_columns if c not in columns]
        raise InvalidInputError(f"out: cannot resume {file}: its columns differ from this version's (missing "
                                f"{missing[:5]}, unexpected {extra[:5]}); it was written by another mjtraj version; "
                                f"start a new store")
    for name, value in cells.items():
        if stored.get(name) != value and name not in VERSION_COLUMNS:
            raise InvalidInputError(f"out: cannot resume {file}: setting {name!r} differs (store: "
                                    f"{stored.get(name)!r}, now: {value!r}); resume with the same settings or start "
                                    f"a new store")
    try:
        units = _stored_units(connection, file)
    except InvalidInputError as e:
        raise InvalidInputError(f"out: cannot resume {file}: {str(e).split(': ', 2)[-1]}") from e
    for (family, unit), rows in units.items():
        if (family, unit) not in unit_rows:
            raise InvalidInputError(f"out: cannot resume {file}: it holds unit {family} {unit}, which this sweep "
                                    f"does not have; start a new store")
        if rows != unit_rows[(family, unit)]:
            raise InvalidInputError(f"out: cannot resume {file}: unit {family} {unit} has {rows} rows, expected "
                                    f"{unit_rows[(family, unit)]}; the store was edited; start a new store")
    return set(units)


__all__ = ["KEY", "STORE_SUFFIXES", "SweepStore", "is_sqlite_file", "is_store_path", "iter_store_cells",
           "iter_store_rows", "read_store_rows", "rowid_bounds", "store_rows", "unit_row_counts"]
