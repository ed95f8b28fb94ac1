"""The nonlinear planners' analytic step Jacobians (Pinocchio's ABA derivatives chained through RK4) against MuJoCo's
own step: its rollout (the transition) and its central differences (the derivatives)."""

import mujoco
import numpy as np
import pytest

from mjtraj.core.model import load_model
from mjtraj.core.planners.rigid_body import TRANSITION_TOL, RigidBody, unsupported
from mjtraj.core.planners.shooting import Shooting

# A tree that exercises every part of the conversion: joints off their body's origin, unaligned axes, reference
# angles (qpos0), a welded body, rotated principal inertias, armature, damping, gears and gains, partial gravity
# compensation shared by every body, a limited and an unlimited control.
TREE = """
<mujoco>
  <option timestep="0.01" integrator="RK4" gravity="0.3 -0.2 -9.81"/>
  <worldbody>
    <body name="a" pos="0.1 0 0.2" quat="0.9 0.1 0.3 0.2" gravcomp="0.25">
      <joint name="j0" type="hinge" axis="0.2 0.3 1" pos="0.02 0.01 0" ref="0.3" damping="0.4" armature="0.05"/>
      <inertial pos="0.05 0.02 0.1" quat="0.8 0.2 0.1 0.4" mass="2.0" diaginertia="0.03 0.02 0.01"/>
      <body name="b" pos="0.3 0 0.1" quat="0.7 0.7 0 0" gravcomp="0.25">
        <joint name="j1" type="hinge" axis="1 0 0.2" pos="0 0.03 0" ref="-0.5" damping="0.1"/>
        <inertial pos="0.15 0 0.02" quat="1 0 0.3 0" mass="1.5" diaginertia="0.02 0.015 0.005"/>
        <body name="welded" pos="0.3 0.05 0" gravcomp="0.25">
          <inertial pos="0.02 0 0" mass="0.7" diaginertia="0.002 0.002 0.001"/>
          <body name="c" pos="0.05 0 0" quat="0.9 0 0 0.4" gravcomp="0.25">
            <joint name="j2" type="hinge" axis="0 1 0" armature="0.02"/>
            <inertial pos="0.1 0.01 0" mass="0.8" diaginertia="0.004 0.003 0.002"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="j0" gear="2" ctrlrange="-20 20"/>
    <general joint="j1" gainprm="1.5" ctrllimited="false"/>
    <motor joint="j2" ctrlrange="-5 5"/>
  </actuator>
</mujoco>
"""


def rollout(model, x0, U):
    """MuJoCo's states (N+1, 2n) from x0 under U (N, nu)."""
    data = mujoco.MjData(model)
    n = model.nv
    data.qpos[:], data.qvel[:] = x0[:n], x0[n:]
    X = [x0]
    for u in U:
        data.ctrl[:] = u
        mujoco.mj_step(model, data)
        X.append(np.concatenate([data.qpos, data.qvel]))
    return np.array(X)


def central_differences(model, x, u, eps=1e-6):
    """d(step)/d(x, u) at (x, u) by central differences of mj_step, shape (2n, 2n + nu)."""
    n = model.nv

    def step(z):
        return rollout(model, z[:2 * n], z[None, 2 * n:])[1]

    z = np.concatenate([x, u])
    return np.stack([(step(z + eps * e) - step(z - eps * e)) / (2 * eps) for e in np.eye(z.size)], axis=1)


def check_against_mujoco(model, X, U, samples):
    A, B = RigidBody.of(model).jacobians(X, U)
    for k in samples:
        numeric = central_differences(model, X[k], U[k])
        analytic = np.concatenate([A[k], B[k]], axis=1)
        np.testing.assert_allclose(analytic, numeric, rtol=1e-6, atol=1e-7 * np.abs(numeric).max())


def test_the_shipped_arms_step_jacobians_are_mujocos_central_differences(rng):
    model = load_model()
    U = rng.uniform(-20.0, 20.0, (30, 3))
    X = rollout(model, np.array([0.3, -1.2, 0.5, 0.5, -0.4, 0.2]), U)
    assert np.all(np.abs(X[:, 2]) < np.pi - 0.1)  # the elbow keeps off its range's ends
    check_against_mujoco(model, X, U, samples=(0, 11, 29))


def test_a_general_tree_converts_exactly(rng):
    """Offsets, reference angles, a welded body, armature, damping, gears and gains: Pinocchio's RK4 step is
    MuJoCo's to TRANSITION_TOL (else jacobians would be None) and its derivatives are MuJoCo's."""
    model = mujoco.MjModel.from_xml_string(TREE)
    assert unsupported(model) is None
    U = rng.uniform(-4.0, 4.0, (25, 3))
    X = rollout(model, np.array([0.2, -0.1, 0.4, 1.0, -2.0, 0.5]), U)
    check_against_mujoco(model, X, U, samples=(0, 12, 24))


def test_a_control_outside_its_range_has_no_effect_and_one_on_its_end_the_effect_from_inside(rng):
    model = load_model()
    U = rng.uniform(-30.0, 30.0, (10, 3))
    U[3, 0], U[5, 1] = 75.0, 60.0  # beyond the upper end (clamped), on it
    X = rollout(model, np.zeros(6), U)
    _, B = RigidBody.of(model).jacobians(X, U)
    np.testing.assert_array_equal(B[3, :, 0], 0.0)
    inside = U.copy()
    inside[5, 1] = 60.0 - 1e-6
    step = (rollout(model, X[5], U[5:6])[1] - rollout(model, X[5], inside[5:6])[1]) / 1e-6  # backward difference
    np.testing.assert_allclose(B[5, :, 1], step, rtol=1e-4, atol=1e-8)


def test_a_joint_on_its_range_end_falls_back_to_mujocos_differences():
    """A range limit's constraint force is not in Pinocchio's model: the transition check refuses the analytic
    Jacobians and the problem differences MuJoCo's step instead (counted)."""
    model = load_model()
    model.jnt_range[1] = (-0.2, 0.2)
    model.jnt_limited[1] = True
    U = np.tile([0.0, 40.0, 0.0], (20, 1))  # drives joint 1 into its upper end
    X = rollout(model, np.zeros(6), U)
    assert X[:, 1].max() > 0.2  # the limit is engaged (soft constraint)
    assert RigidBody.of(model).jacobians(X, U) is None
    problem = Shooting(model, X[0], X[-1], np.zeros((6, 6)), np.eye(3), 20, 1e-7)
    A, B = problem.jacobians(X, U)
    differenced = problem.differenced(X, U)
    np.testing.assert_array_equal(A, differenced[0])
    np.testing.assert_array_equal(B, differenced[1])
    assert problem.jacobian_counts == {"analytic": 0, "differenced": 1}


def test_a_missed_transition_is_refused_by_the_tolerance(rng):
    model = load_model()
    U = rng.uniform(-30.0, 30.0, (10, 3))
    X = rollout(model, np.zeros(6), U)
    rigid = RigidBody.of(model)
    assert rigid.jacobians(X, U) is not None
    X[7, 4] += 10 * TRANSITION_TOL * (1.0 + abs(X[7, 4]))
    assert rigid.jacobians(X, U) is None


@pytest.mark.parametrize(("change", "reason"), [
    (lambda m: setattr(m.opt, "integrator", mujoco.mjtIntegrator.mjINT_EULER), "the integrator is not RK4"),
    (lambda m: m.jnt_stiffness.__setitem__(0, 1.0), "a joint has stiffness or dry friction"),
    (lambda m: m.dof_frictionloss.__setitem__(2, 0.1), "a joint has stiffness or dry friction"),
    (lambda m: m.body_gravcomp.__setitem__(2, 0.5), "the bodies' gravity compensation differs"),
    (lambda m: m.actuator_biastype.__setitem__(0, mujoco.mjtBias.mjBIAS_AFFINE), "an actuator is not a motor on a "
                                                                                   "joint"),
    (lambda m: setattr(m.opt, "viscosity", 0.1), "the medium exerts fluid forces"),
])
def test_what_the_conversion_does_not_hold_is_named_and_differenced(change, reason):
    model = load_model()
    change(model)
    assert unsupported(model) == reason
    assert RigidBody.of(model) is None



@pytest.mark.slow
def test_every_arm_of_the_suite_converts_exactly_or_is_declined_with_its_reason(tmp_path):
    """The arms users bring (tests/arm_suite.py), as `load_model` prepares them: where the conversion holds a model,
    a short motion from the middle of its ranges keeps Pinocchio's step equal to MuJoCo's and its Jacobians equal to
    MuJoCo's central differences; where it does not, `unsupported` names why (here: dry friction, or a stiff damping
    that the arm's preparation integrates implicitly)."""
    from arm_suite import write_suite

    held, declined = [], {}
    for name, path, refusal in write_suite(tmp_path):
        if refusal is not None:
            continue
        model = load_model(path)
        reason = unsupported(model)
        if reason is not None:
            declined[name] = reason
            continue
        limit = np.abs(model.actuator_ctrlrange[:, 1])
        U = 0.01 * limit * np.sin(np.arange(12)[:, None] + np.arange(model.nu)[None, :])
        middle = np.where(model.jnt_limited.astype(bool), model.jnt_range.mean(axis=1), model.qpos0)
        X = rollout(model, np.concatenate([middle, np.zeros(model.nv)]), U)
        check_against_mujoco(model, X, U, samples=(0, 11))
        held.append(name)
    assert len(held) >= 10
    assert set(declined.values()) <= {"a joint has stiffness or dry friction", "the integrator is not RK4"}, declined
    assert declined.get("maker_heavy_damping_light_links") == "the integrator is not RK4"


@pytest.mark.parametrize("which", ["tree", "shipped"])
def test_the_compiled_dynamics_and_derivatives_are_pinocchios(which, rng):
    """tree_dynamics (the compiled Newton-Euler passes with forward-mode tangents) against Pinocchio's own
    computeABADerivatives, the oracle, at random states and torques of the general tree and the shipped arm."""
    import pinocchio as pin

    from mjtraj.core.planners.rigid_body import pinocchio_model

    model = mujoco.MjModel.from_xml_string(TREE) if which == "tree" else load_model()
    body, n = pinocchio_model(model), model.nv
    data = body.createData()
    q, qd, tau = rng.uniform(-3.0, 3.0, (40, n)), rng.uniform(-4.0, 4.0, (40, n)), rng.uniform(-30.0, 30.0, (40, n))
    computed = RigidBody.of(model).tree.derivatives(q, qd, tau)
    for k in range(len(q)):
        da_dq, da_dqd, inverse_mass = (np.array(a) for a in pin.computeABADerivatives(body, data, q[k], qd[k], tau[k]))
        for mine, oracle in zip(computed, (data.ddq, da_dq, da_dqd, inverse_mass), strict=True):
            np.testing.assert_allclose(mine[k], oracle, rtol=1e-11, atol=1e-11 * (1.0 + np.abs(oracle).max()))


@pytest.mark.slow
def test_the_steps_curvature_is_mujocos_second_differences(rng):
    """RigidBody.curvature (forward differences of the analytic Jacobian) against the Hessian of p^T step(z) by second
    differences of MuJoCo's own step, on the general tree: central ones, and at a sample whose control sits on its
    upper end (MuJoCo clamps beyond it) one-sided ones taken from inside."""
    model = mujoco.MjModel.from_xml_string(TREE)
    n = model.nv
    U = rng.uniform(-4.0, 4.0, (6, 3))
    U[4, 2] = 5.0  # j2's control on its upper end
    X = rollout(model, np.array([0.2, -0.1, 0.4, 1.0, -2.0, 0.5]), U)
    p = rng.normal(size=(6, 2 * n))
    rigid = RigidBody.of(model)
    curvature = rigid.curvature(X[:-1], U, p, rigid.step(X[:-1], U)[1])
    eye = np.eye(3 * n)
    for k in (0, 4, 5):
        z = np.concatenate([X[k], U[k]])

        def value(dz, k=k, z=z):
            return float(p[k] @ rollout(model, (z + dz)[:2 * n], (z + dz)[None, 2 * n:])[1])

        if k != 4:
            h = 1e-4
            numeric = np.array([[value(h * (a + b)) - value(h * (a - b)) - value(h * (b - a)) + value(-h * (a + b))
                                 for b in eye] for a in eye]) / (4 * h * h)
            rtol = 1e-4
        else:
            h = 1e-5
            inward = np.where(np.arange(3 * n) == 2 * n + 2, -1.0, 1.0)[:, None] * eye  # -u for the clamped control
            numeric = np.array([[value(h * (a + b)) - value(h * a) - value(h * b) + value(0.0 * a) for b in inward]
                                for a in inward]) / (h * h)
            numeric *= np.outer(np.diag(inward), np.diag(inward))  # back to derivatives in +z
            rtol = 1e-3
        np.testing.assert_allclose(curvature[k], numeric, rtol=rtol, atol=rtol * 0.1 * np.abs(numeric).max())
