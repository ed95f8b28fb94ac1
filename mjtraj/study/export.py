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
import contextlib
import csv
import io
import itertools
import math
import multiprocessing
import os
import shutil
import sqlite3
import tempfile
from collections.abc import Callable, Generator, Iterable, Iterator, Sequence
from dataclasses import dataclass
from json.encoder import encode_basestring_ascii  # type: ignore[attr-defined]
from pathlib import Path
from typing import Any

from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path
from mjtraj.study.store import VERSION_COLUMNS, expected_rows, iter_cells
from mjtraj.study.sweep_store import is_sqlite_file, iter_store_cells, rowid_bounds, store_rows, unit_row_counts

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

    def merge(self, other: ColumnKinds) -> None:
        """Account for the rows `other` accounted for (the kinds do not depend on the rows' order)."""
        for c in self.columns:
            self._text[c] = self._text[c] or other._text[c]
            self._present[c] = self._present[c] or other._present[c]
            self._whole[c] = self._whole[c] and other._whole[c]

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
    """The first pass over `sweep`: its columns, their kinds (if `kinds_needed`: a CSV file's only, since a store's
    parts gather theirs as they are written) and its row count, refusing a sweep that is not one, or is torn or
    unfinished (the rule of `complete_units` and `expected_rows`, counted unit by unit). Reads cells, not dicts:
    only the key columns are looked at unless kinds are needed."""
    store = is_sqlite_file(sweep)
    assert not (store and kinds_needed), "a store's kinds are gathered by its parts"
    cells = iter_store_cells(sweep, rowids=(None, None)) if store else iter_cells(sweep)  # units: checked below
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
    if store:  # counted by SQLite in one scan, its units checked: no row reaches Python for them
        total, counts, _ = unit_row_counts(sweep, planners)
        cells.close()
    else:
        total, counts = 0, collections.Counter()
        for chunk in _batched(itertools.chain([first_values], cells)):
            total += len(chunk)  # rows of other controllers ride along with their unit
            counts.update((values[at_family], values[at_unit]) for values in chunk if values[at_planner] in planners)
            if gathered is not None:
                gathered.add(chunk)
    try:
        per_scenario = math.prod(len(first[k].split("+")) for k in ("sweep_planners", "sweep_ff_accel",
                                                                    "sweep_gravity_comp"))
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


def _cell_chunks(sweep: str | os.PathLike[str], rowids: tuple[int | None, int | None] | None = None
                 ) -> Iterator[list[tuple[str, ...]]]:
    """The rows of `sweep` (of its rowids [low, high) if given: a part of a store) as cells in the header's order,
    in lists of at most CHUNK."""
    cells = iter_store_cells(sweep, rowids=rowids) if rowids is not None else iter_cells(sweep)
    next(cells)
    yield from _batched(cells)


PART_ROWS = 100_000
"""A store's export runs on several processes when each can take at least this many rows ..."""
MAX_WORKERS = 4
"""... on at most this many by default (one per CPU), each holding CHUNK rows at a time: about 70 MB each."""


def export_workers(workers: int | None, rows: int) -> int:
    """The processes that export `rows` rows of a store: `workers` if given, else one per CPU this process may
    use, at most MAX_WORKERS and one per PART_ROWS rows; never more than the rows.

    Raises:
      InvalidInputError: `workers` below 1.
    """
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InvalidInputError(f"workers: expected a whole number >= 1, got {workers!r}")
    if workers is None:
        cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        workers = min(cpus, MAX_WORKERS, rows // PART_ROWS)
    return max(1, min(workers, rows))


def export(sweep: str | os.PathLike[str], out: str | os.PathLike[str],
           progress: Callable[[int, int], None] | None = None, workers: int | None = None) -> int:
    """Write the complete sweep `sweep` (store or CSV file) to `out` (format by suffix: .sqlite or .db, .jsonl,
    .csv); return the rows. CHUNK rows in memory at a time per process: bounded memory, time proportional to the
    rows. `progress(rows written, rows)` is called as chunks are written (again from the rows kept if some output
    is rewritten).

    A CSV file is read twice (checks and column kinds, then the output). A store is checked by SQLite and read
    once where it can be, in consecutive parts of its rows on `workers` processes (`export_workers`; parts
    written side by side, then joined in order: the same output as one process): each part is written under the
    kinds of its rows read so far, which is the output of two passes as long as no later row of the store changes
    a column's kind (a column whose first cells are all missing and whose later ones are whole numbers, a number
    column that turns to text); the parts written under other kinds than every row's are written again.

    Raises:
      InvalidInputError: unknown output suffix, no such sweep file, `workers` below 1, a torn or unfinished
        sweep, or a number JSON cannot hold.
    """
    target = Path(out)
    kind = FORMATS.get(target.suffix.lower())
    if kind is None:
        raise InvalidInputError(f"out: expected a file ending in {', '.join(FORMATS)}, got {str(out)!r}")
    if not Path(sweep).is_file():
        raise InvalidInputError(f"sweep: file not found: {sweep}")
    if Path(sweep).resolve() == target.resolve():
        raise InvalidInputError(f"out: {out} is the sweep itself; choose another path")
    export_workers(workers, 1)  # a bad count refused before the sweep is read
    store = is_sqlite_file(sweep)
    count = export_workers(workers, store_rows(sweep)) if store else 1
    with atomic_path(target) as tmp:
        if count > 1:
            return _write_in_parts(str(sweep), tmp, kind, count, progress)
        columns, gathered, total = _checked_pass(sweep, kinds_needed=kind != "csv" and not store)
        written = _Written(total, progress)
        if kind == "csv" and not store:  # checked complete: its text is the output, byte for byte
            shutil.copyfile(sweep, tmp)
        else:
            _write_one_part(str(sweep), tmp, kind, columns, None if gathered is None else gathered.kinds(), written)
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

    def restart(self, kept: int = 0) -> _Written:
        """Count again from the `kept` rows (those of the output that is not rewritten)."""
        self.done = 0
        self.add(kept)
        return self


@dataclass(frozen=True)
class _Part:
    """A part written by `_part_steps`: whether it holds every row of its range (False: a later row changed the
    kinds as read, and writing stopped there), its rows, the kinds it was written under, and those of its rows
    (None for CSV, which has no kinds)."""

    complete: bool
    rows: int
    kinds: dict[str, str] | None
    gathered: ColumnKinds | None


def _part_steps(sweep: str, rowids: tuple[int | None, int | None] | None, path: Path, kind: str,
                columns: list[str], kinds: dict[str, str] | None) -> Generator[int, None, _Part]:
    """Write the rows of `sweep` (its rowids [low, high) if given) to `path` as `kind` (CSV lines after what the
    file holds, JSON Lines, or the SQLite table without its index) under `kinds` (None: those of the rows read so
    far; where a later row changes them writing stops, and the rest is read for its kinds alone). Yields the rows
    of each chunk written; returns the `_Part`."""
    gathered = None if kind == "csv" else ColumnKinds(columns)
    under, complete, rows = kinds, True, 0
    with _PartFile(path, kind, columns) as output:
        for chunk in _cell_chunks(sweep, rowids):
            rows += len(chunk)
            numbers = None
            if gathered is not None:
                numbers = gathered.add(chunk)
                if kinds is None:
                    now = gathered.kinds()
                    under = under or now
                    complete = complete and now == under
            if complete:
                output.write(chunk, under, numbers)
                yield len(chunk)
    return _Part(complete, rows, under, gathered)


class _PartFile:
    """A part's output while it is written: CSV lines (appended), JSON Lines, or a SQLite table."""

    def __init__(self, path: Path, kind: str, columns: list[str]) -> None:
        self.path, self.kind, self.columns = path, kind, columns
        self._text: Any = None
        self._connection: sqlite3.Connection | None = None

    def __enter__(self) -> _PartFile:
        if self.kind == "sqlite":
            self.path.unlink(missing_ok=True)
            self._connection = sqlite3.connect(self.path)
            self._connection.execute("PRAGMA journal_mode=OFF")  # a new file, put in place whole (atomic_path)
        else:
            self._text = open(self.path, "a" if self.kind == "csv" else "w", encoding="utf-8", newline="")
        return self

    def write(self, chunk: list[tuple[str, ...]], kinds: dict[str, str] | None,
              numbers: list[Numbers | None] | None) -> None:
        if self.kind == "csv":
            self._text.write("".join(csv_lines(chunk)))
        elif self.kind == "jsonl":
            assert kinds is not None
            self._text.write(jsonl_text(self.columns, list(kinds.values()), chunk, numbers))
        else:
            assert kinds is not None and self._connection is not None
            if self._connection.total_changes == 0:
                self._connection.execute(f"CREATE TABLE {TABLE} ({_declared(kinds)})")
            self._connection.executemany(f"INSERT INTO {TABLE} VALUES ({', '.join('?' for _ in self.columns)})",
                                         zip(*typed_columns(chunk, list(kinds.values()), numbers), strict=True))

    def __exit__(self, *exc: object) -> None:
        if self._connection is not None:
            if exc[0] is None:
                self._connection.commit()
            self._connection.close()
        if self._text is not None:
            self._text.close()


def _declared(kinds: dict[str, str]) -> str:
    """The table's column declarations."""
    return ", ".join(f'"{c}" {k}' for c, k in kinds.items())


def _drain(steps: Generator[int, None, _Part], report: Callable[[int], None]) -> _Part:
    """Run a part's steps, reporting each chunk's rows; its `_Part`."""
    while True:
        try:
            report(next(steps))
        except StopIteration as stop:
            return stop.value  # type: ignore[no-any-return]


_counter: Any = None
"""In a worker process: the shared count of rows written (multiprocessing.Value), set by `_count_into`."""


def _count_into(counter: Any) -> None:
    global _counter
    _counter = counter


def _add_to_counter(rows: int) -> None:
    with _counter.get_lock():
        _counter.value += rows


def _part_in_worker(*args: Any) -> _Part:
    """`_part_steps` in a worker process, its rows counted into the shared counter."""
    return _drain(_part_steps(*args), _add_to_counter)


def _write_one_part(sweep: str, tmp: Path, kind: str, columns: list[str], kinds: dict[str, str] | None,
                    written: _Written) -> None:
    """Write `sweep` to `tmp` as `kind` in this process: under `kinds` if given, else as read, and again under
    every row's kinds if a later row changed them."""
    if kind == "csv":
        _write_header(tmp, columns)
    part = _drain(_part_steps(sweep, None, tmp, kind, columns, kinds), written.add)
    assert part.gathered is not None or kind == "csv"
    if part.gathered is not None and (not part.complete or part.kinds != part.gathered.kinds()):
        written.restart()
        _drain(_part_steps(sweep, None, tmp, kind, columns, part.gathered.kinds()), written.add)
    if kind == "sqlite":
        _index(tmp, columns)


def _write_header(tmp: Path, columns: list[str]) -> None:
    with open(tmp, "w", encoding="utf-8", newline="") as f:
        f.write("".join(csv_lines([tuple(columns)])))


PARTS_PER_WORKER = 4
"""A store exported on several processes is cut into this many parts per process, so that the parts written are
appended to the output while the others are still being written."""


def _write_in_parts(sweep: str, tmp: Path, kind: str, workers: int, progress: Callable[[int, int], None] | None
                    ) -> int:
    """Write the store `sweep` to `tmp` as `kind` on `workers` spawned processes, PARTS_PER_WORKER consecutive
    parts each (the first part into `tmp` itself, each other into a file of its own, appended to `tmp` in order
    as soon as it and those before it are written under the first part's kinds), while this process checks the
    store (`_checked_pass`). Parts written under other kinds than every row's are written again. Returns the rows.

    Raises:
      InvalidInputError: as `export`, from this process's checks or from a part's writer.
    """
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    cells = iter_store_cells(sweep, rowids=(None, None))  # the store's columns (its meta checked)
    columns = list(next(cells))
    cells.close()
    bounds = rowid_bounds(sweep, workers * PARTS_PER_WORKER)
    context = multiprocessing.get_context("spawn")  # no fork of a process that may hold MuJoCo threads
    counter = context.Value("q", 0)
    with contextlib.ExitStack() as stack:
        folder = Path(stack.enter_context(tempfile.TemporaryDirectory(dir=tmp.parent, prefix=f".{tmp.stem}.")))
        paths = [tmp, *(folder / f"part{i}{tmp.suffix}" for i in range(1, len(bounds)))]
        pool = stack.enter_context(ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                                       initializer=_count_into, initargs=(counter,)))
        stack.callback(pool.shutdown, cancel_futures=True)  # after an error, no part starts
        if kind == "csv":
            _write_header(tmp, columns)
        futures = {i: pool.submit(_part_in_worker, sweep, bounds[i], paths[i], kind, columns, None)
                   for i in range(len(bounds))}
        _, _, total = _checked_pass(sweep, kinds_needed=False)  # while the parts are written
        written = _Written(total, progress)
        joiner = stack.enter_context(_Joiner(tmp, kind))
        done: dict[int, _Part] = {}

        def collect(good: Callable[[_Part], bool], since: int) -> None:
            """Wait for the parts in `futures`, appending each to `tmp` in order once it and those before it are
            `good`; their rows written are the shared count's growth from `since`."""
            base = written.done
            pending = {future: i for i, future in futures.items()}
            while pending:
                finished, _ = wait(pending, timeout=PROGRESS_SECONDS, return_when=FIRST_COMPLETED)
                written.add(base + counter.value - since - written.done)
                for future in finished:
                    done[pending.pop(future)] = future.result()  # a part's error is raised here
                while joiner.parts < len(bounds) and all(i in done and good(done[i]) for i in range(joiner.parts + 1)):
                    joiner.append(paths[joiner.parts])

        collect(lambda part: part.complete and part.kinds == done[0].kinds, 0)
        if kind != "csv":
            every = ColumnKinds(columns)
            for part in done.values():
                assert part.gathered is not None
                every.merge(part.gathered)
            final = every.kinds()

            def good(part: _Part) -> bool:
                return part.complete and part.kinds == final

            appended = joiner.parts
            if not good(done[0]):
                joiner.restart()  # what was appended is under other kinds: again from the first part
            again = [i for i in range(len(bounds)) if not good(done[i]) or (i < appended and not good(done[0]))]
            if again:
                written.restart(sum(done[i].rows for i in range(len(bounds)) if i not in again))
                since = counter.value  # every part has ended: the count stands still
                futures = {i: pool.submit(_part_in_worker, sweep, bounds[i], paths[i], kind, columns, final)
                           for i in again}
                collect(good, since)
    if kind == "sqlite":
        _index(tmp, columns)
    written.add(total)
    return total


class _Joiner:
    """Appends parts to the output `tmp`, which holds the first part: text as it is, SQLite rows by SQLite;
    `parts` counts the parts it holds; each part's file is deleted once appended."""

    def __init__(self, tmp: Path, kind: str) -> None:
        self.tmp, self.kind, self.parts = tmp, kind, 1
        self._connection: sqlite3.Connection | None = None

    def __enter__(self) -> _Joiner:
        return self

    def append(self, path: Path) -> None:
        if self.kind == "sqlite":
            if self._connection is None:
                self._connection = sqlite3.connect(self.tmp)
            self._connection.execute("ATTACH DATABASE ? AS part", (str(path),))
            with self._connection:  # a bare copy of an identical table: SQLite moves its records in rowid order
                self._connection.execute(f"INSERT INTO main.{TABLE} SELECT * FROM part.{TABLE}")  # (no decoding)
            self._connection.execute("DETACH DATABASE part")
        else:
            with open(self.tmp, "r+b") as out, open(path, "rb") as part:  # not "ab": copy_file_range refuses O_APPEND
                out.seek(0, os.SEEK_END)
                _copy(part, out)
        path.unlink()
        self.parts += 1

    def restart(self) -> None:
        """Hold the first part alone again (it is to be written again)."""
        self.__exit__()
        self.parts = 1

    def __exit__(self, *exc: object) -> None:
        if self._connection is not None:
            self._connection.close()
            self._connection = None


def _copy(source: Any, target: Any) -> None:
    """Copy the file `source` from its position to `target` at its position (both binary, neither opened to
    append), in the kernel where it can (os.copy_file_range)."""
    target.flush()
    if hasattr(os, "copy_file_range"):
        try:
            while os.copy_file_range(source.fileno(), target.fileno(), COPY_BYTES):
                pass
            return
        except OSError:  # a file system without it: copied through Python, from where it stopped
            source.seek(os.lseek(source.fileno(), 0, os.SEEK_CUR))
            target.seek(os.lseek(target.fileno(), 0, os.SEEK_CUR))
    shutil.copyfileobj(source, target, COPY_BYTES)


PROGRESS_SECONDS = 0.25
"""How often an export on several processes reports its progress."""
COPY_BYTES = 1 << 24
"""The most bytes a text part is appended by at a time."""


def _index(path: Path, columns: list[str]) -> None:
    """Index the exported table by family, scenario and planner (those of them it has)."""
    keys = [c for c in ("family", "scenario", "planner") if c in columns]
    if keys:
        connection = sqlite3.connect(path)
        try:
            with connection:
                connection.execute(f"CREATE INDEX {TABLE}_keys ON {TABLE} ({', '.join(keys)})")
        finally:
            connection.close()
