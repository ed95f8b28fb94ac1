"""Sweep backends: a bad backend or an unreachable Ray cluster fails before any file is written; Ray gives the
local rows. Ray is in the `test` extra (.ci/run installs it, and its declared floor in the floors run), so these
tests import it plainly: a missing Ray fails them instead of skipping."""


from __future__ import annotations

import multiprocessing
import os

import pytest

from mjtraj.exceptions import BackendError, InvalidInputError
from mjtraj.study.runner import run_sweep
from mjtraj.study.sweep import SweepSettings

SMALL = dict(scenarios=6, batch=3, planners=("optimal", "cubic"))



def test_bad_backend_and_unreachable_ray(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^backend: unknown value 'dask'; valid: local, ray$"):
        run_sweep(SweepSettings(**SMALL), tmp_path / "a.csv", backend="dask", progress=False)
    with pytest.raises(BackendError, match=r"^ray_address: cannot reach a Ray cluster at 127.0.0.1:9 \("):
        run_sweep(SweepSettings(**SMALL), tmp_path / "b.csv", backend="ray", ray_address="127.0.0.1:9",
                  progress=False)
    assert not (tmp_path / "b.csv").exists()



def _blas_threads() -> str | None:
    import os

    return os.environ.get("OPENBLAS_NUM_THREADS")


@pytest.mark.slow
def test_pool_workers_get_one_blas_thread_unless_the_user_chose(monkeypatch):
    from concurrent.futures import ProcessPoolExecutor

    from mjtraj.study.backends import _one_blas_thread

    context = multiprocessing.get_context("spawn")
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    with ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
        with _one_blas_thread():
            future = pool.submit(_blas_threads)
            assert os.environ["MKL_NUM_THREADS"] == "3"  # the user's choice stands
        assert future.result() == "1"
    assert "OPENBLAS_NUM_THREADS" not in os.environ and os.environ["MKL_NUM_THREADS"] == "3"  # restored


@pytest.mark.slow
def test_ray_backend_gives_the_local_rows(tmp_path):
    settings = SweepSettings(**SMALL)
    run_sweep(settings, tmp_path / "local.csv", workers=1, progress=False)
    run_sweep(settings, tmp_path / "ray.csv", backend="ray", workers=2, progress=False)
    assert (tmp_path / "ray.csv").read_bytes() == (tmp_path / "local.csv").read_bytes()



def _stored_units(path):
    """(family, unit) of every unit the store holds, with repeats, or [] while it does not exist yet."""
    import sqlite3

    if not path.exists():
        return []
    try:
        with sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True) as connection:
            return connection.execute("SELECT family, unit FROM units").fetchall()
    except sqlite3.Error:  # created but not yet holding its tables
        return []


@pytest.mark.slow
def test_a_ray_cluster_that_loses_a_node_mid_sweep_stores_every_unit_once(tmp_path):
    """A two-node Ray cluster on this machine (Ray's own test cluster): the sweep goes through --ray-address, the
    worker node is killed once the store holds its first units, and the store ends with every unit exactly once,
    row for row the local run's."""
    import threading
    import time

    import ray
    from ray.cluster_utils import Cluster

    from mjtraj.cli import main
    from mjtraj.study.store import read_rows

    settings = SweepSettings(scenarios=60, batch=2, planners=("optimal", "cubic", "quintic"))
    run_sweep(settings, tmp_path / "local.sqlite", workers=1, progress=False)
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    worker = cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    store = tmp_path / "ray.sqlite"
    seen: dict[str, int] = {}

    def kill_the_worker_once_units_arrive() -> None:
        deadline = time.time() + 300
        while time.time() < deadline and len(_stored_units(store)) < 2:
            time.sleep(0.02)
        seen["before"] = len(_stored_units(store))
        cluster.remove_node(worker, allow_graceful=False)
        seen["after"] = len(_stored_units(store))

    killer = threading.Thread(target=kill_the_worker_once_units_arrive)
    killer.start()
    try:
        code = main(["sweep", "--scenarios", "60", "--batch", "2", "--planners", "optimal,cubic,quintic",
                     "--backend", "ray", "--ray-address", cluster.address, "--no-progress", "--out", str(store)])
        killer.join()
    finally:
        ray.shutdown()
        cluster.shutdown()
    units = settings.units()
    assert code == 0 and 2 <= seen["before"] and seen["after"] < len(units)  # the node died mid-sweep
    stored = _stored_units(store)
    assert sorted(stored) == sorted(units)  # every unit, exactly once
    assert read_rows(store) == read_rows(tmp_path / "local.sqlite")


def _children(pid):
    """Live child processes of `pid` (from /proc)."""
    import os

    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = open(f"/proc/{entry}/stat").read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                out.append(int(entry))
    return out


@pytest.mark.slow
@pytest.mark.skipif(not __import__("os").path.isdir("/proc"), reason="reads /proc (Linux)")
def test_pool_workers_end_with_their_sweep(tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import time

    proc = subprocess.Popen([sys.executable, "-m", "mjtraj", "sweep", "--scenarios", "4000", "--batch", "50",
                             "--workers", "2", "--no-progress", "--out", str(tmp_path / "s.csv")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and len(_children(proc.pid)) < 3:  # two workers and the resource tracker
        time.sleep(0.1)
    workers = _children(proc.pid)
    assert len(workers) >= 2
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    deadline = time.time() + 10
    while time.time() < deadline and any(os.path.exists(f"/proc/{w}") and
                                         open(f"/proc/{w}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"
                                         for w in workers):
        time.sleep(0.2)
    assert not [w for w in workers if os.path.exists(f"/proc/{w}") and
                open(f"/proc/{w}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"]
