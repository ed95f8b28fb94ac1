"""Analytic Jacobians of one control period (the model's RK4 step) from the derivatives of the forward dynamics
(Carpentier and Mansard, 2018), for the nonlinear planners' `Shooting` problems.

`Shooting` differences the step: 3n perturbed MuJoCo steps per sample, about 11 ms per iterate on one core at
N = 100, n = 3. Here the acceleration a, da/dq, da/dv and M^-1 at the 4 N stage states of RK4
(`mjtraj.core.planners.tree_dynamics`, compiled; one call per stage over all N samples) and the chain rule through
the four stages give A_k = dx_{k+1}/dx_k and B_k = dx_{k+1}/du_k exactly (about 1 ms; 1.8 ms with a call of
Pinocchio's computeABADerivatives per state, which gives the same values to 1e-11, tested). The tree is Pinocchio's
model built from the MjModel's own arrays (`RigidBody.of`): the bodies, hinge axes and inertias, armature and
damping, and gravity as MuJoCo applies it after gravity compensation. Every evaluation checks that this RK4 step
reproduces the rollout MuJoCo made, sample by sample, within TRANSITION_TOL; where it does not (a joint pressed on
the end of its range, a clamped actuator force, any force the conversion leaves out), `RigidBody.jacobians` returns
None and the caller differences MuJoCo's step. So every Jacobian used is one of the plant's own transition.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.core.model import control_range
from mjtraj.core.planners.tree_dynamics import HingeTree

TRANSITION_TOL = 1e-9
"""The tree's RK4 step must give MuJoCo's next state within this, times (1 + |x|), in every component."""
CURVATURE_STEP = 1e-6
"""The relative forward-difference step of `RigidBody.curvature` (its error is of this order; rounding's of 1e-10)."""


@dataclass(frozen=True)
class RigidBody:
    """A hinge-joint tree of `mujoco.MjModel` as Pinocchio models it, with MuJoCo's input map and damping.

    Attributes:
      tree: the joints, frames and inertias of Pinocchio's model, for `mjtraj.core.planners.tree_dynamics`.
      qpos0: MuJoCo's reference angles (n,), rad: Pinocchio's angle is qpos - qpos0.
      actuation: the joint torque per control (n, nu), N m per unit: gear times gain.
      ctrl_low, ctrl_high: each control's range (nu,), -inf/inf where unlimited (MuJoCo clamps ctrl to it).
      damping: each joint's viscous damping (n,), N m s/rad.
      timestep: the RK4 step, s.
      frictionloss: each joint's dry friction (n,), N m, applied as MuJoCo's solver applies it while the joint
        slides, -frictionloss sign(qd) (while it sticks the step does not reproduce MuJoCo's, and the caller
        differences that sample); zero unless made with plant_forces.
      gravity: where the bodies' gravity compensation differs (plant_forces only), a tree of the same joints whose
        bodies weigh m_b (1 - gravcomp_b), whose `HingeTree.gravity` is the torque gravity takes, and `tree` then
        carries no gravity; None where `tree`'s uniform gravity holds it.
    """

    tree: HingeTree
    qpos0: NDArray[np.float64]
    actuation: NDArray[np.float64]
    ctrl_low: NDArray[np.float64]
    ctrl_high: NDArray[np.float64]
    damping: NDArray[np.float64]
    timestep: float
    frictionloss: NDArray[np.float64] | None = None
    gravity: HingeTree | None = None

    @classmethod
    def of(cls, model: mujoco.MjModel, *, plant_forces: bool = False) -> RigidBody | None:
        """`model` as Pinocchio models it, or None where the conversion does not hold it (see `unsupported`).

        plant_forces: also hold dry friction and gravity compensation that differs between bodies (the forces of
        the benchmark's mismatched plants, for the floor's solves). Without it such models are not held, and the
        planners' and `mpc`'s Jacobians of the models they plan on are what they were."""
        if unsupported(model, plant_forces=plant_forces) is not None:
            return None
        body, weight, moment = _built(model)
        per_body = (plant_forces and model.nbody > 1 and np.ptp(model.body_gravcomp[1:]) > 0.0
                    and not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY)
        if per_body:
            body.gravity.linear[:] = 0.0
        actuation = np.zeros((model.nv, model.nu))
        actuation[model.jnt_dofadr[model.actuator_trnid[:, 0]], np.arange(model.nu)] = (model.actuator_gear[:, 0]
                                                                                         * model.actuator_gainprm[:, 0])
        joints = range(1, body.njoints)
        frames = (np.array([body.parents[j] - 1 for j in joints]),
                  np.array([body.jointPlacements[j].rotation for j in joints]),
                  np.array([body.jointPlacements[j].translation for j in joints]),
                  np.array([body.joints[j].extract().axis for j in joints]))
        tree = HingeTree(*frames, np.array([body.inertias[j].mass for j in joints]),
                         np.array([body.inertias[j].lever for j in joints]),
                         np.array([body.inertias[j].inertia for j in joints]), np.array(body.armature),
                         np.array(body.gravity.linear))
        gravity = None
        if per_body:  # a weightless body's lever is never used: its first moment is zero
            lever = np.divide(moment, weight[:, None], out=np.zeros_like(moment), where=weight[:, None] != 0.0)
            gravity = HingeTree(*frames, weight, lever, np.zeros((model.nv, 3, 3)), np.zeros(model.nv),
                                np.array(model.opt.gravity))
        friction = model.dof_frictionloss.copy() if plant_forces and np.any(model.dof_frictionloss != 0.0) else None
        return cls(tree, model.qpos0.copy(), actuation, *control_range(model), model.dof_damping.copy(),
                   float(model.opt.timestep), friction, gravity)

    def jacobians(self, X: NDArray[np.float64], U: NDArray[np.float64]
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """A_k (N, 2n, 2n) and B_k (N, 2n, nu) of the RK4 step at each (x_k, u_k) of the rollout X (N+1, 2n) under U
        (N, nu), or None where the tree's step misses MuJoCo's X[k+1] by more than TRANSITION_TOL. A control outside
        its range has no effect (MuJoCo clamps it), one on its end the effect from inside."""
        A, B, reproduced = self.jacobians_where(X, U)
        return (A, B) if np.all(reproduced) else None

    def jacobians_where(self, X: NDArray[np.float64], U: NDArray[np.float64]
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """`jacobians` sample by sample: (A, B, reproduced (N,)), A_k and B_k valid where reproduced[k], where the
        tree's step gives MuJoCo's X[k+1] within TRANSITION_TOL."""
        after, jacobian = self.step(X[:-1], U)
        reproduced = np.all(np.abs(after - X[1:]) <= TRANSITION_TOL * (1.0 + np.abs(X[1:])), axis=1)
        n = self.qpos0.size
        return jacobian[:, :, :2 * n], jacobian[:, :, 2 * n:], reproduced

    def step(self, x: NDArray[np.float64], U: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The tree's RK4 step from each state x (M, 2n) under U (M, nu) and its Jacobian: (x' (M, 2n),
        dx'/d(x, u) (M, 2n, 2n + nu)). No check against MuJoCo (see `jacobians`)."""
        return self.tree.rk4(x, U, qpos0=self.qpos0, actuation=self.actuation, ctrl_low=self.ctrl_low,
                             ctrl_high=self.ctrl_high, damping=self.damping, frictionloss=self.frictionloss,
                             timestep=self.timestep, held_by=self.gravity)

    def curvature(self, x: NDArray[np.float64], U: NDArray[np.float64], p: NDArray[np.float64],
                  jacobian: NDArray[np.float64]) -> NDArray[np.float64]:
        """The Hessian of p_k^T x'(x_k, u_k), the step's next state weighted by p (M, 2n), in z = (x, u) at each
        (x_k, u_k) (x (M, 2n), U (M, nu)), given the step's Jacobian there (M, 2n, 2n + nu; `step`'s): shape
        (M, 2n + nu, 2n + nu). Forward differences of the analytic Jacobian, step CURVATURE_STEP (1 + |z_i|)
        (backward for a control that would pass its upper end, where MuJoCo clamps it), all M (2n + nu) perturbed
        points in one batched `step`; symmetrised."""
        z = np.concatenate([x, U], axis=1)
        steps, width = z.shape
        n = self.qpos0.size
        delta = CURVATURE_STEP * (1.0 + np.abs(z))  # (M, width)
        delta[:, 2 * n:] *= np.where(U + delta[:, 2 * n:] > self.ctrl_high, -1.0, 1.0)
        moved = (z[:, None, :] + delta[:, :, None] * np.eye(width)[None]).reshape(-1, width)
        _, moved_jacobian = self.step(moved[:, :2 * n], moved[:, 2 * n:])
        pulled = np.einsum("mab,ma->mb", jacobian, p)  # J^T p at each point, (M, width)
        moved_pulled = np.einsum("miab,ma->mib", moved_jacobian.reshape(steps, width, 2 * n, width), p)
        hessian = (moved_pulled - pulled[:, None, :]) / delta[:, :, None]  # row i: d(J^T p)/dz_i
        return 0.5 * (hessian + hessian.transpose(0, 2, 1))  # type: ignore[no-any-return]


def unsupported(model: mujoco.MjModel, *, plant_forces: bool = False) -> str | None:
    """Why `RigidBody.of` does not hold `model`, or None: it needs the RK4 integrator, one hinge joint per moving body,
    motors on joints (fixed gain, no bias or dynamics), one gravity compensation for every body, and no joint
    stiffness, dry friction or fluid forces (plant_forces: gravity compensation may differ and dry friction act)."""
    if model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4:
        return "the integrator is not RK4"
    if (model.njnt != model.nv or model.nu != model.nv or np.any(model.jnt_type != mujoco.mjtJoint.mjJNT_HINGE)
            or np.any(model.body_jntnum > 1)):
        return "a joint is not a hinge, a body has more than one, or the controls are not one per joint"
    if (np.any(model.actuator_trntype != mujoco.mjtTrn.mjTRN_JOINT)
            or np.any(model.actuator_dyntype != mujoco.mjtDyn.mjDYN_NONE)
            or np.any(model.actuator_gaintype != mujoco.mjtGain.mjGAIN_FIXED)
            or np.any(model.actuator_biastype != mujoco.mjtBias.mjBIAS_NONE)):
        return "an actuator is not a motor on a joint"
    if not plant_forces and model.nbody > 1 and np.ptp(model.body_gravcomp[1:]) > 0.0:
        return "the bodies' gravity compensation differs"
    if np.any(model.jnt_stiffness != 0.0) or (not plant_forces and np.any(model.dof_frictionloss != 0.0)):
        return "a joint has stiffness or dry friction"
    if model.opt.density != 0.0 or model.opt.viscosity != 0.0 or np.any(model.opt.wind != 0.0):
        return "the medium exerts fluid forces"
    return None


def pinocchio_model(model: mujoco.MjModel) -> Any:
    """Pinocchio's model of the hinge tree `model` (one `unsupported` holds): the bodies, hinge axes and inertias
    (welded bodies lumped into their joint's), armature, and gravity as MuJoCo applies it after gravity compensation;
    Pinocchio's angles are qpos - qpos0. Damping and the input map are left to the caller (`RigidBody`)."""
    return _built(model)[0]


def _built(model: mujoco.MjModel) -> tuple[Any, NDArray[np.float64], NDArray[np.float64]]:
    """(`pinocchio_model`, then each joint's weight under gravity compensation: sum over the bodies moving with it
    of m_b (1 - gravcomp_b) (n,), kg, and of m_b (1 - gravcomp_b) c_b, c_b the body's centre of mass in the
    joint's frame (n, 3), kg m)."""
    import pinocchio as pin  # here, not at import: only the nonlinear planners need it (0.1 to 0.2 s)
    body = pin.Model()
    joint_of = {0: 0}  # MuJoCo body -> the Pinocchio joint it moves with
    frame_of = {0: pin.SE3.Identity()}  # MuJoCo body frame in that joint's frame
    weight, moment = np.zeros(model.nv + 1), np.zeros((model.nv + 1, 3))
    for b in range(1, model.nbody):
        parent = int(model.body_parentid[b])
        in_parent = frame_of[parent] * _pose(pin, model.body_quat[b], model.body_pos[b])
        if model.body_jntnum[b] == 0:  # welded to its parent
            joint_of[b], frame_of[b] = joint_of[parent], in_parent
        else:
            j = int(model.body_jntadr[b])
            offset = np.array(model.jnt_pos[j], dtype=np.float64)
            joint_of[b] = body.addJoint(joint_of[parent], pin.JointModelRevoluteUnaligned(model.jnt_axis[j].copy()),
                                        in_parent * pin.SE3(np.eye(3), offset), f"joint{j}")
            frame_of[b] = pin.SE3(np.eye(3), -offset)
        rotation = _pose(pin, model.body_iquat[b], np.zeros(3)).rotation
        inertia = rotation @ np.diag(model.body_inertia[b]) @ rotation.T
        body.appendBodyToJoint(joint_of[b], pin.Inertia(float(model.body_mass[b]), model.body_ipos[b].copy(),
                                                        inertia), frame_of[b])
        weighed = float(model.body_mass[b]) * (1.0 - float(model.body_gravcomp[b]))
        weight[joint_of[b]] += weighed
        moment[joint_of[b]] += weighed * frame_of[b].act(np.array(model.body_ipos[b], dtype=np.float64))
    gravity = np.zeros(3)
    if not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY:
        gravity = (1.0 - float(model.body_gravcomp[1:].max(initial=0.0))) * model.opt.gravity
    body.gravity.linear[:] = gravity
    body.armature[:] = model.dof_armature
    return body, weight[1:], moment[1:]


def _pose(pin: Any, quaternion: NDArray[np.float64], position: NDArray[np.float64]) -> Any:
    """Pinocchio's SE3 of MuJoCo's (w, x, y, z) quaternion and position."""
    w, x, y, z = (float(c) for c in quaternion)
    return pin.SE3(pin.Quaternion(w, x, y, z).normalized().toRotationMatrix(), np.array(position, dtype=np.float64))
