"""A sweep's results file: CSV, one row per scenario, controller variant and planner, appended unit by unit.

Each unit's rows go out in one write, flushed and fsynced, so an interrupted sweep leaves whole units and at most
one torn unit at the end. Resuming checks that every row has this process's provenance (`mjtraj.versions.PROVENANCE`:
versions, BLAS, CPU, commit) and the same settings, cuts the torn tail, refuses anything an interruption cannot
explain (a damaged row before the end, a unit twice), and reports which units are done. A lock keeps two sweeps from
writing one file at once. Floats are written as repr(), which reads back to the same bits.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Collection, Generator, Iterator
from pathlib import Path
from typing import IO, Any

from mjtraj.exceptions import InvalidInputError, ProvenanceError
from mjtraj.files import with_path
from mjtraj.study.cells import VERSION_COLUMNS, cell_text, setting_cells
from mjtraj.study.locks import lock_file
from mjtraj.study.sweep_store import is_sqlite_file, iter_store_cells
from mjtraj.versions import difference


def expected_rows(row: dict[str, str]) -> int:
    """The rows a whole sweep writes, from the settings every row records (0 if they are not recorded)."""
    try:
        counts = [len(row[k].split("+")) for k in ("sweep_families", "sweep_planners", "sweep_ff_accel",
                                                     "sweep_gravity_comp")]
        return int(row["sweep_scenarios"]) * math.prod(counts)
    except (KeyError, ValueError):
        return 0


def format_rows(columns: list[str], rows: list[dict[str, Any]]) -> str:
    """CSV text of `rows` (no header)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    for row in rows:
        writer.writerow([cell_text(row[c]) for c in columns])
    return buffer.getvalue()


def csv_text(columns: list[str], rows: list[dict[str, Any]]) -> str:
    """CSV text of the header `columns` and `rows`."""
    return format_rows(columns, [dict(zip(columns, columns, strict=True)), *rows])


def append_rows(path: Path, columns: list[str], rows: list[dict[str, Any]]) -> None:
    """Append `rows` to the CSV file `path` in one write, flushed and fsynced (durable when this returns).

    Raises:
      OSError: naming `path` (a full disk, a file-size limit); the file may end in a torn unit, which resume cuts.
    """
    try:
        with open(path, "a", newline="") as f:
            f.write(format_rows(columns, rows))
            f.flush()
            os.fsync(f.fileno())
    except OSError as e:
        raise with_path(e, path) from e


def read_rows(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """The rows of a results file, CSV or SQLite store (`mjtraj.study.sweep_store`), as dicts of strings (use
    `numeric` for the numbers).

    Raises:
      InvalidInputError: the file is not text, or a row has more or fewer cells than the header (a torn write:
        the message names the line); or a SQLite file is not a readable sweep store.
    """
    return list(iter_rows(path))


def iter_rows(path: str | os.PathLike[str]) -> Iterator[dict[str, str]]:
    """`read_rows` one row at a time, in bounded memory: what a pass over millions of rows reads.

    Raises:
      InvalidInputError: as `read_rows` (a torn or damaged row when the pass reaches it).
    """
    cells = iter_cells(path)
    columns = next(cells)
    for values in cells:
        yield dict(zip(columns, values, strict=True))


def iter_cells(path: str | os.PathLike[str], only: Collection[str] | None = None
               ) -> Generator[tuple[str, ...], None, None]:
    """The header of a results file (CSV or store), then each row's cells in its order, one row at a time: what
    `iter_rows` reads, without a dict per row. With `only`, the header and cells of those columns alone (in the
    file's order; a store does not read the others): a pass over millions of rows that needs some columns.

    Raises:
      InvalidInputError: as `read_rows` (a torn or damaged row when the pass reaches it).
    """
    if is_sqlite_file(path):
        yield from iter_store_cells(path, only)
        return
    if only is not None:
        cells = iter_cells(path)
        names = next(cells)
        keep = [i for i, c in enumerate(names) if c in only]
        yield tuple(names[i] for i in keep)
        yield from (tuple(values[i] for i in keep) for values in cells)
        return
    with open(path, "rb") as raw:
        size = raw.seek(0, os.SEEK_END)
        if size:
            raw.seek(size - 1)
            if raw.read(1) != b"\n":
                raise InvalidInputError(f"sweep: {path} ends inside a row (a torn write); resume the sweep to repair "
                                        f"it")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            first: list[str] | None = next(reader, None)
            yield () if first is None else tuple(first)
            width = 0 if first is None else len(first)
            for values in reader:
                if len(values) != width:
                    if not values:  # a blank line, as csv.DictReader skips it
                        continue
                    raise InvalidInputError(f"sweep: {path} line {reader.line_num} has "
                                            f"{'more' if len(values) > width else 'fewer'} cells than the header (a "
                                            f"torn or damaged file); resume the sweep to repair it")
                yield tuple(values)
    except UnicodeDecodeError as e:
        raise InvalidInputError(f"sweep: {path} is not a text results file (not UTF-8 at byte {e.start})") from e


def numeric(value: str) -> float:
    """A cell as a float (NaN for '' or 'nan')."""
    return float(value) if value not in ("", "nan") else math.nan


class ResultsFile:
    """Append-only writer of one sweep's rows; create with `open`, release with `close`.

    While open it holds an exclusive lock on the file (POSIX `flock`), so a second sweep writing the same file
    at the same time is refused instead of interleaving units. The lock dies with the process.
    """

    def __init__(self, path: Path, columns: list[str], done: set[tuple[str, int]], lock: IO[bytes] | None = None
                 ) -> None:
        self.path = path
        self.columns = columns
        self.done = done
        """(family, unit) already in the file."""
        self._lock = lock

    @classmethod
    def open(cls, path: str | os.PathLike[str], columns: list[str], settings: dict[str, Any],
             unit_rows: dict[tuple[str, int], int], *, resume: bool) -> ResultsFile:
        """Start `path` afresh (it must not exist unless `resume`), or continue it.

        On resume, only an interruption is repaired: a torn last line and an unfinished last unit are cut.
        Anything else that a sweep cannot have written is refused and the file is left untouched.

        Args:
          columns: the header.
          settings: the setting and provenance columns every row of this sweep carries, name -> value.
          unit_rows: rows of each complete unit.

        Raises:
          ProvenanceError: a row's provenance (versions, BLAS, CPU, commit) is not this process's.
          InvalidInputError: the file exists without resume; another sweep is writing it; it was written with
            other settings or other columns; or it is damaged (a row cut short or too long before the end, a unit
            twice, an unfinished unit followed by others, a unit this sweep does not have). The message names the
            first problem and its line.
        """
        file = Path(path)
        if file.exists() and not resume:
            raise InvalidInputError(f"out: {file} exists; pass --resume to continue that sweep, or choose another "
                                    f"path")
        file.parent.mkdir(parents=True, exist_ok=True)
        lock = lock_file(file)
        try:
            if file.stat().st_size == 0:  # absent or empty: the header
                append_rows(file, columns, [dict(zip(columns, columns, strict=True))])
                return cls(file, columns, set(), lock)
            done, keep = _check(file, columns, settings, unit_rows)
            if keep < file.stat().st_size:
                with open(file, "r+b") as f:
                    f.truncate(keep)
            return cls(file, columns, done, lock)
        except BaseException:
            if lock is not None:
                lock.close()
            raise

    def append(self, rows: list[dict[str, Any]]) -> None:
        """Write a unit's rows at once and make them durable."""
        append_rows(self.path, self.columns, rows)

    def close(self) -> None:
        """Release the file's lock (idempotent)."""
        if self._lock is not None:
            self._lock.close()
            self._lock = None


_DAMAGED = "; the file was damaged or edited (an interruption only tears the last line or unit): start a new file"


def _check(file: Path, columns: list[str], settings: dict[str, Any], unit_rows: dict[tuple[str, int], int]
           ) -> tuple[set[tuple[str, int]], int]:
    """Validate a file to resume; return its complete units and the byte length that holds them. The stages: its
    header, each row's cells (provenance and settings), the runs of each unit's rows, no unit twice."""
    lines = file.read_bytes().split(b"\n")
    expected = setting_cells(settings)
    body = lines[1:-1]  # the last piece follows the last newline: empty, or a torn line that is cut
    _check_header(file, lines[0], body, columns, expected)
    index = {c: i for i, c in enumerate(columns)}
    offset = keep = len(lines[0]) + 1
    runs: list[tuple[tuple[str, int], int, int]] = []  # (unit, first line, rows) for each run of one unit
    for number, raw in enumerate(body, start=2):
        offset += len(raw) + 1
        cells = _row_cells(file, raw, number, columns, index, expected)
        unit = _unit_of(file, cells, index, number, unit_rows)
        _extend_runs(file, runs, unit, number, unit_rows)
        if runs[-1][2] == unit_rows[unit]:
            keep = offset
    _check_once(file, runs)
    done = {unit for unit, _, rows in runs if rows == unit_rows[unit]}
    return done, keep


def _check_header(file: Path, first: bytes, body: list[bytes], columns: list[str], expected: dict[str, str]
                  ) -> None:
    """InvalidInputError unless the header line is `columns` (a ProvenanceError where the first row's provenance
    says why it is not)."""
    try:
        header = next(csv.reader([first.decode()]))
    except UnicodeDecodeError as e:
        raise InvalidInputError(f"out: cannot resume {file}: it is not a text results file (not UTF-8 at byte "
                                f"{e.start})") from e
    if header == columns:
        return
    try:
        row = next(csv.reader([body[0].decode()]), []) if body else []
    except (UnicodeDecodeError, csv.Error):  # not a row: the columns' message says enough
        row = []
    if len(row) == len(header):  # its provenance says why the columns differ
        _check_provenance(file, dict(zip(header, row, strict=True)), expected, 2)
    missing = [c for c in columns if c not in header]
    extra = [c for c in header if c not in columns]
    raise InvalidInputError(f"out: cannot resume {file}: its columns differ from this version's "
                            f"(missing {missing[:5]}, unexpected {extra[:5]}); it was written by another "
                            f"mjtraj version; start a new file")


def _row_cells(file: Path, raw: bytes, number: int, columns: list[str], index: dict[str, int],
               expected: dict[str, str]) -> list[str]:
    """Line `number`'s cells, checked: as many as the columns, this run's provenance and settings."""
    try:
        cells = next(csv.reader([raw.decode()]), [])
    except UnicodeDecodeError:
        cells = []
    if len(cells) != len(columns):
        raise InvalidInputError(f"out: cannot resume {file}: line {number} has {len(cells)} cells, the header "
                                f"{len(columns)}{_DAMAGED}")
    provenance = [(name, index[name], value) for name, value in expected.items() if name in VERSION_COLUMNS]
    if any(cells[i] != value for _, i, value in provenance):
        _check_provenance(file, {name: cells[i] for name, i, _ in provenance}, expected, number)
    for name, value in expected.items():
        if name not in VERSION_COLUMNS and cells[index[name]] != value:
            raise InvalidInputError(f"out: cannot resume {file}: setting {name!r} differs (file: "
                                    f"{cells[index[name]]!r}, now: {value!r}) at line {number}; resume with the same "
                                    f"settings or start a new file")
    return cells


def _unit_of(file: Path, cells: list[str], index: dict[str, int], number: int,
             unit_rows: dict[tuple[str, int], int]) -> tuple[str, int]:
    """The (family, unit) a row belongs to, one of this sweep's."""
    try:
        unit = (cells[index["family"]], int(cells[index["unit"]]))
    except ValueError:
        unit = (cells[index["family"]], -1)
    if unit not in unit_rows:
        raise InvalidInputError(f"out: cannot resume {file}: line {number} belongs to unit {unit[0]} "
                                f"{cells[index['unit']]!r}, which this sweep does not have{_DAMAGED}")
    return unit


def _extend_runs(file: Path, runs: list[tuple[tuple[str, int], int, int]], unit: tuple[str, int], number: int,
                 unit_rows: dict[tuple[str, int], int]) -> None:
    """Count line `number`'s row into the runs of consecutive rows of one unit: a unit left unfinished before
    another, or one with more rows than it has, is damage."""
    if runs and runs[-1][0] == unit:
        runs[-1] = (unit, runs[-1][1], runs[-1][2] + 1)
    else:
        if runs and runs[-1][2] != unit_rows[runs[-1][0]]:
            last = runs[-1]
            raise InvalidInputError(f"out: cannot resume {file}: unit {last[0][0]} {last[0][1]} (line "
                                    f"{last[1]}) has {last[2]} of its {unit_rows[last[0]]} rows and other "
                                    f"units follow it{_DAMAGED}")
        runs.append((unit, number, 1))
    if runs[-1][2] > unit_rows[unit]:
        raise InvalidInputError(f"out: cannot resume {file}: unit {unit[0]} {unit[1]} has more than its "
                                f"{unit_rows[unit]} rows (line {number}){_DAMAGED}")


def _check_once(file: Path, runs: list[tuple[tuple[str, int], int, int]]) -> None:
    """InvalidInputError where a unit's rows come in two runs (two sweeps wrote the file, or it was edited)."""
    seen: dict[tuple[str, int], int] = {}
    for unit, first, _ in runs:
        if unit in seen:
            raise InvalidInputError(f"out: cannot resume {file}: unit {unit[0]} {unit[1]} appears twice (lines "
                                    f"{seen[unit]} and {first}); two sweeps wrote this file at once, or it was "
                                    f"edited; start a new file")
        seen[unit] = first


def _check_provenance(file: Path, row: dict[str, str], expected: dict[str, str], number: int) -> None:
    """ProvenanceError if line `number`'s cells `row` record another provenance than `expected`'s."""
    changed = difference(row, expected)
    if changed:
        raise ProvenanceError(f"out: cannot resume {file} (line {number}): its rows {changed}; start a new file (a "
                              f"results file holds rows of one provenance)")
