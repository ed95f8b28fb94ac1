"""The plant model against its parameter table (docs/ur5_model.md), closed forms and Pinocchio."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjtraj.core.feedforward import gravity
from mjtraj.core.gains import mass_matrix
from mjtraj.core.model import JointInfo, default_model_path, load_model
from mjtraj.exceptions import ModelError

# --- the parameter table, typed in from ur5_params.md (the oracle; nothing read from the MJCF) ---
DH = [(0.0, 0.089159, np.pi / 2), (-0.425, 0.0, 0.0), (-0.39225, 0.0, 0.0), (0.0, 0.10915, np.pi / 2),
      (0.0, 0.09465, -np.pi / 2), (0.0, 0.0823, 0.0)]                                    # (a, d, alpha)


MASS = [3.7, 8.393, 2.33, 1.219, 1.219, 0.1879]


COM = [(0, -0.02561, 0.00193), (0.2125, 0, 0.11336), (0.15, 0, 0.0265), (0, -0.0018, 0.01634),
       (0, 0.0018, 0.01634), (0, 0, -0.001159)]


CYL = [(0.075, 0.178, 1), (0.06, 0.425, 0), (0.06, 0.39225, 0), (0.06, 0.095, 1), (0.06, 0.085, 1),
       (0.0375, 0.0305, 2)]                                                                # (r, L, axis in frame i)


def dh(theta: float, a: float, d: float, alpha: float) -> np.ndarray:
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


def frames(q: np.ndarray) -> list[np.ndarray]:
    """DH frames 1..6 in the world with the wrist at zero."""
    theta = list(q) + [0.0, 0.0, 0.0]
    T, out = np.eye(4), []
    for (a, d, alpha), th in zip(DH, theta, strict=True):
        T = T @ dh(th, a, d, alpha)
        out.append(T)
    return out


def potential(q: np.ndarray) -> float:
    """sum m g z_com, from the table by DH forward kinematics."""
    return sum(m * 9.81 * (F[:3, :3] @ np.array(c) + F[:3, 3])[2] for m, c, F in zip(MASS, COM, frames(q), strict=True))


def cylinder(m: float, r: float, L: float, axis: int) -> np.ndarray:
    d = np.full(3, m * (3 * r * r + L * L) / 12)
    d[axis] = m * r * r / 2
    return np.diag(d)



def test_published_cylinder_inertias_match_the_table():
    published = [(0.014972, 0.010406, 0.014972), (0.015107, 0.133886, 0.133886), (0.004194, 0.031971, 0.031971),
                 (0.002014, 0.002194, 0.002014), (0.001831, 0.002194, 0.001831), (0.0000806, 0.0000806, 0.000132)]
    for m, (r, L, axis), p in zip(MASS, CYL, published, strict=True):
        np.testing.assert_allclose(np.diag(cylinder(m, r, L, axis)), p, atol=6e-7)



def test_lumped_forearm_matches_ur5_params(model):
    F3 = frames(np.zeros(3))[2]
    inv3 = np.linalg.inv(F3)
    mass, first, parts = 0.0, np.zeros(3), []
    for i in range(2, 6):
        F = inv3 @ frames(np.zeros(3))[i]
        R, p = F[:3, :3], F[:3, :3] @ np.array(COM[i]) + F[:3, 3]
        parts.append((MASS[i], p, R @ cylinder(MASS[i], *CYL[i]) @ R.T))
        mass += MASS[i]
        first += MASS[i] * p
    com = first / mass
    inertia = sum(I + m * ((p - com) @ (p - com) * np.eye(3) - np.outer(p - com, p - com)) for m, p, I in parts)
    # the values ur5_params.md states
    assert mass == pytest.approx(4.9559, abs=1e-12)
    np.testing.assert_allclose(com, [0.070522, -0.030446, 0.076945], atol=1e-6)
    np.testing.assert_allclose(inertia, [[0.028386, -0.010641, 0.017631], [-0.010641, 0.076381, 0.008116],
                                         [0.017631, 0.008116, 0.071830]], atol=2e-6)
    # and the model holds exactly this body (its frame is DH frame 2 turned by q3, i.e. DH frame 3 shifted by a3)
    body = model.body("forearm_link")
    assert body.mass[0] == pytest.approx(mass, abs=1e-9)
    np.testing.assert_allclose(body.ipos, com + [-0.39225, 0, 0], atol=1e-9)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, body.iquat)
    R = R.reshape(3, 3)
    np.testing.assert_allclose(R @ np.diag(body.inertia) @ R.T, inertia, atol=1e-9)



def test_mass_matrix_at_zero_matches_ur5_params(model):
    np.testing.assert_allclose(mass_matrix(model, np.zeros(3)),
                               [[3.500, 0.020, 0.020], [0.020, 3.353, 1.267], [0.020, 1.267, 0.589]], atol=6e-4)



def test_mass_matrix_symmetric_positive_definite(model, rng):
    joints = JointInfo.of(model)
    for q in rng.uniform(joints.lower, joints.upper, size=(200, 3)):
        D = mass_matrix(model, q)
        np.testing.assert_allclose(D, D.T, atol=1e-12)
        assert np.linalg.eigvalsh(D).min() > 1e-3



@pytest.mark.parametrize("q", [np.zeros(3), np.array([0.7, -1.1, 1.9])])
def test_gravity_equals_gradient_of_potential_from_the_table(model, q):
    h = 1e-6
    grad = [(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(3)]
    np.testing.assert_allclose(gravity(model, q), grad, atol=1e-6)



def test_gravity_at_zero_by_hand(model):
    """Arm horizontal: the shoulder carries every mass beyond it at its lever arm, the elbow the lumped forearm."""
    x = [(frames(np.zeros(3))[i][:3, :3] @ np.array(COM[i]) + frames(np.zeros(3))[i][:3, 3])[0] for i in range(6)]
    # joint 2 sits at x = 0, joint 3 at x = -0.425; torque about -y axis (z1 = -y): tau = sum m g x
    shoulder = sum(MASS[i] * 9.81 * x[i] for i in range(1, 6))
    elbow = sum(MASS[i] * 9.81 * (x[i] + 0.425) for i in range(2, 6))
    np.testing.assert_allclose(gravity(model, np.zeros(3)), [0.0, shoulder, elbow], atol=1e-9)
    assert shoulder == pytest.approx(-53.8, abs=0.1)  # "about 54 N m" in ur5_params.md



def test_inverse_dynamics_returns_applied_torque(model, rng):
    data = mujoco.MjData(model)
    joints = JointInfo.of(model)
    for _ in range(50):
        data.qpos[:] = rng.uniform(joints.lower / 2, joints.upper / 2)
        data.qvel[:] = rng.normal(size=3)
        data.ctrl[:] = rng.uniform(-60, 60, size=3)
        mujoco.mj_forward(model, data)
        applied = data.qfrc_actuator.copy()
        mujoco.mj_inverse(model, data)
        np.testing.assert_allclose(data.qfrc_inverse, applied, atol=1e-9)



def test_steps_five_seconds_under_random_torque_without_warnings(model, rng):
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    for _ in range(int(5.0 / model.opt.timestep)):
        data.ctrl[:] = rng.uniform(-60, 60, size=3)
        mujoco.mj_step(model, data)
    assert all(w.number == 0 for w in data.warning)
    assert np.all(np.isfinite(data.qpos))



def test_pinocchio_agrees(model, rng):
    import pinocchio as pin  # a test dependency (extra 'test'): a missing one fails, never skips

    pmodel = pin.buildModelFromMJCF(str(default_model_path()))
    pdata = pmodel.createData()
    data = mujoco.MjData(model)
    for _ in range(20):
        q, v, a = rng.uniform(-2, 2, 3), rng.normal(size=3), rng.normal(size=3)
        np.testing.assert_allclose(pin.crba(pmodel, pdata, q), mass_matrix(model, q), atol=1e-10)
        data.qpos[:], data.qvel[:], data.qacc[:] = q, v, a
        mujoco.mj_inverse(model, data)
        np.testing.assert_allclose(pin.rnea(pmodel, pdata, q, v, a), data.qfrc_inverse, atol=1e-10)



def test_missing_model_file(tmp_path):
    with pytest.raises(ModelError, match=r"^model file not found: .*nope\.xml \(a shipped arm is named without a "
                                         r"folder: planar_2link, ur5_3dof, ur5_6dof\)$"):
        load_model(tmp_path / "nope.xml")



def test_joint_info(model):
    joints = JointInfo.of(model)
    assert joints.names == ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint")
    np.testing.assert_array_equal(joints.torque_limit, [60, 60, 60])
    np.testing.assert_allclose(joints.upper, [2 * np.pi, 2 * np.pi, np.pi])

