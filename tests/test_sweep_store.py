"""The SQLite sweep store: the rows of the CSV file, bit for bit; resume after a kill at any moment gives the
uninterrupted rows; a unit is stored whole or not at all; duplicates are impossible; a second writer, other
settings and foreign files are refused, leaving the store untouched."""


from __future__ import annotations

import json
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from mjtraj.cli import main
from mjtraj.exceptions import InvalidInputError, ProvenanceError
from mjtraj.study.runner import run_sweep
from mjtraj.study.store import read_rows
from mjtraj.study.sweep import SweepSettings, columns, fixed_columns
from mjtraj.study.sweep_store import SweepStore

SMALL = dict(scenarios=6, batch=3, planners=("optimal", "cubic"))


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """The small sweep as a CSV file and as a store: (csv path, store path)."""
    folder = tmp_path_factory.mktemp("stores")
    csv, store = folder / "small.csv", folder / "small.sqlite"
    run_sweep(SweepSettings(**SMALL), csv, workers=1, progress=False)
    run_sweep(SweepSettings(**SMALL), store, workers=1, progress=False)
    return csv, store


def _units(path):
    with sqlite3.connect(path) as connection:
        return sorted(connection.execute("SELECT family, unit, rows FROM units"))


def test_the_store_holds_the_csv_files_rows_bit_for_bit(stored):
    csv, store = stored
    assert read_rows(store) == read_rows(csv)  # floats as repr(): the same text, so the same bits
    assert _units(store) == [("nominal", 0, 6), ("nominal", 1, 6)]


def test_a_row_twice_is_impossible_and_a_failed_unit_leaves_nothing(stored, tmp_path):
    _, store = stored
    path = tmp_path / "s.sqlite"
    path.write_bytes(store.read_bytes())
    settings = SweepSettings(**SMALL)
    unit_rows = {unit: settings.unit_rows(unit) for unit in settings.units()}
    rows = read_rows(path)
    with sqlite3.connect(path) as connection:  # forget unit 1 but keep one of its rows, as an edit would
        connection.execute("DELETE FROM units WHERE unit = 1")
    with pytest.raises(InvalidInputError, match=r"^out: cannot resume .*: rows of unit nominal 1 are stored without "
                                                 r"the unit; the store was edited"):
        SweepStore.open(path, columns(settings), fixed_columns(settings), unit_rows, resume=True)
    path.write_bytes(store.read_bytes())
    with sqlite3.connect(path) as connection:
        connection.execute("DELETE FROM units WHERE unit = 1")
        connection.execute("DELETE FROM rows WHERE unit = '1'")
    writer = SweepStore.open(path, columns(settings), fixed_columns(settings), unit_rows, resume=True)
    try:
        assert writer.done == {("nominal", 0)}
        unit0 = [r for r in rows if r["unit"] == "0"]
        half = [*[r for r in rows if r["unit"] == "1"][:3], unit0[0]]  # a unit whose last row repeats a stored key
        with pytest.raises(InvalidInputError, match=r"unit nominal 1 is already stored \(UNIQUE constraint failed"):
            writer.append([{**r, "unit": "1"} for r in half])
        assert len(read_rows(path)) == 6 and writer.done == {("nominal", 0)}  # nothing of the failed unit is kept
    finally:
        writer.close()


@pytest.mark.parametrize("damage", ["units", "settings", "versions", "foreign unit", "not a store", "text"])
def test_resume_refuses_what_a_sweep_cannot_have_written(stored, tmp_path, damage):
    _, store = stored
    path = tmp_path / "s.sqlite"
    path.write_bytes(store.read_bytes())
    settings = SweepSettings(**SMALL)
    match = {"units": r"unit nominal 0 has 5 rows, its entry says 6; the store was edited",
             "settings": r"setting 'sweep_seed' differs \(store: '0', now: '1'\)",
             "versions": r"its rows were computed with mujoco 3.0.0, this run has mujoco \S+; start a new store \(a "
                         r"store holds rows of one provenance\)$",
             "foreign unit": r"it holds unit nominal 9, which this sweep does not have",
             "not a store": r"is a SQLite database but not an mjtraj sweep store",
             "text": r"it is not a SQLite sweep store"}[damage]
    with sqlite3.connect(path) as connection:
        if damage == "units":
            connection.execute("DELETE FROM rows WHERE rowid = (SELECT MIN(rowid) FROM rows)")
        elif damage == "settings":
            settings = SweepSettings(**{**SMALL, "seed": 1})
        elif damage == "versions":
            (meta,) = connection.execute("SELECT value FROM meta WHERE key = 'settings'").fetchone()
            connection.execute("UPDATE meta SET value = ? WHERE key = 'settings'",
                               (json.dumps({**json.loads(meta), "mujoco": "3.0.0"}),))
        elif damage == "foreign unit":  # consistent, but a unit this sweep does not have
            connection.execute("UPDATE rows SET unit = '9' WHERE unit = '1'")
            connection.execute("UPDATE units SET unit = 9 WHERE unit = 1")
        elif damage == "not a store":
            connection.execute("DROP TABLE meta")
    if damage == "text":
        path.write_text("family,scenario\n")
    before = path.read_bytes()
    with pytest.raises(InvalidInputError, match=rf"^out: cannot resume {path}: .*{match}|^sweep: {path} {match}"):
        run_sweep(settings, path, resume=True, workers=1, progress=False)
    assert path.read_bytes() == before


def test_resume_across_a_provenance_change_is_refused_in_one_line(stored, tmp_path, monkeypatch, capsys):
    """A store holds rows of one provenance: resumed by a process with another numpy and commit, it is refused in one
    line naming both, the store untouched. The store's own values are numpy's and git's."""
    import numpy as np
    from oracles import provenance_oracle

    import mjtraj.study.sweep

    _, store = stored
    path = tmp_path / "s.sqlite"
    path.write_bytes(store.read_bytes())
    with sqlite3.connect(path) as connection:  # a store with its last unit still to do
        connection.execute("DELETE FROM rows WHERE unit = '1'")
        connection.execute("DELETE FROM units WHERE unit = 1")
    before = path.read_bytes()
    written = json.loads(sqlite3.connect(path).execute("SELECT value FROM meta WHERE key = 'settings'").fetchone()[0])
    assert written["numpy"] == np.__version__ and written["commit"].startswith(provenance_oracle()["commit"])
    other = {**mjtraj.study.sweep.provenance(), "numpy": "0.0.1", "commit": "f" * 40}
    monkeypatch.setattr(mjtraj.study.sweep, "provenance", lambda: other)
    with pytest.raises(ProvenanceError) as refused:
        run_sweep(SweepSettings(**SMALL), path, resume=True, workers=1, progress=False)
    assert str(refused.value) == (f"out: cannot resume {path}: its rows were computed with numpy {np.__version__}, "
                                  f"commit {written['commit']}, this run has numpy 0.0.1, commit {'f' * 40}; start a "
                                  f"new store (a store holds rows of one provenance)")
    assert path.read_bytes() == before
    capsys.readouterr()
    assert main(["sweep", "--scenarios", "6", "--batch", "3", "--planners", "optimal,cubic", "--workers", "1",
                 "--no-progress", "--out", str(path), "--resume"]) == 2
    assert capsys.readouterr().err == f"mjtraj: error: {refused.value}\n"
    assert path.read_bytes() == before


def test_a_unit_a_worker_computed_under_another_provenance_is_refused(tmp_path, monkeypatch):
    """The driver stores only rows of its own provenance: a unit that comes back from a worker with another (here
    the driver's numpy differs) ends the sweep before it is stored."""
    import numpy as np

    import mjtraj.study.runner

    monkeypatch.setattr(mjtraj.study.runner, "fixed_columns", lambda s: {**fixed_columns(s), "numpy": "0.0.1"})
    path = tmp_path / "s.sqlite"
    with pytest.raises(ProvenanceError) as refused:
        run_sweep(SweepSettings(**SMALL), path, workers=1, progress=False)
    assert str(refused.value) == (f"sweep: unit nominal 0 came back from a worker whose rows were computed with numpy "
                                  f"{np.__version__}, this run has numpy 0.0.1; every worker must run mjtraj from the "
                                  f"same commit with the same libraries, BLAS and CPU model")
    assert not path.exists()  # nothing was stored: nothing is left


def test_a_store_from_before_the_full_provenance_is_read_but_not_resumed(stored, tmp_path):
    """A 0.4.0.dev0 store (its rows record mjtraj, mujoco and numpy only): export and audit read it; --resume
    refuses it, naming what it does not record."""
    from mjtraj.versions import MACHINE, PROVENANCE

    _, store = stored
    rows = read_rows(store)
    dropped = list(PROVENANCE[3:])
    assert set(MACHINE) <= set(dropped) and "scipy" in dropped
    old_columns = [c for c in rows[0] if c not in dropped]
    settings = SweepSettings(**SMALL)
    record = {k: v for k, v in fixed_columns(settings).items() if k not in dropped}
    path = tmp_path / "old.sqlite"
    writer = SweepStore.open(path, old_columns, {**record, "mjtraj": "0.4.0.dev0"},
                             {unit: settings.unit_rows(unit) for unit in settings.units()}, resume=False)
    try:
        for unit in ("0", "1"):
            writer.append([{**{c: r[c] for c in old_columns}, "mjtraj": "0.4.0.dev0"} for r in rows
                           if r["unit"] == unit])
    finally:
        writer.close()
    assert main(["export", str(path), "--out", str(tmp_path / "old.csv")]) == 0
    assert [r["cost"] for r in read_rows(tmp_path / "old.csv")] == [r["cost"] for r in rows]
    assert main(["audit", str(path), "--no-tasks", "--out", str(tmp_path / "AUDIT.md")]) == 0
    assert f"Versions: mjtraj 0.4.0.dev0, mujoco {rows[0]['mujoco']}, numpy {rows[0]['numpy']}." in \
        (tmp_path / "AUDIT.md").read_text()
    with pytest.raises(ProvenanceError) as refused:
        run_sweep(settings, path, resume=True, workers=1, progress=False)
    assert str(refused.value) == (
        f"out: cannot resume {path}: its rows were computed with mjtraj 0.4.0.dev0, this run has mjtraj "
        f"{rows[0]['mjtraj']}; record no scipy, osqp, daqp, numba, llvmlite, pin, ruckig, torch, gymnasium, BLAS, "
        f"CPU, commit (written before mjtraj recorded them); start a new store (a store holds rows of one "
        f"provenance)")


def test_a_second_writer_is_refused_while_the_first_holds_the_store(stored, tmp_path):
    _, store = stored
    path = tmp_path / "busy.sqlite"
    settings = SweepSettings(**SMALL)
    unit_rows = {unit: settings.unit_rows(unit) for unit in settings.units()}
    first = SweepStore.open(path, columns(settings), fixed_columns(settings), unit_rows, resume=False)
    try:
        with pytest.raises(InvalidInputError, match=r"^out: .* is being written by another sweep right now"):
            run_sweep(settings, path, resume=True, workers=1, progress=False)
    finally:
        first.close()
    report = run_sweep(settings, path, resume=True, workers=1, progress=False)  # the lock went with close()
    assert report.rows == 12 and read_rows(path) == read_rows(store)
    with pytest.raises(InvalidInputError, match=r"exists; pass --resume"):
        run_sweep(settings, path, workers=1, progress=False)


def _stored_units(path) -> int:
    try:
        with sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True) as connection:
            return int(connection.execute("SELECT COUNT(*) FROM units").fetchone()[0])
    except sqlite3.Error:  # not created yet
        return 0


@pytest.mark.slow
@pytest.mark.parametrize("after", [0, 1, 12, 30])
def test_resume_after_a_kill_at_any_moment_gives_the_uninterrupted_rows(tmp_path, after):
    """SIGKILL once `after` of 40 units are stored (0: during start-up), so mostly in the middle of a unit's
    computation or transaction; every stored unit is whole, and the resumed store equals a run never
    interrupted, row for row."""
    args = ["--scenarios", "120", "--batch", "3", "--planners", "optimal,cubic", "--workers", "1", "--no-progress"]
    whole, cut = tmp_path / "whole.sqlite", tmp_path / "cut.sqlite"
    subprocess.run([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(whole)], check=True,
                   capture_output=True)
    proc = subprocess.Popen([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(cut)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and proc.poll() is None and (after == 0 or _stored_units(cut) < after):
        time.sleep(0.3 if after == 0 else 0.005)
        if after == 0:
            break
    assert proc.poll() is None, "the sweep ended before the kill"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    stored = _units(cut) if _stored_units(cut) else []
    assert len(stored) < 40 and all(rows == 6 for _, _, rows in stored)  # whole units only
    if stored:
        assert len(read_rows(cut)) == 6 * len(stored)
    subprocess.run([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(cut), "--resume"], check=True,
                   capture_output=True, text=True)
    assert read_rows(cut) == read_rows(whole)  # one worker stores units in order: the same rows in the same order


@pytest.mark.slow
def test_export_and_audit_read_stores(stored, tmp_path, capsys):
    csv, store = stored
    assert main(["export", str(store), "--out", str(tmp_path / "back.csv")]) == 0
    assert read_rows(tmp_path / "back.csv") == read_rows(csv)
    assert (tmp_path / "back.csv").read_bytes() == csv.read_bytes()
    assert main(["audit", str(store), "--no-tasks", "--out", str(tmp_path / "AUDIT.md")]) == 0
    text = (tmp_path / "AUDIT.md").read_text()
    assert "nominal" in text
    capsys.readouterr()
    assert main(["audit", str(store), "--no-tasks", "--json", "--out", str(tmp_path / "AUDIT2.md")]) == 0
    record = json.loads(capsys.readouterr().out)  # the verdict table as records, nothing else on stdout
    assert [r["claim"] for r in record["verdicts"]] == [1, 2, 3, 4, 5, 6]
    for r in record["verdicts"]:  # each record is its row of the Markdown table
        assert f"| {r['claim']} | {r['text']} | {' | '.join(r['verdicts'].values())} |" in text


def test_cells_of_some_columns_are_the_rows_columns_from_a_store_and_a_csv_file(stored):
    """iter_cells(path, only): the header and cells of those columns, in the file's order, from either format;
    what read_rows holds for them."""
    from mjtraj.study.store import iter_cells

    csv, store = stored
    only = {"planner", "scenario", "cost", "family", "no_such_column"}
    for path in (csv, store):
        cells = list(iter_cells(path, only))
        header = [c for c in read_rows(path)[0] if c in only]
        assert list(cells[0]) == header
        assert cells[1:] == [tuple(r[c] for c in header) for r in read_rows(path)]
    assert list(iter_cells(csv, only)) == list(iter_cells(store, only))


def test_the_rowid_ranges_cover_every_row_once_in_order_also_with_gaps(tmp_path):
    """rowid_bounds splits the rowid span evenly (no row read); reading the ranges one after another gives the
    store's rows in order, each once, with no range empty: on a store as written (equal ranges) and on one with
    a run of rows deleted (the emptied range merged into the next)."""
    from mjtraj.bench import synthetic_store
    from mjtraj.study.sweep_store import iter_store_cells, rowid_bounds

    path = tmp_path / "s.sqlite"
    synthetic_store(str(path), 1000)

    def parts(ranges):
        out = []
        for rowids in ranges:
            cells = iter_store_cells(path, rowids=rowids)
            next(cells)
            out.append(list(cells))
        return out

    whole = parts([(None, None)])[0]
    split = parts(rowid_bounds(path, 7))
    assert [len(p) for p in split] == [142, 143, 143, 143, 143, 143, 143] and sum(split, []) == whole
    assert len(rowid_bounds(path, 5000)) == 1000  # never more ranges than rows
    with sqlite3.connect(path) as connection:
        connection.execute("DELETE FROM rows WHERE rowid > 150 AND rowid <= 600")
    with sqlite3.connect(path) as connection:
        left = [r for (r,) in connection.execute("SELECT rowid FROM rows ORDER BY rowid")]
    split = parts(rowid_bounds(path, 7))
    assert [len(p) for p in split] == [142, 8, 114, 143, 143] and sum(split, []) == [whole[r - 1] for r in left]


def test_one_scan_counts_the_rows_of_each_unit_as_python_counts_them(stored, tmp_path):
    """unit_row_counts against counting the rows in Python: the planners' rows and every row of each unit; an
    edited store (a row deleted, a unit's entry deleted) is refused as iter_store_cells refuses it."""
    import collections
    import shutil

    from mjtraj.study.sweep_store import iter_store_rows, unit_row_counts

    _, store = stored
    rows = list(iter_store_rows(store))
    for planners in (None, {"cubic"}, {"cubic", "optimal", "nothing"}):
        total, own, every = unit_row_counts(store, planners)
        assert total == len(rows)
        assert every == collections.Counter((r["family"], r["unit"]) for r in rows)
        assert own == collections.Counter((r["family"], r["unit"]) for r in rows
                                          if planners is None or r["planner"] in planners)
    for edit, message in (("DELETE FROM rows WHERE rowid = 2", r"unit nominal 0 has 5 rows, its entry says 6"),
                          ("DELETE FROM units WHERE unit = 1", r"rows of unit nominal 1 are stored without the unit")):
        edited = tmp_path / f"{len(message)}.sqlite"
        shutil.copyfile(store, edited)
        with sqlite3.connect(edited) as connection:
            connection.execute(edit)
        with pytest.raises(InvalidInputError, match=message):
            unit_row_counts(edited, None)
        with pytest.raises(InvalidInputError, match=message):
            list(iter_store_rows(edited))
