"""Sweep backends: a bad backend or an unreachable Ray cluster fails before any file is written; Ray gives the
local rows."""


from __future__ import annotations

import pytest

from mjtraj.exceptions import BackendError, InvalidInputError
from mjtraj.study.runner import run_sweep
from mjtraj.study.sweep import SweepSettings

SMALL = dict(scenarios=6, batch=3, planners=("optimal", "cubic"))



def test_bad_backend_and_unreachable_ray(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^backend: unknown value 'dask'; valid: local, ray$"):
        run_sweep(SweepSettings(**SMALL), tmp_path / "a.csv", backend="dask", progress=False)
    pytest.importorskip("ray")
    with pytest.raises(BackendError, match=r"^ray_address: cannot reach a Ray cluster at 127.0.0.1:9 \("):
        run_sweep(SweepSettings(**SMALL), tmp_path / "b.csv", backend="ray", ray_address="127.0.0.1:9",
                  progress=False)
    assert not (tmp_path / "b.csv").exists()



@pytest.mark.slow
def test_ray_backend_gives_the_local_rows(tmp_path):
    pytest.importorskip("ray")
    settings = SweepSettings(**SMALL)
    run_sweep(settings, tmp_path / "local.csv", workers=1, progress=False)
    run_sweep(settings, tmp_path / "ray.csv", backend="ray", workers=2, progress=False)
    assert (tmp_path / "ray.csv").read_bytes() == (tmp_path / "local.csv").read_bytes()

