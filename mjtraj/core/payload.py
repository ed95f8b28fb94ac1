"""Where an arm carries a payload (its flange), and the nominal model with a point mass added there: the mismatch
family's payload and the adaptive law's payload regressor use the one rule."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
from numpy.typing import NDArray

FLANGE_SITE = "attachment_site"
FLANGE_RULE = (f"the payload sits at the site {FLANGE_SITE!r} if the arm has one, else at the centre of mass of the "
               f"last joint's body; the links whose mass and inertia are scaled are the bodies the joints move")
PAYLOAD_RADIUS = 0.05
"""m; the payload's inertia is that of a solid sphere."""


def flange(model: mujoco.MjModel) -> tuple[int, NDArray[np.float64]]:
    """FLANGE_RULE's body id and point (in that body's frame, m, shape (3,)) of `model`."""
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, FLANGE_SITE)
    if site >= 0:
        return int(model.site_bodyid[site]), model.site_pos[site].copy()
    last = int(model.jnt_bodyid[model.njnt - 1])
    return last, model.body_ipos[last].copy()


def with_point_mass(model: mujoco.MjModel, mass: float) -> mujoco.MjModel:
    """A copy of `model` whose flange body also carries a solid sphere of `mass` kg and radius PAYLOAD_RADIUS
    centred on the flange point (FLANGE_RULE): the body's mass, centre of mass and principal inertia combined by
    the parallel-axis theorem. Its dynamics equal those of the mismatch plant (`perturbed_plant`, a separate body
    welded there) with that payload; gravity compensation fields are left as they are (read qfrc_bias, not
    qfrc_gravcomp, for the payload's weight)."""
    out = copy.copy(model)
    body, point = flange(model)
    m, c = float(model.body_mass[body]), model.body_ipos[body]
    rotation = np.empty(9)
    mujoco.mju_quat2Mat(rotation, model.body_iquat[body])
    R = rotation.reshape(3, 3)
    total = m + mass
    centre = (m * c + mass * point) / total

    def shifted(offset: NDArray[np.float64], weight: float) -> NDArray[np.float64]:
        return weight * (offset @ offset * np.eye(3) - np.outer(offset, offset))

    inertia = (R @ np.diag(model.body_inertia[body]) @ R.T + shifted(c - centre, m)
               + 0.4 * mass * PAYLOAD_RADIUS**2 * np.eye(3) + shifted(point - centre, mass))
    principal, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, axes.reshape(-1))
    out.body_mass[body] = total
    out.body_ipos[body] = centre
    out.body_inertia[body] = principal
    out.body_iquat[body] = quat
    return out
