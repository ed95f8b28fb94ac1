"""The batched dynamics probe against MuJoCo's own mj_inverse and mj_forward."""


from __future__ import annotations

import copy

import mujoco
import numpy as np

from mjtraj.core.dynamics import DynamicsProbe
from mjtraj.core.model import default_model_path


def test_probe_matches_mj_inverse_and_mj_forward(model, rng):
    q, qd, qdd = rng.uniform(-3, 3, (50, 3)), rng.uniform(-2, 2, (50, 3)), rng.uniform(-5, 5, (50, 3))
    probe = DynamicsProbe(model, size=7)  # several chunks
    ff, acc = probe.inverse(q, qd, qdd), probe.accelerations(q, qd, qdd)
    data = mujoco.MjData(model)
    for k in range(50):
        data.qpos[:], data.qvel[:], data.qacc[:] = q[k], qd[k], qdd[k]
        mujoco.mj_inverse(model, data)
        np.testing.assert_allclose(ff[k], data.qfrc_inverse - data.qfrc_gravcomp, rtol=1e-12, atol=1e-11)
        data.ctrl[:] = qdd[k]
        mujoco.mj_forward(model, data)
        assert np.array_equal(acc[k], data.qacc)



def test_a_serial_probe_gives_the_batched_probes_bits_and_sees_model_edits(model, rng):
    """The serial probe (one MjData, state after state) and the Batch probe agree bit for bit on every query; the
    serial one reads the model at each call, so an edit of a parameter is seen."""
    q, qd, u = rng.uniform(-3, 3, (40, 3)), rng.uniform(-2, 2, (40, 3)), rng.uniform(-5, 5, (40, 3))
    serial, batched = DynamicsProbe(model, size=9, serial=True), DynamicsProbe(model, size=9)
    for name, args in (("accelerations", (q, qd, u)), ("inverse", (q, qd, u)), ("gravity", (q,))):
        assert np.array_equal(getattr(serial, name)(*args), getattr(batched, name)(*args)), name
    for a, b in zip(serial.mass_and_bias(q, qd), batched.mass_and_bias(q, qd), strict=True):
        assert np.array_equal(a, b)
    heavier = mujoco.MjModel.from_xml_path(str(default_model_path()))
    probe = DynamicsProbe(heavier, size=4, serial=True)
    before = probe.gravity(q[:4])
    heavier.body_mass[2] *= 2.0
    assert not np.array_equal(probe.gravity(q[:4]), before)


def test_terms_past_a_joint_limit_are_those_of_the_full_model(model, rng):
    """The batched terms run on a copy without contacts and constraints: past a joint limit, where the full model
    has an active limit (its forward accelerations feel it), D, bias, passive and gravity forces are still the full
    model's, bit for bit (the serial probe runs the full model)."""
    q, qd = rng.uniform(-3, 3, (20, 3)), rng.uniform(-2, 2, (20, 3))
    q[:, 2] = np.where(np.arange(20) % 2 == 0, 1.0, -1.0) * (model.jnt_range[2, 1] + rng.uniform(0.05, 0.5, 20))
    serial, batched = DynamicsProbe(model, size=6, serial=True), DynamicsProbe(model, size=6)
    free = copy.copy(model)
    free.jnt_limited[:] = 0
    zero = np.zeros_like(q)
    within = np.abs(q[:, 2]) < model.jnt_range[2, 1]
    assert not within.any()
    limited, unlimited = serial.accelerations(q, qd, zero), DynamicsProbe(free, size=6).accelerations(q, qd, zero)
    assert np.all(np.abs(limited - unlimited).max(axis=1) > 1e-6)  # the limit acts on every one of these states
    for a, b in zip(serial.mass_and_bias(q, qd), batched.mass_and_bias(q, qd), strict=True):
        assert np.array_equal(a, b)
    assert np.array_equal(serial.inverse(q, qd, qd), batched.inverse(q, qd, qd))
    assert np.array_equal(serial.gravity(q), batched.gravity(q))
