"""Packaging: the public names import, documented defaults match, and the wheel carries its data files."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import mjtraj

ROOT = Path(__file__).resolve().parents[1]



def test_all_names_import():
    for name in mjtraj.__all__:
        assert getattr(mjtraj, name) is not None



def test_documented_loop_defaults_match_design():
    """DESIGN §3 defaults: feedforward inverse, sample acceleration, native gravity comp, no anti-windup."""
    import dataclasses

    from mjtraj.core.closed_loop import LoopConfig

    defaults = {f.name: f.default for f in dataclasses.fields(LoopConfig) if f.default is not dataclasses.MISSING}
    assert defaults == {"feedforward": "inverse", "ff_accel": "sample", "gravity_comp": "native",
                        "anti_windup": "none", "substeps": 1, "divergence_bound": pytest.approx(3.141592653589793),
                        "delay": 0}



@pytest.mark.slow
def test_wheel_contains_model_and_scenario(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True, capture_output=True)
    wheel = next(tmp_path.glob("mjtraj-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    assert "mjtraj/assets/ur5_3dof.xml" in names
    assert "mjtraj/scenarios/paper.toml" in names
    assert "mjtraj/py.typed" in names
    assert not any(n.startswith(("envs/", "tests/")) for n in names)

