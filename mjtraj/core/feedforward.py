"""Feedforward torque from the nominal model: ID(q_ref, qd_ref, qdd_ref) - G(q_ref), as mj_inverse computes it, and the
model's dry friction while the reference moves."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import choice
from mjtraj.core.dynamics import DynamicsProbe
from mjtraj.core.reference import Reference
from mjtraj.exceptions import InvalidInputError

FEEDFORWARD_MODES = ("inverse", "planned", "none")
FEEDFORWARD_ACCEL = ("sample", "step_average")


def gravity(model: mujoco.MjModel, q: NDArray[np.float64]) -> NDArray[np.float64]:
    """G(q) of `model` at the poses q; shape (..., n) in, (..., n) out, N m."""
    poses = np.asarray(q, dtype=np.float64)
    flat = poses.reshape(-1, model.nv)
    return DynamicsProbe(model, size=flat.shape[0]).gravity(flat).reshape(poses.shape)


def feedforward_many(model: mujoco.MjModel, references: Sequence[Reference], *, mode: str = "inverse",
                     accel: str = "sample", probe: DynamicsProbe | None = None) -> NDArray[np.float64]:
    """Feedforward corrective torque of each reference for control periods k = 0..N-1; shape (N, B, n), N m.

    Args:
      references: B references of one length N.
      mode: 'inverse' = ID(q_ref,k, qd_ref,k, qdd_ref,k) - G(q_ref,k) on the nominal `model` (mj_inverse's
        qfrc_inverse - qfrc_gravcomp without constraint forces) + frictionloss sign(qd_ref,k), the model's dry
        friction while the reference moves (Coulomb compensation); 'planned' = the planner's own u_plan; 'none' = 0.
      accel: qdd_ref,k used by 'inverse': 'sample' = qdd_ref(t_k), 'step_average' = (qd_ref,k+1 - qd_ref,k)/dt,
        the acceleration a zero-order-held torque produces over the period.
      probe: a DynamicsProbe of `model` to evaluate on (one is made if None).
    """
    choice("feedforward", mode, FEEDFORWARD_MODES)
    choice("ff_accel", accel, FEEDFORWARD_ACCEL)
    N, n = references[0].steps, references[0].n
    B = len(references)
    if mode == "none":
        return np.zeros((N, B, n))
    if mode == "planned":
        for ref in references:
            if ref.u_plan is None:
                raise InvalidInputError(f"feedforward: mode 'planned' needs a planner that publishes u_plan; "
                                        f"the {ref.planner!r} reference has none; valid for it: inverse, none")
        return np.stack([ref.u_plan for ref in references if ref.u_plan is not None], axis=1)
    q = np.stack([ref.q[:N] for ref in references], axis=1)
    qd = np.stack([ref.qd[:N] for ref in references], axis=1)
    qdd = reference_accelerations(references, accel)
    probe = DynamicsProbe(model, size=N * B) if probe is None else probe
    torque = probe.inverse(q.reshape(-1, n), qd.reshape(-1, n), qdd.reshape(-1, n)).reshape(N, B, n)
    friction = model.dof_frictionloss
    if np.any(friction != 0.0):  # the model's dry friction while the reference moves (none on the UR5: its bits)
        torque = torque + friction * np.sign(qd)
    return torque


def feedforward(model: mujoco.MjModel, reference: Reference, *, mode: str = "inverse",
                accel: str = "sample") -> NDArray[np.float64]:
    """`feedforward_many` for one reference; shape (N, n), N m."""
    return feedforward_many(model, [reference], mode=mode, accel=accel)[:, 0]


def reference_accelerations(references: Sequence[Reference], accel: str) -> NDArray[np.float64]:
    """qdd_ref,k of each reference for k = 0..N-1 by the ff_accel rule, shape (N, B, n), rad/s^2: 'sample' =
    qdd_ref(t_k), 'step_average' = (qd_ref,k+1 - qd_ref,k)/dt."""
    N = references[0].steps
    if accel == "sample":
        return np.stack([ref.qdd[:N] for ref in references], axis=1)
    return np.stack([np.diff(ref.qd, axis=0) / np.diff(ref.t)[:, None] for ref in references], axis=1)
