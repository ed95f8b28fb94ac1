"""The audit's reading of sweep files: each file's units counted and checked whole, then every kept row's metrics
as per-planner arrays aligned by scenario, per condition (`SweepData`)."""

from __future__ import annotations

import dataclasses
import itertools
import operator
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.core.metrics import METRIC_NAMES
from mjtraj.domain.families import FAMILIES
from mjtraj.domain.scenario import load_scenario
from mjtraj.exceptions import InvalidInputError, MjtrajError
from mjtraj.study.fixed_tasks import TASKS, task_rows
from mjtraj.study.store import VERSION_COLUMNS, expected_rows, iter_cells, iter_rows
from mjtraj.study.sweep import SHIPPED_CONFIG
from mjtraj.study.sweep_store import is_sqlite_file, iter_store_cells, unit_row_counts

NUMERIC = METRIC_NAMES + ("model_error", "plan_effort", "max_displacement", "duration")


@dataclass(frozen=True)
class Condition:
    """One family under one controller variant, with one set of planner weights (the sweep's scenario file; ''
    when the audit reads a single one)."""

    family: str
    ff_accel: str
    gravity_comp: str
    weights: str = ""

    def __str__(self) -> str:
        where = f"{self.family}, ff_accel={self.ff_accel}, gravity_comp={self.gravity_comp}"
        return f"{self.weights}: {where}" if self.weights else where


def weights_label(config: str) -> str:
    """How a sweep's scenario file is named in the audit: Bryson's weights for the shipped paper scenario, and an
    ORACLE label for a file tuned on its own task (`mjtraj tune --on-task`)."""
    if config == SHIPPED_CONFIG:
        return "Bryson weights (paper.toml)"
    try:
        tuning = load_scenario(config).tuning or {}
    except MjtrajError:
        tuning = {}
    return f"{config} (ORACLE: tuned on its own task)" if str(tuning.get("mode", "")).startswith("oracle") else config


def unit_counts(rows: Iterable[dict[str, str]]
                ) -> tuple[dict[str, str] | None, int, dict[tuple[str, str], int], dict[tuple[str, str], int]]:
    """One pass over a sweep's rows: its first row, how many there are, the rows of the sweep's own planners in each
    (family, unit), and all the rows in each (rows of other controllers, rl eval's policies, ride along with their
    unit)."""
    first: dict[str, str] | None = None
    total = 0
    own: dict[tuple[str, str], int] = {}
    every: dict[tuple[str, str], int] = {}
    planners: set[str] = set()
    for row in rows:
        if first is None:
            first = row
            planners = set(row.get("sweep_planners", "").split("+"))
        total += 1
        if "unit" in row:
            key = (row["family"], row["unit"])
            every[key] = every.get(key, 0) + 1
            if row.get("planner") in planners:
                own[key] = own.get(key, 0) + 1
    return first, total, own, every


def whole_units(first: dict[str, str], counts: dict[tuple[str, str], int]) -> set[tuple[str, str]]:
    """The (family, unit) keys of `counts` (rows of the sweep's own planners) that hold every row they should
    (scenarios of the unit x planners x variants, from the settings `first` records)."""
    try:
        per_scenario = int(np.prod([len(first[k].split("+")) for k in ("sweep_planners", "sweep_ff_accel",
                                                                       "sweep_gravity_comp")]))
        batch, scenarios = int(first["sweep_batch"]), int(first["sweep_scenarios"])
        return {key for key, n in counts.items() if n == per_scenario * min(batch, scenarios - int(key[1]) * batch)}
    except (KeyError, ValueError) as e:
        raise InvalidInputError(f"sweep: a row's settings are malformed ({e}); not a sweep results file") from e


def complete_units(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    """The rows of the units that hold every row they should (scenarios of the unit x planners x variants)."""
    if not rows or "sweep_batch" not in rows[0] or "unit" not in rows[0]:
        return rows
    whole = whole_units(rows[0], unit_counts(rows)[2])
    return [r for r in rows if (r["family"], r["unit"]) in whole]


def _rows_as_cells(rows: list[dict[str, str]]) -> Iterator[tuple[str, ...]]:
    """Rows of dicts as `iter_cells` gives a file's: the header (the first row's keys), then each row's cells."""
    if rows:
        header = tuple(rows[0])
        yield header
        yield from (tuple(r[c] for c in header) for r in rows)


class _Kept:
    """The header, then the cells of the rows of the file `path` in the (family, unit) keys `keep` (every row if
    None), read anew, row by row, at each iteration."""

    def __init__(self, path: str | os.PathLike[str], keep: set[tuple[str, str]] | None) -> None:
        self.path, self.keep = path, keep

    def __iter__(self) -> Iterator[tuple[str, ...]]:
        cells = iter_cells(self.path, READ_COLUMNS)
        header = next(cells)
        yield header
        if self.keep is None:
            yield from cells
            return
        family, unit = header.index("family"), header.index("unit")
        yield from (values for values in cells if (values[family], values[unit]) in self.keep)

    def first(self) -> dict[str, str] | None:
        """The first kept row, every column of it, or None."""
        cells = iter_cells(self.path)
        header = next(cells)
        if self.keep is not None:
            family, unit = header.index("family"), header.index("unit")
            cells = (values for values in cells if (values[family], values[unit]) in self.keep)
        values = next(cells, None)
        return None if values is None else dict(zip(header, values, strict=True))


def _file_counts(path: str | os.PathLike[str]
                 ) -> tuple[dict[str, str] | None, int, dict[tuple[str, str], int], dict[tuple[str, str], int]]:
    """`unit_counts` of the file `path`; a store's counted by SQLite in one scan (no row reaches Python)."""
    first = _first_stored_row(path) if is_sqlite_file(path) else None
    if first is None or "unit" not in first:  # a CSV file, or a store without units: counted row by row
        return unit_counts(iter_rows(path))
    total, own, every = unit_row_counts(path, first.get("sweep_planners", "").split("+"))  # the units checked
    return first, total, dict(own), dict(every)


def _first_stored_row(path: str | os.PathLike[str]) -> dict[str, str] | None:
    """The first row of the store `path`, every column of it, or None; its units are checked by whoever counts
    them (`unit_row_counts`)."""
    cells = iter_store_cells(path, rowids=(None, None))
    try:
        header = next(cells)
        values = next(cells, None)
    finally:
        cells.close()
    return None if values is None else dict(zip(header, values, strict=True))


READ_COLUMNS = frozenset(("family", "unit", "scenario", "planner", "status", "ff_accel", "gravity_comp", "config",
                          *NUMERIC))
"""The columns the audit's second pass reads (the first row's settings and versions are read whole)."""
READ_CHUNK = 10_000
"""Rows whose metrics are parsed into arrays at a time by the audit's second pass."""
FAILED_NAN = np.array([j for j, m in enumerate(NUMERIC) if m != "max_displacement"], dtype=np.intp)
"""The metrics (indices into NUMERIC) a failed row does not have: all but max_displacement."""


@dataclass
class _Group:
    """The rows of one (condition, planner): scenario numbers, ok flags and metrics (NUMERIC order), in file order,
    as chunks of arrays."""

    scenarios: list[NDArray[np.int64]] = dataclasses.field(default_factory=list)
    ok: list[NDArray[np.float64]] = dataclasses.field(default_factory=list)
    missed: list[NDArray[np.float64]] = dataclasses.field(default_factory=list)
    metrics: list[NDArray[np.float64]] = dataclasses.field(default_factory=list)


class SweepData:
    """A sweep's rows as per-planner arrays aligned by scenario, per condition; with `tasks`, also each file's rows
    on the paper task and its reverse (`mjtraj.study.fixed_tasks`), computed now.

    Each file is read twice: once to count its units (by SQLite for a store), once, row by row as cells
    (`iter_cells`), to keep the metrics the audit reads as arrays; no row's text is kept, so memory grows with the
    metrics (about 130 bytes a row), not with the rows.
    """

    def __init__(self, paths: Sequence[str | os.PathLike[str]], *, partial: bool = False, tasks: bool = False,
                 progress: Callable[[str], None] | None = None) -> None:
        self.missing: dict[str, str] = {}
        """File -> what `partial` left out of it."""
        self.task_notes: dict[str, str] = {}
        """File -> why its fixed-task rows could not be computed."""
        self.count = 0
        """Rows audited."""
        self.first: dict[str, str] = {}
        """The first audited row (every row records the sweep's settings and versions)."""
        sources: list[tuple[Iterable[tuple[str, ...]], dict[str, str] | None]] = []
        for path in paths:
            if not Path(path).is_file():
                raise InvalidInputError(f"sweep: file not found: {path}")
            if progress is not None:
                progress(f"reading {Path(path).name}")
            rows = _Kept(path, self._kept_units(path, partial))
            start = rows.first()
            sources.append((rows, start))
            if tasks and start is not None:
                if progress is not None:
                    progress(f"the paper task and its reverse for {Path(path).name}")
                extra, why = task_rows(start)
                sources.append((list(_rows_as_cells(extra)), extra[0] if extra else None))
                if why:
                    self.task_notes[str(path)] = why
        self._read(sources, paths)

    def _kept_units(self, path: str | os.PathLike[str], partial: bool) -> set[tuple[str, str]] | None:
        """The first pass over the file `path`: the (family, unit) keys of its complete units where some are not
        (None: every row). An incomplete file is refused unless `partial`, which notes what it leaves out in
        `missing`."""
        first, total, own, every = _file_counts(path)
        keep = None
        if first is not None and "sweep_batch" in first and "unit" in first:
            whole = whole_units(first, own)
            kept = sum(n for key, n in every.items() if key in whole)
            if kept < total:
                if not partial:
                    raise InvalidInputError(
                        f"sweep: {path} is incomplete: {kept} of its {total} rows are in complete units, "
                        f"{expected_rows(first)} expected; finish it with the same mjtraj sweep command and "
                        f"--resume, or pass --partial to audit the complete units only")
                self.missing[str(path)] = f"{total - kept} rows of incomplete units left out"
                keep = whole
        if first is not None and keep is None and total < expected_rows(first):
            if not partial:
                raise InvalidInputError(
                    f"sweep: {path} is incomplete: {total} of {expected_rows(first)} rows; finish it with the "
                    f"same mjtraj sweep command and --resume, or pass --partial to audit what is there")
            self.missing[str(path)] = f"{expected_rows(first) - total} of {expected_rows(first)} rows " \
                                      f"not computed yet"
        return keep

    def _read(self, sources: list[tuple[Iterable[tuple[str, ...]], dict[str, str] | None]],
              paths: Sequence[str | os.PathLike[str]]) -> None:
        """The second pass: every kept row's metrics into arrays per (condition, planner), READ_CHUNK rows at a time,
        then per-condition tables aligned by scenario (a scenario stored twice keeps its last row)."""
        groups = self._groups(sources)
        if not self.count:
            raise InvalidInputError(f"sweep: no rows in {', '.join(map(str, paths))}")
        self.versions = {k: self.first[k] for k in VERSION_COLUMNS if k in self.first}  # an older file records fewer
        self.settings = {k: v for k, v in self.first.items() if k.startswith("sweep_") or k in ("sensor_noise",
                                                                                               "delay")}
        configs = list(dict.fromkeys(key[3] for key in groups))
        self.planners = list(dict.fromkeys(key[4] for key in groups))
        self.weights = [weights_label(c) for c in configs] if len(configs) > 1 else [""]
        merged: dict[Condition, dict[str, list[_Group]]] = {}
        for (family, ff_accel, gravity_comp, config, planner), group in groups.items():
            label = weights_label(config) if len(configs) > 1 else ""
            merged.setdefault(Condition(family, ff_accel, gravity_comp, label), {}).setdefault(planner, []).append(
                group)
        order = {family: k for k, family in enumerate(FAMILIES + TASKS)}
        self.conditions = sorted(merged, key=lambda c: (self.weights.index(c.weights),
                                                        order.get(c.family, len(order)), c.ff_accel, c.gravity_comp))
        self._tables: dict[Condition, dict[str, dict[str, NDArray[np.float64]]]] = {
            c: _table(merged[c]) for c in self.conditions}

    def _groups(self, sources: list[tuple[Iterable[tuple[str, ...]], dict[str, str] | None]]
                ) -> dict[tuple[str, str, str, str, str], _Group]:
        """Every row of `sources` (each: cells, header first, and its first row) into groups by (family, ff_accel,
        gravity_comp, config, planner), READ_CHUNK rows at a time; counts the rows (`count`) and keeps the first
        (`first`)."""
        groups: dict[tuple[str, str, str, str, str], _Group] = {}
        for source, first in sources:
            cells = iter(source)
            header = next(cells, None)
            if header is None:
                continue
            where = {c: i for i, c in enumerate(header)}
            missing = [c for c in ("family", "scenario", "planner", "status", "ff_accel", "gravity_comp", *NUMERIC)
                       if c not in where]
            metric_cells = operator.itemgetter(*(where.get(m, 0) for m in NUMERIC))  # used once none is missing
            key_cells = (where.get("family"), where.get("ff_accel"), where.get("gravity_comp"), where.get("config"),
                         where.get("planner"))
            while chunk := list(itertools.islice(cells, READ_CHUNK)):
                if missing:
                    raise InvalidInputError(f"sweep: not a sweep results file (missing columns {', '.join(missing)})")
                if not self.count and first is not None:
                    self.first = first
                self.count += len(chunk)
                self._add(groups, chunk, where, key_cells, metric_cells)
        return groups

    @staticmethod
    def _add(groups: dict[tuple[str, str, str, str, str], _Group], chunk: list[tuple[str, ...]],
             where: dict[str, int], key_cells: tuple[int | None, ...], metric_cells: Callable[[Any], Any]) -> None:
        """One chunk of rows (cells in `where`'s order) into `groups`: their metrics parsed as arrays ('' and
        'nan' missing; NaN where the row failed, but max_displacement)."""
        f, a, g, c, p = key_cells
        keys = [(v[f], v[a], v[g], "" if c is None else v[c], v[p]) for v in chunk]  # type: ignore[index]
        metrics = np.fromiter((float(cell or "nan") for v in chunk for cell in metric_cells(v)), dtype=np.float64,
                              count=len(chunk) * len(NUMERIC)).reshape(len(chunk), len(NUMERIC))  # as `numeric`
        good = np.array([v[where["status"]] == "ok" for v in chunk])
        missed = np.array([v[where["status"]] == "missed_goal" for v in chunk])
        failed = np.flatnonzero(~good)
        metrics[np.ix_(failed, FAILED_NAN)] = np.nan
        scenario = np.array([v[where["scenario"]] for v in chunk]).astype(np.int64)
        ids: dict[tuple[str, str, str, str, str], list[int]] = {}
        for i, key in enumerate(keys):
            ids.setdefault(key, []).append(i)
        for key, rows in ids.items():
            group = groups.setdefault(key, _Group())
            group.scenarios.append(scenario[rows])
            group.ok.append(good[rows].astype(np.float64))
            group.missed.append(missed[rows].astype(np.float64))
            group.metrics.append(metrics[rows])

    def values(self, condition: Condition, planner: str, metric: str) -> NDArray[np.float64]:
        """Per-scenario values (NaN where the planner failed); empty if the planner is absent."""
        return self._tables[condition].get(planner, {}).get(metric, np.zeros(0))

    def has(self, condition: Condition, planner: str) -> bool:
        return planner in self._tables[condition]

    def failures(self, condition: Condition, planner: str) -> int:
        ok = self.values(condition, planner, "ok")
        return int(np.sum(ok != 1.0))

    def missed_goals(self, condition: Condition, planner: str) -> int:
        """Rows of the planner in the condition whose status is missed_goal (counted among its failures)."""
        return int(np.sum(self.values(condition, planner, "missed") == 1.0))


def _table(parts: dict[str, list[_Group]]) -> dict[str, dict[str, NDArray[np.float64]]]:
    """One condition's table: planner -> metric (NUMERIC, ok, missed) -> values per scenario of the condition (those
    of any planner, sorted; NaN where a planner has no row), a scenario stored twice at its last row."""
    per = {planner: [np.concatenate([a for g in groups for a in getattr(g, name)])
                     for name in ("scenarios", "ok", "missed", "metrics")]
           for planner, groups in parts.items()}
    scenarios = np.unique(np.concatenate([s for s, _, _, _ in per.values()]))
    table: dict[str, dict[str, NDArray[np.float64]]] = {}
    for planner, (scenario, ok, missed, metrics) in per.items():
        last = len(scenario) - 1 - np.unique(scenario[::-1], return_index=True)[1]  # a repeat's last row
        at = np.searchsorted(scenarios, scenario[last])
        t = {m: np.full(len(scenarios), np.nan) for m in NUMERIC + ("ok", "missed")}
        t["ok"][at] = ok[last]
        t["missed"][at] = missed[last]
        for j, m in enumerate(NUMERIC):
            t[m][at] = metrics[last, j]
        table[planner] = t
    return table
