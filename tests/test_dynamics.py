"""The batched dynamics probe against MuJoCo's own mj_inverse and mj_forward."""


from __future__ import annotations

import mujoco
import numpy as np

from mjtraj.core.dynamics import DynamicsProbe


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

