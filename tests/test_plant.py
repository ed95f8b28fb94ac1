"""The plant: gravity compensation modes, and holding a pose."""


from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.planners import make
from mjtraj.core.reference import Reference


def realisable_reference(model, rng, steps=60, substeps=1):
    """Simulate the nominal plant under random torques; the samples are a reference it can follow exactly."""
    data = mujoco.MjData(model)
    data.qpos[:] = [0.2, -1.2, 0.6]
    u = rng.uniform(-20, 20, size=(steps, 3))
    q, qd = [data.qpos.copy()], [data.qvel.copy()]
    for k in range(steps):
        data.ctrl[:] = u[k]
        for _ in range(substeps):
            mujoco.mj_step(model, data)
        q.append(data.qpos.copy())
        qd.append(data.qvel.copy())
    dt = model.opt.timestep * substeps
    return Reference("realisable", np.arange(steps + 1) * dt, np.array(q), np.array(qd),
                     np.zeros((steps + 1, 3)), u_plan=u)



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

