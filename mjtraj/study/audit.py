"""`mjtraj audit`: the paper's six claims checked against sweep files, written as AUDIT.md with figures.

Verdict rule, per condition (family x ff_accel x gravity_comp): a comparison "A below B" holds when the 95 %
bootstrap interval of the paired ratio mean(B)/mean(A) lies above 1, fails when it lies below 1, and is
inconclusive otherwise. On the paper task and its reverse (one fixed motion each, a measurement rather than a
sample) it holds when B's value is above A's and fails when it is below. A claim holds in a condition when all its
comparisons hold. Across conditions: "holds" (all), "does not hold" (none), else "depends" with the conditions where
it holds.
"""

from __future__ import annotations

import dataclasses
import itertools
import operator
import os
import re
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.core.metrics import GOAL_TOLERANCE, METRIC_NAMES
from mjtraj.exceptions import InvalidInputError, MjtrajError
from mjtraj.study.families import FAMILIES
from mjtraj.study.fixed_tasks import TASKS, task_rows
from mjtraj.study.paper import PAPER_TABLE
from mjtraj.study.scenario import load_scenario
from mjtraj.study.stats import EXACT_PAIRS, PairedRatio, cvar, paired_ratio
from mjtraj.study.store import VERSION_COLUMNS, expected_rows, iter_cells, iter_rows
from mjtraj.study.sweep import SHIPPED_CONFIG, SweepSettings
from mjtraj.study.sweep_store import is_sqlite_file, iter_store_cells, unit_row_counts
from mjtraj.versions import describe

CLASSICAL = ("cubic", "quintic", "trapezoidal")
LARGE_MOTION = 1.0
"""rad: claim 6 is checked on scenarios whose largest joint displacement exceeds this."""
NUMERIC = METRIC_NAMES + ("model_error", "plan_effort", "max_displacement", "duration")


MIN_SCENARIOS = 10
"""A comparison on fewer paired scenarios gets no verdict (its bootstrap interval would mean nothing)."""


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
FAILED_NAN = np.array([j for j, m in enumerate(NUMERIC) if m != "max_displacement"], dtype=np.intp)
"""The metrics (indices into NUMERIC) a failed row does not have: all but max_displacement."""
"""Rows whose metrics are parsed into arrays at a time by the audit's second pass."""


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
            rows = _Kept(path, keep)
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

    def _read(self, sources: list[tuple[Iterable[tuple[str, ...]], dict[str, str] | None]],
              paths: Sequence[str | os.PathLike[str]]) -> None:
        """The second pass: every kept row's metrics into arrays per (condition, planner), READ_CHUNK rows at a time,
        then per-condition tables aligned by scenario (a scenario stored twice keeps its last row)."""
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
        self._tables: dict[Condition, dict[str, dict[str, NDArray[np.float64]]]] = {}
        for c in self.conditions:
            per = {planner: [np.concatenate([a for g in parts for a in getattr(g, name)])
                             for name in ("scenarios", "ok", "missed", "metrics")]
                   for planner, parts in merged[c].items()}
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
            self._tables[c] = table

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


def below(data: SweepData, c: Condition, a: str, b: str, metric: str, mask: NDArray[np.bool_] | None = None
          ) -> tuple[str, PairedRatio]:
    """Is planner a's metric below planner b's? ('yes' | 'no' | 'inconclusive', ratio mean(b)/mean(a))."""
    x, y = data.values(c, b, metric), data.values(c, a, metric)
    if mask is not None:
        x, y = x[mask], y[mask]
    r = paired_ratio(x, y)
    if c.family in TASKS:  # one fixed motion: a measurement, compared directly
        return ("yes" if r.ratio > 1.0 else "no" if r.ratio < 1.0 else "inconclusive") if r.count else "too few", r
    verdict = ("too few" if r.count < MIN_SCENARIOS else "yes" if r.low > 1.0 else "no" if r.high < 1.0
               else "inconclusive")
    return verdict, r


NO_PAIRS = "- (no paired rows: no ok execution on one side)"


def _fmt_ratio(r: PairedRatio) -> str:
    if r.count == 0 or not np.isfinite(r.ratio):
        return NO_PAIRS
    return f"{r.ratio:.3f}" + (" (one motion)" if r.count == 1 else f" [{r.low:.3f}, {r.high:.3f}]")


def _fmt_red(r: PairedRatio) -> str:
    red, lo, hi = r.reduction
    if r.count == 0 or not np.isfinite(red):
        return NO_PAIRS
    return f"{red:+.1f} %" + (" (one motion)" if r.count == 1 else f" [{lo:+.1f}, {hi:+.1f}]")


def _claim_holds(parts: list[str]) -> str:
    if any(p == "too few" for p in parts):
        return f"no verdict (fewer than {MIN_SCENARIOS} paired scenarios)"
    return "holds" if all(p == "yes" for p in parts) else "does not hold" if any(p == "no" for p in parts) \
        else "inconclusive"


def _overall(per_condition: dict[Condition, str]) -> str:
    per_condition = {c: v for c, v in per_condition.items() if not v.startswith("no verdict")}
    if not per_condition:
        return f"no verdict (fewer than {MIN_SCENARIOS} paired scenarios)"
    held = [c for c, v in per_condition.items() if v == "holds"]
    if len(held) == len(per_condition):
        return "holds"
    if not held:
        return "does not hold"
    parts = []
    for family in dict.fromkeys(c.family for c in per_condition):
        mine = [c for c in per_condition if c.family == family]
        ok = [c for c in mine if c in held]
        if len(ok) == len(mine):
            parts.append(f"{family} (every controller variant)")
        else:
            parts += [str(c) for c in ok]
    return "depends: holds only in " + "; ".join(parts)


def write_audit(paths: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str], *, figures: bool = True,
                partial: bool = False, tasks: bool = True, progress: Callable[[str], None] | None = None,
                figure_formats: Sequence[str] = ("png",)) -> str:
    """Write the audit of the sweep files `paths` to `out` (Markdown) and its figures beside it; return the text.

    An incomplete sweep file is refused unless `partial`, which audits its complete units and says what is missing.
    With `tasks`, each file's planners, controller variants and scenario file are also run on the paper task and its
    reverse (conditions of their own), and the weight frontier on the paper task is computed and drawn.
    `progress(stage)` is called as each stage begins. Each figure is written in every format of `figure_formats`
    (png, pdf, svg); the Markdown shows the first.
    """
    def stage(name: str) -> None:
        if progress is not None:
            progress(name)

    data = SweepData(paths, partial=partial, tasks=tasks, progress=progress)
    stage("the claims")
    out = Path(out)
    lines: list[str] = []
    verdicts: dict[str, dict[Condition, str]] = {str(i): {} for i in range(1, 7)}
    detail: dict[str, list[str]] = {str(i): [] for i in range(1, 7)}
    for c in data.conditions:
        if not data.has(c, "optimal"):
            continue
        present = [p for p in CLASSICAL if data.has(c, p)]
        # 1. lowest RMS tracking error
        parts = [below(data, c, "optimal", p, "rms_err") for p in present]
        verdicts["1"][c] = _claim_holds([v for v, _ in parts])
        detail["1"].append(f"| {c} | " + " | ".join(f"{p}/optimal {_fmt_ratio(r)}" for p, (_, r) in
                                                    zip(present, parts, strict=True)) + f" | {verdicts['1'][c]} |")
        # 2. lowest corrective torque, 28-41 % below
        parts = [below(data, c, "optimal", p, "int_dtau") for p in present]
        verdicts["2"][c] = _claim_holds([v for v, _ in parts])
        in_band = all(r.reduction[2] >= 28.0 and r.reduction[1] <= 41.0 for _, r in parts)
        detail["2"].append(f"| {c} | " + " | ".join(f"{p}: {_fmt_red(r)}" for p, (_, r) in
                                                    zip(present, parts, strict=True))
                           + f" | {verdicts['2'][c]}; 28-41 % band {'met' if in_band else 'not met'} |")
        # 3. lowest executed cost, ~48 % below cubic, > 62 % below quintic and trapezoidal
        parts = [below(data, c, "optimal", p, "cost") for p in present]
        verdicts["3"][c] = _claim_holds([v for v, _ in parts])
        detail["3"].append(f"| {c} | " + " | ".join(f"{p}: {_fmt_red(r)}" for p, (_, r) in
                                                    zip(present, parts, strict=True)) + f" | {verdicts['3'][c]} |")
        # 4. trapezoidal tracks worst
        others = [p for p in ("optimal", "cubic", "quintic") if data.has(c, p)]
        if data.has(c, "trapezoidal"):
            parts = [below(data, c, p, "trapezoidal", "rms_err") for p in others]
            verdicts["4"][c] = _claim_holds([v for v, _ in parts])
            detail["4"].append(f"| {c} | " + " | ".join(f"trapezoidal/{p} {_fmt_ratio(r)}" for p, (_, r) in
                                                        zip(others, parts, strict=True)) + f" | {verdicts['4'][c]} |")
        # 5. quintic needs more effort than cubic
        if data.has(c, "quintic") and data.has(c, "cubic"):
            parts = [below(data, c, "cubic", "quintic", m) for m in ("int_dtau", "rms_dtau")]
            verdicts["5"][c] = _claim_holds([v for v, _ in parts])
            detail["5"].append(f"| {c} | int_dtau quintic/cubic {_fmt_ratio(parts[0][1])} | rms_dtau "
                               f"{_fmt_ratio(parts[1][1])} | {verdicts['5'][c]} |")
        # 6. midpoint beats start linearisation for large motions
        if data.has(c, "optimal_start"):
            large = data.values(c, "optimal", "max_displacement") > LARGE_MOTION
            parts = [below(data, c, "optimal", "optimal_start", m, large) for m in ("model_error", "rms_err", "cost")]
            verdicts["6"][c] = _claim_holds([v for v, _ in parts[:1]])
            detail["6"].append(f"| {c} | {int(large.sum())} | " + " | ".join(
                f"{_fmt_ratio(r)} ({v})" for v, r in parts) + f" | {verdicts['6'][c]} |")
    summary = _summary_table(data)
    lines += _header(data, paths)
    lines += ["## Verdicts", "", "| # | claim (paper) | verdict |", "|---|---|---|"]
    claims = {"1": "the optimal planner has the lowest RMS tracking error",
              "2": "it has the lowest corrective torque, 28 to 41 % below the classical planners",
              "3": "it has the lowest executed cost, about 48 % below cubic, over 62 % below quintic and trapezoidal",
              "4": "the trapezoidal planner tracks worst",
              "5": "higher-order smoothness does not lower effort (quintic needs more than cubic)",
              "6": "midpoint linearisation beats start-point linearisation for large motions"}
    if len(data.weights) > 1:
        lines[-2:] = ["| # | claim (paper) | " + " | ".join(data.weights) + " |",
                      "|---|---|" + "---|" * len(data.weights)]
    for k, text in claims.items():
        cells = []
        for label in data.weights:
            mine = {c: v for c, v in verdicts[k].items() if c.weights == label}
            cells.append(_overall(mine) if mine else "not measured (planner absent)")
        lines.append(f"| {k} | {text} | " + " | ".join(cells) + " |")
    lines += ["", "Verdict rule: " + " ".join((__doc__ or "").split("Verdict rule, ")[1].split()), ""]
    headers = {
        "1": ("RMS tracking error: paired ratio mean(planner)/mean(optimal), 95 % bootstrap interval",
              "| condition | " + " | ".join(CLASSICAL) + " | verdict |"),
        "2": ("Corrective torque (Int. dtau): reduction of optimal vs planner, 100 (1 - optimal/planner) "
              "[interval]; paper: 28.35, 41.29, 30.27 %", "| condition | " + " | ".join(CLASSICAL) + " | verdict |"),
        "3": ("Executed cost J_exec: reduction of optimal vs planner [interval]; paper: 48.13, 62.12, 62.64 %",
              "| condition | " + " | ".join(CLASSICAL) + " | verdict |"),
        "4": ("Trapezoidal tracks worst: mean(trapezoidal)/mean(other) of RMS error",
              "| condition | vs optimal | vs cubic | vs quintic | verdict |"),
        "5": ("Quintic vs cubic effort: mean(quintic)/mean(cubic)", "| condition | Int. dtau | RMS dtau | verdict |"),
        "6": (f"Midpoint vs start linearisation on large motions (max |dq| > {LARGE_MOTION} rad): "
              "mean(start)/mean(midpoint) of the linear model's open-loop prediction error, the executed RMS error "
              "and cost (verdict on the prediction error)",
              "| condition | scenarios | model error | RMS error | cost | verdict |"),
    }
    for k, (title, head) in headers.items():
        lines += [f"## Claim {k}: {claims[k]}", "", title, "", head,
                  "|" + "---|" * (head.count("|") - 1)] + (detail[k] or ["| (not measured) |"]) + [""]
    lines += _conclusions(data)
    if tasks:
        stage("the weight frontier")
        lines += _frontier_section(data, out, paths, figures=figures, formats=figure_formats)
    lines += _where_it_pays(data)
    lines += _min_effort(data)
    if tasks:
        stage("the floors of the fixed motions")
        lines += _floors_section(data)
    lines += ["## Per-condition summary", "", "Mean and median per planner; CVaR(90 %) of the RMS tracking error "
              "(the mean of the worst 10 % of scenarios); failures are rows whose status is not ok. Missed goals "
              "(status missed_goal, on every family: the execution ended farther from its goal than "
              f"{GOAL_TOLERANCE:g} x the task's largest joint displacement) are failures: they keep their metrics in "
              "the sweep file but leave every paired ratio and verdict above, as a diverged row does, so each "
              "verdict reads only executions that reached their goals.", ""] + summary
    if figures:
        stage("the figures")
        lines += _figures(data, out, figure_formats)
    lines += _definitions(data)
    lines += _paper_note()
    text = "\n".join(lines) + "\n"
    from mjtraj.files import write_text_atomic

    write_text_atomic(out, text)
    return text


def _header(data: SweepData, paths: Sequence[str | os.PathLike[str]]) -> list[str]:
    s = data.settings
    return ["# Audit of the paper's claims", "",
            f"Regenerate: `mjtraj audit {' '.join(map(str, paths))}` (this file is written by that command from the "
            f"sweep file; nothing in it is typed by hand).", "",
            f"Sweep: families {s.get('sweep_families')}, {s.get('sweep_scenarios')} scenarios per family, seed "
            f"{s.get('sweep_seed')}, planners {s.get('sweep_planners')}, ff_accel {s.get('sweep_ff_accel')}, "
            f"gravity_comp {s.get('sweep_gravity_comp')}, sensor noise {s.get('sensor_noise')} rad, delay "
            f"{s.get('delay')}; {data.count} rows. Versions: {describe(data.versions)}.", "",
            "Scenario rules are in `mjtraj/study/families.py`; controller and weights rules in "
            "`mjtraj/study/sweep.py`.", ""] + (
        [f"Weights compared, each a sweep's scenario file, never mixed: {', '.join(data.weights)}. Each column of "
         "the verdicts reads only its own sweep's rows; the sweep settings above are the first file's.", ""]
        if len(data.weights) > 1 else []) + (
        ["Partial audit: " + "; ".join(f"{path}: {what}" for path, what in data.missing.items()) + ".", ""]
        if data.missing else []) + (
        ["The paper task and its reverse are conditions of their own: each file's planners, controller variants and "
         "scenario file run now on those two fixed motions (nominal plant, Bryson's score on the task), through "
         "the sweep's own code, with this mjtraj's versions. One motion is a measurement, so their comparisons are "
         "direct, without intervals."
         + "".join(f" Not computed for {path}: {why}." for path, why in data.task_notes.items()), ""]
        if any(c.family in TASKS for c in data.conditions) or data.task_notes else []) + (
        [f"Intervals over more than {EXACT_PAIRS:,} paired scenarios are the delta method's normal intervals, not "
         "the bootstrap's (the same to within the bootstrap's own resampling error at that size, at a small "
         "fraction of its cost).", ""]
        if any(data.values(c, p, "ok").size > EXACT_PAIRS for c in data.conditions for p in data.planners) else [])


def _summary_table(data: SweepData) -> list[str]:
    out = ["| condition | planner | n ok | failures | of them missed goals | RMS err mean / median (rad) | "
           "CVaR90 RMS err | Int. dtau mean / median (N m s) | RMS dtau mean | J_exec mean / median |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for c in data.conditions:
        for p in data.planners:
            if not data.has(c, p):
                continue
            e, i, r, j = (data.values(c, p, m) for m in ("rms_err", "int_dtau", "rms_dtau", "cost"))
            ok = int(np.sum(np.isfinite(e)))
            failed, missed = data.failures(c, p), data.missed_goals(c, p)
            out.append(f"| {c} | {p} | {ok} | {failed} | {missed} | {np.nanmean(e):.4g} / {np.nanmedian(e):.4g} | "
                       f"{cvar(e, 0.9):.4g} | {np.nanmean(i):.4g} / {np.nanmedian(i):.4g} | {np.nanmean(r):.4g} | "
                       f"{np.nanmean(j):.4g} / {np.nanmedian(j):.4g} |" if ok else
                       f"| {c} | {p} | 0 | {failed} | {missed} | - | - | - | - | - |")
    return out + [""]


def _conclusions(data: SweepData) -> list[str]:
    """Plain sentences from the numbers: per set of weights and family (first controller variant), the optimal
    planner's J_exec and tracking error against the cubic's."""
    lines = ["## Conclusions", "",
             "The optimal planner against the cubic (the minimum-effort reference of a constant-inertia arm), in "
             "the first controller variant of each family, as mean ratios over paired scenarios [95 % interval]:",
             ""]
    seen: set[tuple[str, str]] = set()
    for c in data.conditions:
        if (c.weights, c.family) in seen or not (data.has(c, "optimal") and data.has(c, "cubic")):
            continue
        seen.add((c.weights, c.family))
        cost = paired_ratio(data.values(c, "optimal", "cost"), data.values(c, "cubic", "cost"))
        err = paired_ratio(data.values(c, "optimal", "rms_err"), data.values(c, "cubic", "rms_err"))
        if cost.count < MIN_SCENARIOS:
            continue
        verdict = ("lower than" if cost.high < 1.0 else "higher than" if cost.low > 1.0 else
                   "not distinguishable from")
        weights = c.weights or "these weights"
        lines.append(f"- {weights}, {c.family} motions ({cost.count} scenarios): J_exec {verdict} the cubic's, "
                     f"ratio {_fmt_ratio(cost)}, won in {100 * (1 - cost.win_rate):.0f} % of them; RMS tracking "
                     f"error ratio {_fmt_ratio(err)}.")
    return lines + [""] if len(lines) > 4 else []


def _frontier_section(data: SweepData, out: Path, paths: Sequence[str | os.PathLike[str]], *, figures: bool,
                      formats: Sequence[str] = ("png",)) -> list[str]:
    """The optimal planner's weight frontier on the paper task of the first file's scenario, in its first controller
    variant: the table, the figure, and where each audited set of weights puts the optimal planner on that task."""
    from mjtraj.study.frontier import frontier
    from mjtraj.study.report import format_frontier

    head = ["## The weight frontier on the paper task", ""]
    try:
        settings = SweepSettings.from_record(data.first)
    except MjtrajError as e:
        return head + [f"(not computed: {e})", ""]
    ff, gc = settings.ff_accel[0], settings.gravity_comp[0]
    scenario = dataclasses.replace(settings.base, loop=settings.loop_config(ff, gc, mismatch=False))
    result = frontier(scenario)
    points = {}
    for label in data.weights:
        c = Condition(TASKS[0], ff, gc, label)
        if c in data.conditions and data.has(c, "optimal"):
            points[f"optimal, {label or 'these weights'}"] = (float(data.values(c, "optimal", "rms_dtau")[0]),
                                                              float(data.values(c, "optimal", "rms_err")[0]))
    config = data.first.get("config", "")
    lines = head + [
             "The optimal planner for Q = alpha Q_bryson (R = R_bryson fixed), alpha from 0 to 100, on the paper task "
             f"of {weights_label(config) or 'the first file'}, controller ff_accel={ff}, gravity_comp={gc}, scored "
             "by the scenario's fixed J_exec; every other planner as one point. The same table is printed by "
             "`mjtraj frontier`" + ("" if config == SHIPPED_CONFIG else f" --config {config}") + "." + (
                 " Each audited set of weights puts the optimal planner here on this task (RMS dtau N m, RMS error "
                 "rad): " + "; ".join(f"{k}: {v[0]:.4g}, {v[1]:.4g}" for k, v in points.items()) + "."
                 if points else ""), "",
             "```", format_frontier(result), "```", ""]
    if figures:
        from mjtraj.study.plots import frontier_figure

        folder = out.parent / (out.stem + "_figures")
        folder.mkdir(parents=True, exist_ok=True)
        shown = frontier_figure(result, folder / "frontier_paper_task.png", points=points, formats=formats)
        if shown is not None:
            lines += [f"![the weight frontier on the paper task]({folder.name}/{shown.name})", ""]
    return lines


DISPLACEMENT_BINS = (0.0, 0.5, 1.0, 1.5)
"""rad: the largest joint displacement's bins of the "where it pays" table."""
DURATION_BINS = (0.0, 0.7, 0.85, 1.0, 2.0)
"""s: the duration bins (the aggressive family spans 0.5 to 1 s; nominal moves take 2 s)."""


def _floors_section(data: SweepData) -> list[str]:
    """Each planner's reference on the paper task and its reverse: its execution under the first file's controller
    beside the clairvoyant floor of that reference (`mjtraj.study.fixed_tasks.task_floors`)."""
    from mjtraj.study.fixed_tasks import task_floors

    rows, why = task_floors(data.first)
    lines = ["## How well each reference can be executed: the floor", "",
             "The clairvoyant floor of a reference is the least J_exec any controller can score executing it on the "
             "nominal plant within the saturation, reaching the goal (docs/floor.md): how well the reference can be "
             "executed at best. Beside it, the first file's controller's execution (its first controller variant, "
             "native gravity compensation) on the paper task and its reverse.", ""]
    if not rows:
        return lines + [f"Not computed: {why}.", ""]
    lines += ["| motion | planner | J_exec of its execution | floor of its reference | J / floor |",
              "|---|---|---|---|---|"]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['task']} | {r['planner']} | not computed: {r['error']} | - | - |")
            continue
        cost, floor = float(r["cost"]), float(r["floor"])  # type: ignore[arg-type]
        note = "" if r["status"] == "ok" else f" ({r['status']})"
        lines.append(f"| {r['task']} | {r['planner']} | {cost:.4g}{note} | {floor:.4g} | {cost / floor:.3f} |")
    return lines + [""]


def _where_it_pays(data: SweepData) -> list[str]:
    """J_exec of cubic over the optimal planner's, per condition and bin of displacement and duration: above 1 (the
    whole interval) is where control-aware planning pays."""
    lines = ["## Where control-aware planning pays", "",
             "Paired ratio mean(J_exec cubic) / mean(J_exec optimal) [95 % bootstrap interval] and the share of "
             "scenarios the optimal planner wins, per bin of the largest joint displacement and of the duration. "
             f"Above 1 is where it pays; bins with fewer than {MIN_SCENARIOS} scenarios are left out.", "",
             "| condition | bin | scenarios | cubic / optimal | optimal wins |", "|---|---|---|---|---|"]
    rows = 0
    for c in data.conditions:
        if not (data.has(c, "optimal") and data.has(c, "cubic")):
            continue
        move, duration = data.values(c, "optimal", "max_displacement"), data.values(c, "optimal", "duration")
        for label, values, edges, unit in (("max abs(dq)", move, DISPLACEMENT_BINS, "rad"),
                                           ("T", duration, DURATION_BINS, "s")):
            for low, high in zip(edges[:-1], edges[1:], strict=True):
                mask = (values > low) & (values <= high)
                if mask.sum() < MIN_SCENARIOS:
                    continue
                r = paired_ratio(data.values(c, "cubic", "cost")[mask], data.values(c, "optimal", "cost")[mask])
                if r.count < MIN_SCENARIOS:
                    continue
                lines.append(f"| {c} | {label} in ({low:g}, {high:g}] {unit} | {r.count} | {_fmt_ratio(r)} | "
                             f"{100 * r.win_rate:.0f} % |")
                rows += 1
    return lines + ([] if rows else ["| (not measured: optimal and cubic are both needed) | | | | |"]) + [""]


def _min_effort(data: SweepData) -> list[str]:
    lines = [
        "## The minimum-effort reference", "",
        "For a gravity-compensated arm with constant inertia D (so C = 0), the plant is D q'' = u. A reference "
        "q(t) tracked exactly needs u = D q''(t), so its effort is E = integral of u^T R u dt = integral of "
        "q''^T (D R D) q'' dt. Rest to rest (q(0) = q0, q(T) = qg, q'(0) = q'(T) = 0), the Euler-Lagrange "
        "equation of this integrand is (D R D) q'''' = 0: every joint follows a cubic polynomial, and the "
        "boundary conditions make it the cubic planner's q0 + dq (3 s^2 - 2 s^3), whatever D and R are. Its "
        "effort is 12 dq^T (D R D) dq / T^3; the quintic's is 120/7 = 17.14 (1.43 times, so 1.195 times the RMS "
        "torque), the trapezoid's with V = 1.5 dq/T is 13.5 (1.125 times, 1.061 in RMS). So on such an arm "
        "claim 5 is a theorem, and no planner that moves along the straight joint path needs less L2 "
        "feedforward effort than the cubic.", "",
        "That bound holds only under its assumptions: constant inertia, effort measured as the L2 norm of the "
        "torque, and the straight joint-space path. The UR5's inertia varies with the pose and couples the joints, "
        "so a reference that leaves the straight path (folding the elbow to cut the inertia the big joints move) "
        "can need less torque than the cubic; the true bound is the minimum-effort reference of the nonlinear "
        "dynamics within the joint ranges and speed limits: the `nonlinear_min_effort` planner (below, when the sweep "
        "ran it). Nor is L1 effort (Int. dtau) minimised by the cubic.", "",
        "The paper's optimal planner minimises a different objective: it adds the state weight Q, which pays for "
        "being away from the goal at every step. That pulls the motion forward and costs effort. With Q = 0 its "
        "QP is the discrete minimum-effort problem of its own linear model (the `min_effort` variant): for the "
        "constant-inertia linear model that is the cubic's torque held over each period, the zero-order-held "
        "cubic, which tracks with the same effort and less error than the sampled cubic (see `mjtraj frontier` at "
        "alpha = 0). How far the optimal planner's effort lies from it:", ""]
    rows = ["| condition | planned RMS u: optimal/min_effort | executed RMS dtau: optimal/min_effort | executed "
            "RMS dtau: cubic/min_effort |", "|---|---|---|---|"]
    for c in data.conditions:
        if data.has(c, "min_effort") and data.has(c, "optimal"):
            plan = paired_ratio(data.values(c, "optimal", "plan_effort"), data.values(c, "min_effort", "plan_effort"))
            run = paired_ratio(data.values(c, "optimal", "rms_dtau"), data.values(c, "min_effort", "rms_dtau"))
            cub = paired_ratio(data.values(c, "cubic", "rms_dtau"), data.values(c, "min_effort", "rms_dtau")) \
                if data.has(c, "cubic") else None
            rows.append(f"| {c} | {_fmt_ratio(plan)} | {_fmt_ratio(run)} | {_fmt_ratio(cub) if cub else '-'} |")
    lines += (rows if len(rows) > 2 else ["(not measured: add `min_effort` to the sweep's planners)"]) + [""]
    return lines + _effort_left(data)


BOUND = "nonlinear_min_effort"
"""The planner whose executed effort is the study's effort bound."""


def _effort_left(data: SweepData) -> list[str]:
    """Every planner's executed RMS dtau over the nonlinear effort bound's, paired by scenario."""
    lines = ["## Effort left on the table", "",
             f"`{BOUND}` is the least corrective effort with which the nominal nonlinear arm makes each move within "
             "its joint ranges, the pi rad/s speed limit and the torque bound (the paper's objective with Q = 0, "
             "solved on the MuJoCo model itself). Each cell is mean(planner's executed RMS dtau) / mean(the "
             f"bound's), paired by scenario, with a 95 % bootstrap interval: 1 means no effort left to save.", ""]
    names = (*CLASSICAL, "scurve", "optimal", "min_effort", "nonlinear_optimal")
    rows = []
    for c in data.conditions:
        if not data.has(c, BOUND):
            continue
        bound = data.values(c, BOUND, "rms_dtau")
        present = [p for p in names if data.has(c, p)]
        rows.append((c, present, [paired_ratio(data.values(c, p, "rms_dtau"), bound) for p in present],
                     int(np.sum(np.isfinite(bound)))))
    if not rows:
        return lines[:2] + [f"(not measured: add `{BOUND}` to the sweep's planners; it plans in about 0.07 s: "
                            "1,000 nominal scenarios take about a minute on two cores)", ""]
    for c, present, ratios, count in rows:
        lines += [f"{c} ({count} scenarios with a bound):", "", "| " + " | ".join(present) + " |",
                  "|" + "---|" * len(present), "| " + " | ".join(_fmt_ratio(r) for r in ratios) + " |", ""]
    return lines


METRIC_LABELS = {"rms_err": "RMS tracking error", "int_dtau": "integral of |corrective torque|",
                 "cost": "executed cost J_exec"}
"""Plain names of the metrics the audit's figures draw."""


def _figures(data: SweepData, out: Path, formats: Sequence[str] = ("png",)) -> list[str]:
    import matplotlib

    from mjtraj.study.plots import planner_color, save_figure

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = out.parent / (out.stem + "_figures")
    folder.mkdir(parents=True, exist_ok=True)
    written: set[str] = set()
    lines = ["## Figures", ""]
    for c in data.conditions:
        if not data.has(c, "optimal") or c.family in TASKS:  # one motion: no distribution to draw
            continue
        present = [p for p in data.planners if p != "optimal" and data.has(c, p)]
        fig, axes = plt.subplots(1, 3, figsize=(12, 4.2))
        for ax, metric in zip(axes, ("rms_err", "int_dtau", "cost"), strict=True):
            ratios = []
            for p in present:
                r = data.values(c, p, metric) / data.values(c, "optimal", metric)
                ratios.append(r[np.isfinite(r) & (r > 0)])
            boxes = ax.boxplot(ratios, showfliers=False, patch_artist=True)
            for box, p in zip(boxes["boxes"], present, strict=True):
                box.set_facecolor(planner_color(p))
                box.set_alpha(0.6)
            ax.set_xticks(range(1, len(present) + 1), present, rotation=30, fontsize=9)
            ax.axhline(1.0, color="k", lw=0.8, ls="--")
            ax.set_yscale("log")
            ax.set_ylabel(f"{METRIC_LABELS[metric]}, planner / optimal (log)", fontsize=9)
            ax.set_title(METRIC_LABELS[metric], fontsize=10)
        fig.suptitle(str(c), fontsize=9)
        fig.tight_layout()
        slug = re.sub(r"[^A-Za-z0-9]+", "_", c.weights).strip("_")
        name = f"ratios_{slug + '_' if slug else ''}{c.family}_{c.ff_accel}_{c.gravity_comp}.png"
        paths = save_figure(fig, folder / name, formats, dpi=150)
        plt.close(fig)
        written.update(path.name for path in paths)
        lines.append(f"![{c}]({folder.name}/{paths[0].name})")
    for stale in folder.glob("ratios_*"):  # the figures of an earlier audit into the same file
        if stale.name not in written:
            stale.unlink()
    return lines + [""]


def _definitions(data: SweepData) -> list[str]:
    """How the paper's columns read against our metric definitions, with the arithmetic."""
    p = PAPER_TABLE
    o = p["optimal"]
    lines = [
        "## The paper's columns and our definitions", "",
        "Our metrics (docs/design.md): `rms_dtau` is the RMS over every joint and period; `rms_dtau_norm` the RMS over "
        "periods of the torque vector's norm (sqrt(n) times `rms_dtau`); `rms_tau_total` the RMS of the total torque "
        "G(q) + dtau; `int_dtau` the sum over joints and periods of |dtau| dt, the paper's J_dtau.", "",
        "| paper column | reads as | arithmetic from its Table I |", "|---|---|---|"]
    for name in ("cubic", "quintic", "trapezoidal"):
        row = p[name]
        from_int = 100 * (row["int_dtau"] - o["int_dtau"]) / row["int_dtau"]
        from_rms = 100 * (row["rms_dtau"] - o["rms_dtau"]) / row["rms_dtau"]
        lines.append(f"| dtau Red. ({name}) = {row['dtau_red']} % | the reduction of Int. dtau (L1), not of RMS dtau | "
                     f"Int.: 100 ({row['int_dtau']} - {o['int_dtau']}) / {row['int_dtau']} = {from_int:.2f} %; RMS: "
                     f"{from_rms:.2f} % |")
    for name, stated in (("cubic", 22), ("quintic", 50), ("trapezoidal", 73)):
        row = p[name]
        as_reduction = 100 * (row["rms_err"] - o["rms_err"]) / row["rms_err"]
        as_increase = 100 * (row["rms_err"] - o["rms_err"]) / o["rms_err"]
        lines.append(f"| RMS error \"increased by approximately {stated} %\" ({name}) | a reduction relative to "
                     f"{name}, worded as an increase | 100 ({row['rms_err']:.4g} - {o['rms_err']:.4g}) / "
                     f"{row['rms_err']:.4g} = {as_reduction:.1f} %; as an increase over optimal: {as_increase:.1f} % |")
    paper_ratio = [p[k]["int_dtau"] / (2.0 * 3 * p[k]["rms_dtau"])
                   for k in ("optimal", "cubic", "quintic", "trapezoidal")]
    lines += ["", "Int. dtau / (T n RMS) is the mean |dtau| over the RMS: near 0.8 for these smooth torques when the "
              "RMS is over every joint and period. The paper's Table I gives "
              f"{min(paper_ratio):.2f} to {max(paper_ratio):.2f} (T = 2 s, n = 3). The same ratio with the norm-based "
              "RMS (`rms_dtau_norm`, sqrt(n) times larger) comes close to the paper's range, which suggests its RMS "
              "dtau is of the torque vector's norm. Ours, per condition (median over scenarios):",
              "", "| condition | planner | Int. dtau / (T n rms_dtau) | Int. dtau / (T n rms_dtau_norm) |",
              "|---|---|---|---|"]
    for c in data.conditions:
        for planner in data.planners:
            if not data.has(c, planner):
                continue
            integral, rms_value = data.values(c, planner, "int_dtau"), data.values(c, planner, "rms_dtau")
            norm, T = data.values(c, planner, "rms_dtau_norm"), data.values(c, planner, "duration")
            ours = integral / (T * 3 * rms_value)
            by_norm = integral / (T * 3 * norm)
            if np.isfinite(ours).any():
                lines.append(f"| {c} | {planner} | {np.nanmedian(ours):.3f} | {np.nanmedian(by_norm):.3f} |")
    return lines + [""]


def _paper_note() -> list[str]:
    p = PAPER_TABLE
    return ["## Where we differ from the paper", "",
            "The paper reports one motion (its Table I: optimal RMS error "
            f"{p['optimal']['rms_err']:.3e} rad, Int. dtau {p['optimal']['int_dtau']} N m s, cost "
            f"{p['optimal']['cost']}; reductions {p['cubic']['dtau_red']}, {p['quintic']['dtau_red']}, "
            f"{p['trapezoidal']['dtau_red']} % of Int. dtau and {p['cubic']['cost_red']}, "
            f"{p['quintic']['cost_red']}, {p['trapezoidal']['cost_red']} % of cost). The verdicts above are what "
            "our plant, controller and stated rules give over many motions; where a verdict reads 'does not "
            "hold', our results contradict the paper's claim under that condition. `mjtraj compare` reproduces "
            "the single paper motion.", ""]
