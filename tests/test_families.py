"""Scenario families: seeded draws, and a perturbed plant that reproduces the nominal one when unperturbed."""


from __future__ import annotations

import mujoco
import numpy as np

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.planners import make
from mjtraj.study.families import Perturbation, draw_scenario, perturbed_plant, plant_fields


def test_unperturbed_plant_reproduces_the_nominal_one(model, scenario):
    """The payload body and per-simulation fields change nothing when the perturbation is the identity."""
    ref = make("cubic").plan(scenario.task, model)
    identity = Perturbation(0.0, np.ones(3), np.ones(3), np.zeros(3), np.zeros(3))
    plant = perturbed_plant(model)
    nominal = ClosedLoop(model, scenario.loop, nsim=2).run([ref, ref])
    perturbed = ClosedLoop(model, scenario.loop, nsim=2, plant=plant,
                           plant_fields=plant_fields(plant, [identity, identity])).run([ref, ref])
    np.testing.assert_allclose(perturbed.q, nominal.q, atol=1e-12)
    heavy = Perturbation(5.0, np.ones(3), np.ones(3), np.zeros(3), np.zeros(3))
    sagging = ClosedLoop(model, scenario.loop, nsim=1, plant=plant,
                         plant_fields=plant_fields(plant, [heavy])).run([ref])
    assert np.abs(sagging.e).max() > 10 * np.abs(nominal.e).max()
    assert model.nbody == 4  # the nominal model is untouched


def test_mismatch_scenarios_are_seeded(model):
    a, b = draw_scenario("mismatch", 3, 17, model, 0.02), draw_scenario("mismatch", 3, 17, model, 0.02)
    assert np.array_equal(a.task.q0, b.task.q0) and a.perturbation.payload == b.perturbation.payload
    assert 0 <= a.perturbation.payload <= 5 and np.all(np.abs(a.task.displacement) <= 1.5)
    c = draw_scenario("aggressive", 3, 17, model, 0.02)
    assert 0.5 <= c.task.duration <= 1.0



def test_the_payload_sits_at_the_flange(model):
    """The payload's centre of mass is the flange site itself, in every pose (it once sat 0.45 m beyond it: an
    unset inertial position is placed at the body's offset a second time)."""
    plant = perturbed_plant(model)
    data = mujoco.MjData(plant)
    for q in ([0.3, -1.0, 0.8], [-2.0, -0.4, 2.1], [0.0, -1.5707963267948966, 0.0]):
        data.qpos[:] = q
        mujoco.mj_forward(plant, data)
        np.testing.assert_allclose(data.xipos[plant.body("mjtraj_payload").id],
                                   data.site_xpos[plant.site("attachment_site").id], atol=1e-12)
