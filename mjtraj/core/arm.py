"""A user's MJCF arm prepared as mjtraj's plant, with `mujoco.MjSpec` (their file is never edited).

ARM_RULES states what is changed and what is kept. The shipped UR5 model already has this form; preparing it
changes nothing that the loop sees.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import positive
from mjtraj.exceptions import InvalidInputError, ModelError

ARM_RULES = (
    "a gripper's fingers (slide joints on a branch with no hinge below them) are held fixed at their 'home' "
    "keyframe's value, else at 0 within their range, and the equality constraints, fixed tendons and sensors that "
    "only concern them go with them (the held joints are named in the output); every other joint must be a hinge, "
    "with no tendons or equality constraints (an unnamed hinge is named jointK in "
    "mjtraj's copy); each hinge keeps its passive properties (damping, armature, friction loss) and range. The "
    "model's actuators are replaced by one torque motor per hinge (gear 1, set explicitly whatever the file's default"
    " class says) whose control range is the corrective saturation: the torque_limit given (--torque-limit: one value"
    " for every joint, or one per joint); else the torque an existing motor on that joint can apply (gear x gain x "
    "its control range, within gear x its force range), else gear x the force range of the actuator that drove it, "
    "else the joint's actuator force range, and never more than that range; sensors of the replaced actuators are "
    "removed and keyframes' ctrl set to zero; every body gets native gravity compensation (gravcomp 1, applied at the"
    " joints); contacts are disabled (the study's plant is the free arm); the integrator is RK4 at the control period"
    " dt, or implicitfast where the file's joint damping would make RK4 diverge at that period (damping x dt / "
    "inertia above 2, RK4's limit being 2.785; the output says so)")


HELD_TEXT = "mjtraj_held"
"""The name of the custom text element in which a prepared arm lists the joints it holds (`held_joints`)."""


def _finger(joint: mujoco.MjsJoint) -> bool:
    """A slide joint on a branch of its own: no hinge on its body or below it (a gripper's finger, not the arm)."""
    if joint.type != mujoco.mjtJoint.mjJNT_SLIDE:
        return False
    below = joint.parent.find_all(mujoco.mjtObj.mjOBJ_JOINT)
    return not any(other.type == mujoco.mjtJoint.mjJNT_HINGE for other in below)


def _rotate(quat: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.zeros(3)
    mujoco.mju_rotVecQuat(out, np.asarray(v, dtype=np.float64), np.asarray(quat, dtype=np.float64))
    return out


def _hold_fingers(spec: mujoco.MjSpec, file: Path) -> list[str]:
    """Hold every finger (`_finger`) fixed where the file puts it: at its 'home' keyframe's value, else at 0 moved
    into its range (its lower limit when 0 is below it). The joint is removed and its body moved by that much along
    the joint's axis; the equality constraints and fixed tendons that couple held fingers only (a gripper's
    mimic), and sensors of held joints, go with them; keyframes lose their entries. Returns one line per held
    joint (also stored in the model as the text HELD_TEXT). What couples a held finger to the arm is left for
    `_hinges` to refuse."""
    joints = list(spec.joints)
    fingers = [j for j in joints if _finger(j)]
    if not fingers:
        return []
    names = {j.name for j in fingers if j.name}
    home = next((key for key in spec.keys if key.name == "home" and len(key.qpos)), None)
    order = {id(j): k for k, j in enumerate(joints)}
    lines = []
    for joint in fingers:
        value, where = _held_value(joint, home, order[id(joint)], len(joints))
        body = joint.parent
        body.pos = np.asarray(body.pos, dtype=np.float64) + value * _rotate(body.quat, joint.axis)
        lines.append(f"{joint.name or '(unnamed slide joint)'} held at {value:g} m ({where})")
    _delete_finger_couplings(spec, names)
    _drop_finger_entries(spec, joints)
    for joint in fingers:
        spec.delete(joint)
    spec.add_text(name=HELD_TEXT, data="; ".join(lines))
    return lines


def _held_value(joint: mujoco.MjsJoint, home: mujoco.MjsKey | None, index: int, count: int) -> tuple[float, str]:
    """Where a finger (joint `index` of the model's `count`) is held, m, and why: its 'home' keyframe's value, else
    0, moved to its range's nearest end when outside a limited range."""
    if home is not None and len(home.qpos) == count:
        value, where = float(home.qpos[index]), "its 'home' keyframe"
    else:
        value, where = 0.0, "0"
    if joint.limited == mujoco.mjtLimited.mjLIMITED_TRUE or (
            joint.limited == mujoco.mjtLimited.mjLIMITED_AUTO and joint.range[0] < joint.range[1]):
        low, high = float(joint.range[0]), float(joint.range[1])
        if not low <= value <= high:
            value, where = min(max(value, low), high), "its range's nearest end"
    return value, where


def _delete_finger_couplings(spec: mujoco.MjSpec, names: set[str]) -> None:
    """Delete the joint equalities and fixed tendons that couple the held fingers `names` only, and their sensors."""
    for equality in list(spec.equalities):
        if equality.type == mujoco.mjtEq.mjEQ_JOINT and {equality.name1, equality.name2} - {""} <= names:
            spec.delete(equality)
    for tendon in list(spec.tendons):
        wraps = list(tendon.path)
        if wraps and all(w.type == mujoco.mjtWrap.mjWRAP_JOINT and w.target is not None and w.target.name in names
                         for w in wraps):
            spec.delete(tendon)
    for sensor in list(spec.sensors):
        if sensor.objtype == mujoco.mjtObj.mjOBJ_JOINT and sensor.objname in names:
            spec.delete(sensor)


def _drop_finger_entries(spec: mujoco.MjSpec, joints: list[mujoco.MjsJoint]) -> None:
    """Remove the fingers' entries from every keyframe's qpos and qvel that has one per joint of `joints`."""
    kept = [k for k, j in enumerate(joints) if not _finger(j)]
    for key in spec.keys:
        if len(key.qpos) == len(joints):
            key.qpos = np.asarray(key.qpos)[kept]
        if len(key.qvel) == len(joints):
            key.qvel = np.asarray(key.qvel)[kept]


RK4_DAMPING_BOUND = 2.0
"""RK4 is stable on a joint whose damping over its inertia, times the timestep, stays within 2.785 (its stability
interval on the negative real axis); past this bound (a margin below it) the arm is integrated by implicitfast."""
INTEGRATOR_TEXT = "mjtraj_integrator"
"""The name of the custom text element in which a prepared arm says why it is not integrated by RK4."""


def _stiffest_joint(model: mujoco.MjModel) -> tuple[float, int]:
    """The largest damping x timestep / inertia over the joints (armature included), at the 'home' keyframe and at
    qpos0, and its joint."""
    data = mujoco.MjData(model)
    worst, joint = 0.0, 0
    poses = [model.qpos0] + [model.key_qpos[k] for k in range(model.nkey) if model.key(k).name == "home"]
    for q in poses:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        inertia = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, inertia)
        rate = model.dof_damping * model.opt.timestep / np.diag(inertia)
        if rate.max() > worst:
            worst, joint = float(rate.max()), int(model.dof_jntid[int(np.argmax(rate))])
    return worst, joint


def _stable_integrator(spec: mujoco.MjSpec, model: mujoco.MjModel) -> bool:
    """Where the joint damping of `model` (compiled from `spec`, under RK4) makes RK4 unstable at its timestep
    (RK4_DAMPING_BOUND), set `spec` to implicitfast (MuJoCo's, damping treated implicitly) and say why in the text
    INTEGRATOR_TEXT; returns whether it did."""
    rate, joint = _stiffest_joint(model)
    if rate <= RK4_DAMPING_BOUND:
        return False
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.add_text(name=INTEGRATOR_TEXT, data=(
        f"implicitfast, not RK4: joint {model.joint(joint).name}'s damping x timestep / inertia is {rate:.3g} "
        f"(RK4 diverges past 2.785)"))
    return True


def integrator_note(model: mujoco.MjModel) -> str:
    """Why this prepared arm is not integrated by RK4 ('' when it is)."""
    return _text(model, INTEGRATOR_TEXT)


def _text(model: mujoco.MjModel, name: str) -> str:
    k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, name)
    if k < 0:
        return ""
    start = int(model.text_adr[k])
    return bytes(model.text_data[start:start + int(model.text_size[k]) - 1]).decode()


def held_joints(model: mujoco.MjModel) -> str:
    """What `arm_spec` held fixed in this model ('' if nothing): one 'NAME held at VALUE m (WHERE)' per joint."""
    return _text(model, HELD_TEXT)


def _hinges(spec: mujoco.MjSpec, file: Path) -> list[mujoco.MjsJoint]:
    """The model's joints, checked to be hinges of an open chain without tendons or equality constraints."""
    for joint in spec.joints:
        if joint.type != mujoco.mjtJoint.mjJNT_HINGE:
            kind = str(joint.type).split("_")[-1].lower()
            raise ModelError(f"model {file}: joint {joint.name or '(unnamed)'!r} is a {kind} joint; mjtraj "
                             f"plans arms of hinge joints only")
    if spec.tendons:
        raise ModelError(f"model {file}: tendon {spec.tendons[0].name or '(unnamed)'!r}: tendons are not supported")
    if spec.equalities:
        raise ModelError(f"model {file}: equality constraint {spec.equalities[0].name or '(unnamed)'!r}: "
                         f"equality constraints are not supported")
    if not spec.joints:
        raise ModelError(f"model {file}: no hinge joints, so nothing to plan")
    return list(spec.joints)


TorqueLimit = float | tuple[float, ...] | None
"""A user's corrective saturation: one value (N m) for every joint, one per joint, or None (from the model)."""


def torque_limits(torque_limit: object, n: int) -> list[float | None]:
    """`torque_limit` (TorqueLimit, or a list) as one value or None per joint of n, each checked positive.

    Raises:
      InvalidInputError: not a positive number, nor n of them.
    """
    if isinstance(torque_limit, (list, tuple, np.ndarray)) and len(torque_limit) != n:
        raise InvalidInputError(f"torque_limit: expected one value for every joint or one for each of the {n} "
                                f"joints, got {len(torque_limit)}: {list(torque_limit)!r}")
    limit = normalized_limit(torque_limit)
    return list(limit) if isinstance(limit, tuple) else [limit] * n


def normalized_limit(torque_limit: object) -> TorqueLimit:
    """A TorqueLimit from a number, a list of numbers (one value: that value) or None, checked positive."""
    if torque_limit is None:
        return None
    if isinstance(torque_limit, (list, tuple, np.ndarray)):
        values = tuple(positive("torque_limit", v) for v in torque_limit)
        if not values:
            raise InvalidInputError("torque_limit: expected a value (N m) or one per joint, got none")
        return values[0] if len(values) == 1 else values
    return positive("torque_limit", torque_limit)  # type: ignore[arg-type]


def _saturation(spec: mujoco.MjSpec, joint: mujoco.MjsJoint, torque_limit: float | None, file: Path) -> float:
    """The corrective saturation of `joint`, N m, by ARM_RULES: what its actuators can apply, within the joint's own
    actuator force range when it has one."""
    if torque_limit is not None:
        return torque_limit
    limit = _actuator_limit(spec, joint, file)
    if joint.actfrclimited != mujoco.mjtLimited.mjLIMITED_FALSE and np.any(joint.actfrcrange):
        limit = min(limit, float(np.min(np.abs(joint.actfrcrange))))
    return limit


def _actuator_limit(spec: mujoco.MjSpec, joint: mujoco.MjsJoint, file: Path) -> float:
    mine = [a for a in spec.actuators if a.trntype == mujoco.mjtTrn.mjTRN_JOINT and a.target == joint.name]
    for actuator in mine:  # a motor (also geared): joint torque = gear x gain x ctrl, within gear x forcerange
        is_motor = (actuator.gaintype == mujoco.mjtGain.mjGAIN_FIXED and actuator.gainprm[0] != 0.0
                    and actuator.biastype == mujoco.mjtBias.mjBIAS_NONE and actuator.gear[0] != 0.0)
        if is_motor and actuator.ctrllimited != mujoco.mjtLimited.mjLIMITED_FALSE and np.any(actuator.ctrlrange):
            limit = abs(actuator.gear[0] * actuator.gainprm[0]) * float(np.min(np.abs(actuator.ctrlrange)))
            if actuator.forcelimited == mujoco.mjtLimited.mjLIMITED_TRUE and np.any(actuator.forcerange):
                limit = min(limit, abs(actuator.gear[0]) * float(np.min(np.abs(actuator.forcerange))))
            return limit
    for actuator in mine:
        if actuator.forcelimited != mujoco.mjtLimited.mjLIMITED_FALSE and np.any(actuator.forcerange):
            return abs(actuator.gear[0]) * float(np.min(np.abs(actuator.forcerange)))
    if np.any(joint.actfrcrange):
        return float(np.min(np.abs(joint.actfrcrange)))
    raise ModelError(f"model {file}: joint {joint.name!r} has no actuator force range to take the corrective "
                     f"saturation from; give torque_limit (--torque-limit, N m)")


def prepare_arm(path: str | os.PathLike[str], *, dt: float | None = None, torque_limit: TorqueLimit = None
                ) -> mujoco.MjModel:
    """The plant model of the MJCF arm at `path`, prepared by ARM_RULES.

    Args:
      dt: control period, s (the model's own timestep if None).
      torque_limit: corrective saturation, N m: one value for every joint, or one per joint (None: from the
        model, by ARM_RULES).

    Raises:
      ModelError: the file is missing, does not compile, or is not an arm of actuatable hinges (names the element).
    """
    spec = arm_spec(path, dt=dt, torque_limit=torque_limit)
    model = compile_arm(spec, path)
    return compile_arm(spec, path) if _stable_integrator(spec, model) else model


def compile_arm(spec: mujoco.MjSpec, path: str | os.PathLike[str]) -> mujoco.MjModel:
    """Compile an arm's spec (from `arm_spec`, perhaps with more added); a failure is a ModelError naming `path`."""
    try:
        return spec.compile()
    except ValueError as e:
        raise ModelError(f"cannot prepare model {Path(path)}: {' '.join(str(e).split())}") from e


def assets_folder() -> Path:
    """Where the shipped arms are (package data `mjtraj.assets`)."""
    return Path(str(resources.files("mjtraj.assets")))


def shipped_arms() -> tuple[str, ...]:
    """The arms shipped with mjtraj, usable by name wherever a model path is taken."""
    return tuple(sorted(p.stem for p in assets_folder().glob("*.xml")))


def arm_file(path: str | os.PathLike[str]) -> Path:
    """The MJCF file `path` names: a file, or the name of a shipped arm (planar_2link, ur5_3dof, ur5_6dof).

    Raises:
      ModelError: neither (the message lists the shipped arms).
    """
    file = Path(path)
    if file.is_file():
        return file
    shipped = assets_folder() / f"{file.name}.xml"
    if file.name == str(path) and shipped.is_file():
        return shipped
    raise ModelError(f"model file not found: {file} (a shipped arm is named without a folder: "
                     f"{', '.join(shipped_arms())})")


def arm_spec(path: str | os.PathLike[str], *, dt: float | None = None, torque_limit: TorqueLimit = None
             ) -> mujoco.MjSpec:
    """The MjSpec of the arm at `path` prepared by ARM_RULES, not yet compiled, under RK4 (`prepare_arm` compiles
    it, and changes the integrator where the file's damping is too stiff for RK4).

    Raises:
      ModelError: as `prepare_arm`.
    """
    file = arm_file(path)
    try:
        spec = mujoco.MjSpec.from_file(str(file))
    except ValueError as e:
        raise ModelError(f"cannot load model {file}: {' '.join(str(e).split())}") from e
    _hold_fingers(spec, file)
    joints = _hinges(spec, file)
    taken = {joint.name for joint in joints}
    for j, joint in enumerate(joints):
        if not joint.name:  # a motor is attached by name: name it in this copy (the file is not edited)
            joint.name = next(name for k in range(j, j + len(joints) + 1)
                              if (name := f"joint{k}") not in taken)
            taken.add(joint.name)
    limits = [_saturation(spec, joint, given, file)
              for joint, given in zip(joints, torque_limits(torque_limit, len(joints)), strict=True)]
    replaced = {a.name for a in spec.actuators if a.name}
    for actuator in list(spec.actuators):
        spec.delete(actuator)
    for sensor in list(spec.sensors):  # sensors of the replaced actuators would name actuators that are gone
        if sensor.objtype == mujoco.mjtObj.mjOBJ_ACTUATOR and sensor.objname in replaced:
            spec.delete(sensor)
    for joint, limit in zip(joints, limits, strict=True):
        motor = spec.add_actuator(name=f"{joint.name}_motor", target=joint.name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        motor.set_to_motor()
        motor.gear = np.array([1.0, 0, 0, 0, 0, 0])  # set, not inherited: the file's default class may gear motors
        motor.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
        motor.actlimited = mujoco.mjtLimited.mjLIMITED_FALSE
        motor.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        motor.ctrlrange = np.array([-limit, limit])
        joint.actgravcomp = True
    for key in spec.keys:  # a keyframe's ctrl was for the replaced actuators: the new motors start at zero
        if len(key.ctrl):
            key.ctrl = np.zeros(len(joints))
    for body in spec.bodies[1:]:
        body.gravcomp = 1.0
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    if dt is not None:
        spec.option.timestep = positive("dt", dt)
    return spec


def home_pose(model: mujoco.MjModel) -> NDArray[np.float64]:
    """The model's keyframe 'home' if it has one, else its qpos0, clipped into the joint ranges; shape (n,), rad."""
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")
    q = np.array(model.key_qpos[key] if key >= 0 else model.qpos0, dtype=np.float64)
    limited = model.jnt_limited.astype(bool)
    return np.where(limited, np.clip(q, model.jnt_range[:, 0], model.jnt_range[:, 1]), q)
