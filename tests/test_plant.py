"""The plant: gravity compensation modes, and holding a pose."""


from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.planners import make
from mjtraj.core.reference import Reference


def test_zoh_differs_from_native_on_a_moving_arm(model, scenario, task):
    ref = make("cubic").plan(task, model)
    native = ClosedLoop(model, scenario.loop).run([ref])
    zoh = ClosedLoop(model, dataclasses.replace(scenario.loop, gravity_comp="zoh")).run([ref])
    gap = np.max(np.abs(native.e - zoh.e))
    assert 1e-5 < gap < 0.05


@pytest.mark.parametrize("mode", ["native", "zoh"])
def test_holding_a_pose(model, scenario, mode):
    """A constant reference at a loaded pose: gravity compensation alone holds it (no correction needed)."""
    pose = np.array([0.3, -0.4, 1.2])
    ref = Reference("hold", np.arange(51) * 0.02, np.tile(pose, (51, 1)), np.zeros((51, 3)), np.zeros((51, 3)))
    rollout = ClosedLoop(model, dataclasses.replace(scenario.loop, gravity_comp=mode)).run([ref])
    assert np.max(np.abs(rollout.e)) < 1e-12
    assert np.max(np.abs(rollout.dtau)) < 1e-9

