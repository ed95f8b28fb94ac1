"""The UR5 3-DoF plant model: loading the shipped MJCF and reading joint facts from it."""

from __future__ import annotations

import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import positive
from mjtraj.exceptions import InvalidInputError, ModelError

MODEL_FILE = "ur5_3dof.xml"


def default_model_path() -> Path:
    """Path of the shipped `ur5_3dof.xml` (installed as package data `mjtraj.assets`)."""
    return Path(str(resources.files("mjtraj.assets").joinpath(MODEL_FILE)))


def load_model(path: str | os.PathLike[str] | None = None, *, dt: float | None = None,
               torque_limit: float | tuple[float, ...] | None = None) -> mujoco.MjModel:
    """Load the plant model.

    Args:
      path: an MJCF file; None for the shipped UR5 3-DoF model.
      dt: control period in s; sets `opt.timestep` when given (the model's own 0.02 s otherwise).
      torque_limit: a user's arm only: the corrective saturation, N m, one value or one per joint
        (mjtraj.core.arm.ARM_RULES).

    Raises:
      ModelError: the file is missing or MuJoCo cannot compile it.
    """
    if path is not None:  # a user's arm (or the shipped file named explicitly), prepared by mujoco.MjSpec
        from mjtraj.core.arm import prepare_arm

        return prepare_arm(path, dt=dt, torque_limit=torque_limit)
    if torque_limit is not None:
        raise InvalidInputError(f"torque_limit: only for your own arm (a model file), got {torque_limit!r} for the "
                                f"shipped UR5, whose saturation is its motors' 60 N m")
    file = default_model_path()
    if not file.is_file():
        raise ModelError(f"model file not found: {file}")
    try:
        model = mujoco.MjModel.from_xml_path(str(file))
    except ValueError as e:
        raise ModelError(f"cannot load model {file}: {' '.join(str(e).split())}") from e
    if model.nu != model.nv or model.nv != model.njnt:
        raise ModelError(f"model {file}: expected one hinge joint and one motor per degree of freedom, "
                         f"got njnt={model.njnt}, nv={model.nv}, nu={model.nu}")
    if dt is not None:
        model.opt.timestep = positive("dt", dt)
    return model


def control_range(model: mujoco.MjModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each control's range (low, high), shape (nu,) each: MuJoCo clamps ctrl to it; -inf/inf where unlimited."""
    limited = model.actuator_ctrllimited.astype(bool)
    return (np.where(limited, model.actuator_ctrlrange[:, 0], -np.inf),
            np.where(limited, model.actuator_ctrlrange[:, 1], np.inf))


@dataclass(frozen=True)
class JointInfo:
    """Joint names and limits of a model; arrays of shape (n,)."""

    names: tuple[str, ...]
    lower: NDArray[np.float64]
    """Lower position limits, rad."""
    upper: NDArray[np.float64]
    """Upper position limits, rad."""
    torque_limit: NDArray[np.float64]
    """Corrective-torque saturation |dtau_i| from the motors' ctrlrange, N m."""

    @classmethod
    def of(cls, model: mujoco.MjModel) -> JointInfo:
        """Read the joints of `model` (limits of an unlimited joint are +-inf)."""
        names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
                      for j in range(model.njnt))
        limited = model.jnt_limited.astype(bool)
        lower = np.where(limited, model.jnt_range[:, 0], -np.inf)
        upper = np.where(limited, model.jnt_range[:, 1], np.inf)
        ctrl = np.where(model.actuator_ctrllimited.astype(bool), np.abs(model.actuator_ctrlrange).min(axis=1),
                        np.inf)
        torque = np.empty(model.nv)
        torque[model.actuator_trnid[:, 0]] = ctrl
        for array in (lower, upper, torque):
            array.setflags(write=False)
        return cls(names, lower, upper, torque)

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.names)
