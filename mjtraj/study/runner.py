"""Run a sweep end to end: open (or resume) the results file, map the units over a backend, append as they come."""

from __future__ import annotations

import os
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mjtraj.exceptions import InvalidInputError, ProvenanceError
from mjtraj.study.backends import backend_map, check_backend
from mjtraj.study.cells import VERSION_COLUMNS
from mjtraj.study.store import ResultsFile
from mjtraj.study.sweep import SweepSettings, UnitResult, columns, fixed_columns
from mjtraj.study.sweep_store import SweepStore, is_store_path
from mjtraj.versions import difference


@dataclass
class SweepReport:
    """What a run did: rows written now, units skipped as already done, statuses, and time per stage (s).

    `seconds` sums the stages over all units (CPU time of the workers); `wall` is the run's elapsed time.
    """

    path: Path
    rows: int = 0
    skipped_units: int = 0
    statuses: Counter[str] = field(default_factory=Counter)
    seconds: dict[str, float] = field(default_factory=dict)
    wall: float = 0.0


def run_sweep(settings: SweepSettings, out: str | os.PathLike[str], *, resume: bool = False, backend: str = "local",
              workers: int | None = None, ray_address: str | None = None, progress: bool = True) -> SweepReport:
    """Run (or continue, with `resume`) the sweep `settings` into `out`: a SQLite store when its suffix is one of
    `mjtraj.study.sweep_store.STORE_SUFFIXES` (.sqlite, .sqlite3, .db), else a CSV results file.

    Args:
      backend: 'local' (a process pool of `workers`, default all cores; 1 runs in this process) or 'ray'.
      ray_address: a Ray cluster (HOST:PORT, ray://HOST:PORT or 'auto'); None starts a local instance.

    Raises:
      ProvenanceError: `out` holds rows of another provenance (`mjtraj.versions.provenance`: versions, BLAS, CPU,
        commit) than this process's, or a worker's rows have another.
      InvalidInputError: unknown backend, or a file that cannot be resumed (see ResultsFile.open and
        SweepStore.open).
      BackendError: Ray missing or unreachable; raised before the file is touched.
    """
    check_backend(backend, ray_address)  # before the file is touched
    workers = (os.cpu_count() or 1) if workers is None else workers
    if workers < 1:
        raise InvalidInputError(f"workers: expected a whole number >= 1, got {workers!r}")
    units = settings.units()
    unit_rows = {unit: settings.unit_rows(unit) for unit in units}
    record = fixed_columns(settings)
    path = Path(out)
    fresh = not path.exists()
    opener = SweepStore.open if is_store_path(path) else ResultsFile.open
    results: SweepStore | ResultsFile = opener(path, columns(settings), record, unit_rows, resume=resume)
    report = SweepReport(path=path, skipped_units=len(results.done))
    todo = [unit for unit in units if unit not in results.done]
    bar = None
    if progress:
        from tqdm import tqdm

        total = sum(unit_rows[u] for u in units)
        bar = tqdm(total=total, initial=total - sum(unit_rows[u] for u in todo), unit="row", desc="sweep",
                   dynamic_ncols=True)
    start = time.perf_counter()
    try:
        for result in backend_map(backend, settings, todo, workers=workers, ray_address=ray_address):
            _check_provenance(result, record)
            results.append(result.rows)
            report.rows += len(result.rows)
            report.statuses.update(row["status"] for row in result.rows)
            for stage, seconds in result.seconds.items():
                report.seconds[stage] = report.seconds.get(stage, 0.0) + seconds
            if bar is not None:
                bar.update(len(result.rows))
                bar.set_postfix_str(", ".join(f"{k} {v}" for k, v in sorted(report.statuses.items())))
    except BaseException:
        if fresh and report.rows == 0:
            results.close()
            for leftover in (path, path.with_name(path.name + "-journal")):
                leftover.unlink(missing_ok=True)  # nothing but a header or a schema was written: leave nothing
        raise
    finally:
        results.close()
        if bar is not None:
            bar.close()
    report.wall = time.perf_counter() - start
    return report


def _check_provenance(result: UnitResult, record: dict[str, Any]) -> None:
    """ProvenanceError if a worker computed `result` under another provenance than this sweep's `record` (its fixed
    columns): a store holds rows of one provenance."""
    if result.rows:
        row = result.rows[0]
        changed = difference({k: str(row[k]) for k in VERSION_COLUMNS if k in row}, record)
        if changed:
            family, unit = result.unit
            raise ProvenanceError(f"sweep: unit {family} {unit} came back from a worker whose rows {changed}; every "
                                  f"worker must run mjtraj from the same commit with the same libraries, BLAS and CPU "
                                  f"model")


__all__ = ["SweepReport", "run_sweep"]
