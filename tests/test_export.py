"""`mjtraj export`: the SQLite database and the JSON Lines hold exactly the sweep file's cells, typed; torn or
unfinished sweeps and unknown formats are one-line refusals that leave nothing behind."""

from __future__ import annotations

import json
import math
import sqlite3

import pytest

from mjtraj.cli import main
from mjtraj.exceptions import InvalidInputError
from mjtraj.study.export import TABLE, export
from mjtraj.study.runner import run_sweep
from mjtraj.study.store import numeric, read_rows
from mjtraj.study.sweep import SweepSettings


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    path = tmp_path_factory.mktemp("export") / "s.csv"
    run_sweep(SweepSettings(families=("nominal", "mismatch"), scenarios=3, batch=2, planners=("cubic", "optimal")),
              path, progress=False)
    return path


def same(cell, value):
    """A CSV cell and its exported value agree: text as is, numbers by value, '' and 'nan' as null."""
    if isinstance(value, str):
        return cell == value
    if value is None:
        return cell in ("", "nan")
    return cell not in ("", "nan") and numeric(cell) == value and not math.isnan(value)


@pytest.mark.slow
def test_sqlite_and_jsonl_hold_every_cell_typed(sweep, tmp_path):
    rows = read_rows(sweep)
    assert main(["export", str(sweep), "--out", str(tmp_path / "s.sqlite")]) == 0
    assert export(sweep, tmp_path / "s.jsonl") == len(rows)
    connection = sqlite3.connect(tmp_path / "s.sqlite")
    connection.row_factory = sqlite3.Row
    stored = [dict(r) for r in connection.execute(f"SELECT * FROM {TABLE}")]
    kinds = {r[1]: r[2] for r in connection.execute(f"PRAGMA table_info({TABLE})")}
    lines = [json.loads(line) for line in (tmp_path / "s.jsonl").read_text().splitlines()]
    assert len(stored) == len(lines) == len(rows)
    for row, db, js in zip(rows, stored, lines, strict=True):
        assert list(js) == list(row)
        for column, cell in row.items():
            assert same(cell, db[column]) and same(cell, js[column]), column
    assert kinds["planner"] == kinds["mujoco"] == kinds["reason"] == "TEXT"
    assert kinds["scenario"] == "INTEGER" and kinds["cost"] == kinds["payload_kg"] == "REAL"
    count = connection.execute(f"SELECT COUNT(*) FROM {TABLE} WHERE planner = 'cubic' AND family = 'mismatch'")
    assert count.fetchone()[0] == 3


@pytest.mark.slow
def test_torn_unfinished_or_unknown_are_refused_and_leave_nothing(sweep, tmp_path):
    text = sweep.read_text()
    torn = tmp_path / "torn.csv"
    torn.write_text(text[:-20])
    with pytest.raises(InvalidInputError, match=r"ends inside a row \(a torn write\)"):
        export(torn, tmp_path / "t.sqlite")
    lines = text.splitlines(keepends=True)
    unfinished = tmp_path / "unfinished.csv"
    unfinished.write_text("".join(lines[:-2]))
    with pytest.raises(InvalidInputError, match=r"^sweep: .*unfinished.csv is unfinished; finish it with the same "
                                                r"mjtraj sweep command and --resume before exporting it$"):
        export(unfinished, tmp_path / "u.jsonl")
    with pytest.raises(InvalidInputError, match=r"^out: expected a file ending in .sqlite, .db, .jsonl, .csv, got "
                                                r"'.*s.parquet'$"):
        export(sweep, tmp_path / "s.parquet")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["torn.csv", "unfinished.csv"]


@pytest.mark.slow
def test_csv_export_is_the_rows_text_byte_for_byte(sweep, tmp_path):
    """Oracle: the whole file formatted at once (csv_text of every row), what export wrote before it streamed."""
    from mjtraj.study.store import csv_text

    rows = read_rows(sweep)
    assert export(sweep, tmp_path / "copy.csv") == len(rows)
    assert (tmp_path / "copy.csv").read_bytes() == csv_text(list(rows[0]), rows).encode() == sweep.read_bytes()
    store = tmp_path / "s.sqlite"
    run_sweep(SweepSettings(families=("nominal", "mismatch"), scenarios=3, batch=2, planners=("cubic", "optimal")),
              store, progress=False)
    assert export(store, tmp_path / "from_store.csv") == len(rows)
    assert (tmp_path / "from_store.csv").read_bytes() == csv_text(list(rows[0]), read_rows(store)).encode()


@pytest.mark.parametrize("cells", [
    ("1", "2.5", "", "nan"), ("a,b", "x"), ('say "hi"', "1"), ("two\nlines", "1"), ("cr\r", ""), ("",),
    ("", ""), (" lead", "trail "), ("'", "\t"), (), ("é", "∞"),
])
def test_csv_lines_are_csv_writers_lines(cells):
    """Oracle: the csv module's writer, on cells that need quoting and cells that do not."""
    import csv
    import io

    from mjtraj.study.export import csv_lines

    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(cells)
    assert list(csv_lines([cells, cells])) == [buffer.getvalue()] * 2


@pytest.mark.slow
def test_a_store_cell_that_is_not_text_reads_as_str_has_it(sweep, tmp_path):
    """A store edited by hand (a number or NULL where the sweep wrote text) is read as before: str() of the value,
    '' for NULL; export's CSV equals csv_text of those rows."""
    from mjtraj.study.store import csv_text

    store = tmp_path / "s.sqlite"
    run_sweep(SweepSettings(scenarios=3, batch=2, planners=("cubic",)), store, progress=False)
    with sqlite3.connect(store) as connection:
        connection.execute("UPDATE rows SET rms_err = 0.25, duration = NULL WHERE scenario = '1'")
    rows = read_rows(store)
    edited = [r for r in rows if r["scenario"] == "1"]
    assert edited and all(r["rms_err"] == "0.25" and r["duration"] == "" for r in edited)
    export(store, tmp_path / "out.csv")
    assert (tmp_path / "out.csv").read_bytes() == csv_text(list(rows[0]), rows).encode()


def _synthetic_sweep(template, path, scenarios):
    """A complete sweep of `scenarios` scenarios per family: the template's rows of scenario 0, repeated."""
    import csv

    rows = read_rows(template)
    batch = 250
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for family in ("nominal", "mismatch"):
            first = [r for r in rows if r["family"] == family and r["scenario"] == "0"]
            for i in range(scenarios):
                for r in first:
                    writer.writerow({**r, "scenario": str(i), "unit": str(i // batch), "sweep_scenarios":
                                     str(scenarios), "sweep_batch": str(batch)})
    return path


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".sqlite"])
def test_export_runs_in_bounded_memory(sweep, tmp_path, suffix):
    """Peak memory (tracemalloc) exporting 4 times the rows grows by less than half: the rows are streamed."""
    import tracemalloc

    peaks = []
    for scenarios in (500, 2_000):
        source = _synthetic_sweep(sweep, tmp_path / f"big{scenarios}.csv", scenarios)
        tracemalloc.start()
        written = export(source, tmp_path / f"out{scenarios}{suffix}")
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert written == scenarios * 4
    assert peaks[1] < 1.5 * peaks[0], peaks


TURNS_TEXT = "UPDATE rows SET duration = 'fast' WHERE family = 'mismatch' AND scenario = '2'"
TURNS_WHOLE = "UPDATE rows SET payload_kg = '3' WHERE family = 'mismatch'"


def _edited_store(store, edit):
    """A small two-family store at `store`, then the SQL `edit` (None: none) run on it."""
    run_sweep(SweepSettings(families=("nominal", "mismatch"), scenarios=3, batch=2, planners=("cubic",)), store,
              progress=False)
    if edit:
        with sqlite3.connect(store) as connection:
            connection.execute(edit)
    return store


@pytest.mark.slow
@pytest.mark.parametrize("edit", [None, TURNS_TEXT, TURNS_WHOLE])
def test_a_store_read_once_gives_the_two_pass_output(tmp_path, monkeypatch, edit):
    """A store's typed exports are written as its rows are read; where a later row changes a column's kind (a
    number column turning to text, a column first missing then whole) they are written again. Oracle: the same
    rows exported from a CSV file, which is read twice (kinds first), byte for byte."""
    from mjtraj.study import export as export_module

    monkeypatch.setattr(export_module, "CHUNK", 3)  # several chunks, the change in a later one
    writes = []
    part_steps = export_module._part_steps
    monkeypatch.setattr(export_module, "_part_steps",
                        lambda *a: (writes.append(a[5]) if a[3] == "jsonl" else None) or part_steps(*a))
    store = _edited_store(tmp_path / "s.sqlite", edit)
    export(store, tmp_path / "rows.csv")
    for suffix in (".jsonl", ".sqlite"):
        export(store, tmp_path / f"mine{suffix}")
        export(tmp_path / "rows.csv", tmp_path / f"oracle{suffix}")
    assert (tmp_path / "mine.jsonl").read_bytes() == (tmp_path / "oracle.jsonl").read_bytes()
    # the store's JSON Lines written once as read (None: kinds as read), again with every row's kinds after a
    # change; then the CSV file's, with its kinds from its first pass
    assert writes[0] is None and len(writes) == (2 if edit is None else 3) and None not in writes[1:]
    dumps = []
    for name in ("mine", "oracle"):
        with sqlite3.connect(tmp_path / f"{name}.sqlite") as connection:
            dumps.append(list(connection.iterdump()))
    assert dumps[0] == dumps[1]
    kinds = {r[1]: r[2] for r in sqlite3.connect(tmp_path / "mine.sqlite").execute(f"PRAGMA table_info({TABLE})")}
    assert (kinds["duration"], kinds["payload_kg"]) == {None: ("REAL", "REAL"), TURNS_TEXT: ("TEXT", "REAL"),
                                                        TURNS_WHOLE: ("REAL", "INTEGER")}[edit]


TURNS_ONE_PART = "UPDATE rows SET payload_kg = '3' WHERE NOT (family = 'nominal' AND scenario = '1')"
"""Whole payloads everywhere but in the second row: in parts of a row each, that part alone is read as REAL."""


@pytest.mark.slow
@pytest.mark.parametrize("edit", [None, TURNS_TEXT, TURNS_WHOLE, TURNS_ONE_PART])
def test_an_export_on_several_processes_is_the_one_process_export(tmp_path, edit):
    """A store exported in parts on 2 and 3 processes, appended in order, is the export on one: CSV and JSON Lines
    byte for byte, SQLite dump for dump, also where a row of a later part changes a column's kind (every part
    written under other kinds as read is written again: from the first one, or that part alone); progress ends
    at every row."""
    store = _edited_store(tmp_path / "s.sqlite", edit)
    rows = sqlite3.connect(store).execute("SELECT COUNT(*) FROM rows").fetchone()[0]
    for suffix in (".csv", ".jsonl", ".sqlite"):
        outputs = []
        for workers in (1, 2, 3):
            calls: list[tuple[int, int]] = []
            out = tmp_path / f"w{workers}{suffix}"
            assert export(store, out, progress=lambda *a, calls=calls: calls.append(a), workers=workers) == rows
            assert calls[-1] == (rows, rows)
            if suffix == ".sqlite":
                with sqlite3.connect(out) as connection:
                    outputs.append(list(connection.iterdump()))
            else:
                outputs.append(out.read_bytes())
            assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no part left behind
        assert outputs[1] == outputs[0] and outputs[2] == outputs[0], suffix


def test_export_workers_follow_the_rows_and_refuse_a_bad_count(sweep, tmp_path):
    from mjtraj.study.export import MAX_WORKERS, PART_ROWS, export_workers

    assert export_workers(None, PART_ROWS - 1) == 1
    assert 1 <= export_workers(None, 100 * PART_ROWS) <= MAX_WORKERS
    assert export_workers(3, 2) == 2 and export_workers(2, 10) == 2
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InvalidInputError, match=rf"^workers: expected a whole number >= 1, got {bad!r}$"):
            export(sweep, tmp_path / "x.jsonl", workers=bad)
    assert not (tmp_path / "x.jsonl").exists()


@pytest.fixture(scope="module")
def turned(tmp_path_factory):
    """A store whose last row turns a number column to text, its row count, and its rows as a CSV file."""
    folder = tmp_path_factory.mktemp("turned")
    store = folder / "s.sqlite"
    run_sweep(SweepSettings(families=("nominal", "mismatch"), scenarios=3, batch=2, planners=("cubic",)), store,
              progress=False)
    with sqlite3.connect(store) as connection:
        connection.execute(TURNS_TEXT)
        rows = connection.execute("SELECT COUNT(*) FROM rows").fetchone()[0]
    export(store, folder / "rows.csv")
    return store, rows, folder / "rows.csv"


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".sqlite"])
def test_progress_counts_the_rows_written_up_to_the_sweeps_rows(tmp_path, monkeypatch, turned, suffix):
    """export's progress(done, total): total is the sweep's row count, done grows chunk by chunk to it, and starts
    again from zero only when a store's typed output is rewritten (a later row changed a column's kind)."""
    from mjtraj.study import export as export_module

    monkeypatch.setattr(export_module, "CHUNK", 3)
    store, rows, text = turned
    for source in (store, text):
        calls: list[tuple[int, int]] = []
        assert export(source, tmp_path / f"out{suffix}", progress=lambda *a, calls=calls: calls.append(a)) == rows
        assert {total for _, total in calls} == {rows} and calls[-1][0] == rows
        done = [d for d, _ in calls]
        restarts = sum(b < a for a, b in zip(done, done[1:], strict=False))
        rewritten = suffix != ".csv" and source == store  # the edit turns a column to text in a later chunk
        assert restarts == int(rewritten), done
        assert len(calls) > rows // 3 or source.suffix == ".csv" == suffix  # a CSV copied as it is: one report


@pytest.mark.slow
def test_an_infinity_is_refused_by_json_lines_and_other_nans_are_missing(tmp_path):
    """'NaN' (any spelling float() reads as nan) is a missing value, null in JSON; an infinity is a number SQLite
    stores and JSON cannot hold: JSON Lines export refuses it naming the column, and leaves no file."""
    store = tmp_path / "s.sqlite"
    run_sweep(SweepSettings(scenarios=3, batch=2, planners=("cubic",)), store, progress=False)
    with sqlite3.connect(store) as connection:
        connection.execute("UPDATE rows SET cost = 'NaN' WHERE scenario = '1'")
    export(store, tmp_path / "ok.jsonl")
    lines = [json.loads(line) for line in (tmp_path / "ok.jsonl").read_text().splitlines()]
    assert [row["cost"] is None for row in lines] == [row["scenario"] == 1 for row in lines]
    with sqlite3.connect(store) as connection:
        connection.execute("UPDATE rows SET rms_err = 'inf' WHERE scenario = '2'")
    for workers in (1, 2):  # in a part on a process of its own too: the same error, nothing left behind
        with pytest.raises(InvalidInputError, match=r"^sweep: column 'rms_err' holds a number JSON cannot hold \("):
            export(store, tmp_path / "bad.jsonl", workers=workers)
        assert not [p for p in tmp_path.iterdir() if p.name.startswith((".", "bad"))]
    export(store, tmp_path / "ok.sqlite")
    stored = sqlite3.connect(tmp_path / "ok.sqlite").execute(f"SELECT rms_err FROM {TABLE} WHERE scenario = 2")
    assert {value for (value,) in stored} == {math.inf}


@pytest.mark.parametrize("kernel_bytes", [None, 1000])
def test_a_part_is_appended_whole_by_the_kernel_or_from_where_it_stopped(tmp_path, monkeypatch, kernel_bytes):
    """_copy appends a part with os.copy_file_range, and where the file system refuses it (at once, or after some
    bytes), copies the rest through Python from where the kernel stopped: the output is head + part, byte for byte."""
    import os

    from mjtraj.study.export import _copy

    part = bytes(range(256)) * 10_000
    (tmp_path / "part").write_bytes(part)
    (tmp_path / "out").write_bytes(b"head|")
    if kernel_bytes is not None:
        real, calls = os.copy_file_range, []

        def refusing(source, target, count):
            if calls:
                raise OSError(18, "Invalid cross-device link")
            calls.append(count)
            return real(source, target, kernel_bytes)

        monkeypatch.setattr(os, "copy_file_range", refusing)
    with open(tmp_path / "out", "r+b") as out, open(tmp_path / "part", "rb") as source:
        out.seek(0, os.SEEK_END)
        _copy(source, out)
    assert (tmp_path / "out").read_bytes() == b"head|" + part
