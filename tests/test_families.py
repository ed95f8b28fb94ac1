"""Scenario families: seeded draws, and a perturbed plant that reproduces the nominal one when unperturbed."""


from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.planners import make
from mjtraj.domain.families import Perturbation, draw_scenario, perturbed_plant, plant_fields


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


def test_the_heaviest_payload_of_a_weak_arm_is_one_it_can_hold_and_the_ur5s_range_is_unchanged(model, tmp_path):
    """Oracle: MuJoCo's own bias force of the arm carrying that payload (`with_point_mass`) at the workspace poses:
    holding it takes at most HOLD_FRACTION of a joint's saturation, exactly that on the binding joint."""
    from arm_suite import THREE, chain

    from mjtraj.core.gains import workspace_poses
    from mjtraj.core.model import JointInfo
    from mjtraj.core.payload import with_point_mass
    from mjtraj.domain.families import HOLD_FRACTION, PAYLOAD_MASS, arm_scales
    from mjtraj.domain.scenario import scenario_for_model

    assert arm_scales(model)[0] == 1.0  # the UR5 holds more than its range: its draws are unchanged
    path = tmp_path / "weak.xml"
    path.write_text(chain("weak", THREE))
    weak = scenario_for_model(path, torque_limit=5.0).model
    scale, _ = arm_scales(weak)
    mass = scale * PAYLOAD_MASS[1]
    assert mass < float(np.sum(weak.body_mass[1:])) / 17.05 * PAYLOAD_MASS[1]  # the cap binds on this arm
    loaded = with_point_mass(weak, mass)
    limit = JointInfo.of(weak).torque_limit
    worst = np.zeros(weak.nv)
    for q in workspace_poses(weak, weak.qpos0, weak.qpos0):
        torque = []
        for m in (weak, loaded):
            data = mujoco.MjData(m)
            data.qpos[:] = q
            mujoco.mj_forward(m, data)
            torque.append(data.qfrc_bias.copy())
        worst = np.maximum(worst, np.abs(torque[1] - torque[0]))
    assert np.all(worst <= HOLD_FRACTION * limit * (1 + 1e-9))
    assert np.max(worst / limit) == pytest.approx(HOLD_FRACTION, rel=1e-6)


def test_the_drawn_damping_and_friction_add_to_the_arms_own_and_the_ur5s_plants_are_the_draws(model, tmp_path):
    """A file's own joint damping and friction stay in its mismatch plants (they had been replaced by the draws, so
    an arm integrated implicitly for its stiff damping lost it and diverged); the UR5 declares none, so its plants'
    fields are the draws bit for bit."""
    from arm_suite import THREE, chain

    from mjtraj.domain.scenario import scenario_for_model

    draw = draw_scenario("mismatch", 0, 3, model, 0.02).perturbation
    fields = plant_fields(perturbed_plant(model), [draw])
    assert np.array_equal(fields["dof_damping"][0], draw.damping)
    assert np.array_equal(fields["dof_frictionloss"][0], draw.friction)
    path = tmp_path / "damped.xml"
    path.write_text(chain("damped", THREE, joint_extra=' damping="20" frictionloss="1"'))
    arm = scenario_for_model(path, workspace=True)
    plant = perturbed_plant(arm.model, str(path))
    other = draw_scenario("mismatch", 0, 3, arm.model, 0.02).perturbation
    fields = plant_fields(plant, [other])
    np.testing.assert_array_equal(fields["dof_damping"][0], 20.0 + other.damping)
    np.testing.assert_array_equal(fields["dof_frictionloss"][0], 1.0 + other.friction)
