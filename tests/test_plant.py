"""The plant: gravity compensation modes, holding a pose, per-simulation fields set later, pickling."""


from __future__ import annotations

import copy
import dataclasses
import pickle

import numpy as np
import pytest

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.planners import make
from mjtraj.core.plant import BatchPlant
from mjtraj.core.reference import Reference
from mjtraj.domain.families import draw_perturbation, perturbed_plant, plant_fields


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



def _fields(plant, seed, count):
    rng = np.random.default_rng(seed)
    return plant_fields(plant, [draw_perturbation(rng, 3) for _ in range(count)])


def _drive(plant, steps=40):
    """Step `plant` under a fixed torque sequence; the positions after each step, (steps, nsim, n)."""
    out = []
    for k in range(steps):
        plant.step(np.full((plant.nsim, 3), 5.0 * np.sin(0.3 * k)))
        out.append(plant.qpos.copy())
    return np.array(out)


@pytest.mark.parametrize("nsim", [1, 3])
def test_set_fields_on_some_simulations_equals_building_with_them(model, nsim):
    """Fields set later on a subset (an env's next episode) give the same plant as fields given at construction."""
    plant_model = perturbed_plant(model)
    first, second = _fields(plant_model, 1, nsim), _fields(plant_model, 2, nsim)
    ids = np.arange(nsim)[-1:]  # only the last simulation gets the second draw
    expected = {name: values.copy() for name, values in first.items()}
    for name, values in second.items():
        expected[name][ids] = values[ids]
    built = BatchPlant(plant_model, nsim, nominal=model, fields=expected)
    later = BatchPlant(plant_model, nsim, nominal=model, fields=first)
    later.set_fields({name: values[ids] for name, values in second.items()}, ids)
    q0 = np.tile([0.3, -1.0, 0.8], (nsim, 1))
    for p in (built, later):
        p.reset(q0, np.zeros((nsim, 3)))
    np.testing.assert_array_equal(_drive(built), _drive(later))
    unchanged = BatchPlant(plant_model, nsim, nominal=model, fields=first)  # and the second draw did change it
    unchanged.reset(q0, np.zeros((nsim, 3)))
    later.reset(q0, np.zeros((nsim, 3)))
    assert not np.array_equal(_drive(unchanged)[:, ids], _drive(later)[:, ids])


@pytest.mark.parametrize("nsim", [1, 3])
@pytest.mark.parametrize("gravity_comp", ["native", "zoh"])
def test_a_plant_pickles_and_copies_mid_run_bit_for_bit(model, nsim, gravity_comp):
    """mujoco's Batch cannot be pickled; a BatchPlant can, with its fields and state, and goes on identically."""
    plant_model = perturbed_plant(model)
    plant = BatchPlant(plant_model, nsim, nominal=model, gravity_comp=gravity_comp,
                       fields=_fields(plant_model, 4, nsim))
    plant.reset(np.tile([0.3, -1.0, 0.8], (nsim, 1)), np.zeros((nsim, 3)))
    _drive(plant, 17)
    clones = [pickle.loads(pickle.dumps(plant)), copy.deepcopy(plant)]
    expected = _drive(plant)
    for clone in clones:
        np.testing.assert_array_equal(_drive(clone), expected)
