"""Feedforward torque from the nominal model: ID(q_ref, qd_ref, qdd_ref) - G(q_ref) through mj_inverse."""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj._validate import choice
from mjtraj.exceptions import InvalidInputError
from mjtraj.reference import Reference

FEEDFORWARD_MODES = ("inverse", "planned", "none")
FEEDFORWARD_ACCEL = ("sample", "step_average")


def gravity(model: mujoco.MjModel, q: NDArray[np.float64], data: mujoco.MjData | None = None) -> NDArray[np.float64]:
    """G(q) of `model` at the poses q; shape (..., n) in, (..., n) out, N m."""
    data = mujoco.MjData(model) if data is None else data
    poses = np.asarray(q, dtype=np.float64)
    out = np.empty_like(poses)
    flat_in, flat_out = poses.reshape(-1, model.nv), out.reshape(-1, model.nv)
    for i, pose in enumerate(flat_in):
        data.qpos[:] = pose
        data.qvel[:] = 0.0
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_rne(model, data, 0, flat_out[i])
    return out


def feedforward(model: mujoco.MjModel, reference: Reference, *, mode: str = "inverse",
                accel: str = "sample") -> NDArray[np.float64]:
    """Feedforward corrective torque for control periods k = 0..N-1; shape (N, n), N m.

    Args:
      mode: 'inverse' = ID(q_ref,k, qd_ref,k, qdd_ref,k) - G(q_ref,k) by mj_inverse on the nominal `model`;
        'planned' = the planner's own u_plan; 'none' = 0.
      accel: qdd_ref,k used by 'inverse': 'sample' = qdd_ref(t_k), 'step_average' = (qd_ref,k+1 - qd_ref,k)/dt,
        the acceleration a zero-order-held torque produces over the period.
    """
    choice("feedforward", mode, FEEDFORWARD_MODES)
    choice("ff_accel", accel, FEEDFORWARD_ACCEL)
    N, n = reference.steps, reference.n
    if mode == "none":
        return np.zeros((N, n))
    if mode == "planned":
        if reference.u_plan is None:
            raise InvalidInputError(f"feedforward: mode 'planned' needs a planner that publishes u_plan; "
                                    f"the {reference.planner!r} reference has none; valid for it: inverse, none")
        return np.array(reference.u_plan)
    qdd = reference.qdd[:N] if accel == "sample" else np.diff(reference.qd, axis=0) / np.diff(reference.t)[:, None]
    data = mujoco.MjData(model)
    out = np.empty((N, n))
    for k in range(N):
        data.qpos[:] = reference.q[k]
        data.qvel[:] = reference.qd[k]
        data.qacc[:] = qdd[k]
        mujoco.mj_inverse(model, data)
        out[k] = data.qfrc_inverse - data.qfrc_gravcomp
    return out
