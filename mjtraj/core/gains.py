"""The stated PID gain rule: diagonal gains from the inertia each joint presents along the move."""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.checks import positive, positive_int, vector
from mjtraj.core.controller import PIDGains
from mjtraj.core.task import UNLIMITED_RANGE

GAIN_RULE = (
    "joint i presents the inertia 1/(D(q)^-1)_ii with the other joints free; over 21 poses on the segment q0->qg "
    "its least is J_min and its largest J_max. Tune the lightest case to natural frequency w = 2 pi/(20 dt) (a "
    "twentieth of the sampling rate) with damping ratio 1, and put the integral corner a decade below the lowest "
    "natural frequency the joint reaches along the move, w_low = w sqrt(J_min/J_max): kp = J_min w^2, "
    "kd = 2 J_min w, ki = kp w_low/10; where the joint's own damping b dominates its inertia at w (b > J_min w), "
    "kp = b w instead, the bandwidth w of a joint that responds as b qd = kp e")


def mass_matrix(model: mujoco.MjModel, q: npt.ArrayLike) -> NDArray[np.float64]:
    """D(q), shape (n, n), kg m^2."""
    data = mujoco.MjData(model)
    data.qpos[:] = vector("q", q, model.nq)
    mujoco.mj_forward(model, data)
    D = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, D)
    return D


def free_inertia(model: mujoco.MjModel, q0: npt.ArrayLike, qg: npt.ArrayLike, *, samples: int = 21
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Least and largest 1/(D(q)^-1)_ii over `samples` poses on the segment q0->qg; shape (n,) each, kg m^2.

    1/(D^-1)_ii is the inertia joint i presents when the other joints are free. Unlike D_ii it sees the
    strongly coupled shoulder-elbow mode, so diagonal gains sized from it keep that mode in bounds.
    """
    return free_inertia_at(model, segment_poses(model, q0, qg, samples))


def segment_poses(model: mujoco.MjModel, q0: npt.ArrayLike, qg: npt.ArrayLike, samples: int = 21
                  ) -> NDArray[np.float64]:
    """`samples` evenly spaced poses on the segment q0->qg, ends included; shape (samples, n), rad."""
    a, b = vector("q0", q0, model.nq), vector("qg", qg, model.nq)
    return a + np.linspace(0.0, 1.0, positive_int("samples", samples))[:, None] * (b - a)


def free_inertia_at(model: mujoco.MjModel, poses: npt.ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Least and largest 1/(D(q)^-1)_ii over `poses` (P, n); shape (n,) each, kg m^2 (see `free_inertia`)."""
    inertia = np.array([1.0 / np.diag(np.linalg.inv(mass_matrix(model, q))) for q in np.asarray(poses)])
    return inertia.min(axis=0), inertia.max(axis=0)


WORKSPACE_RULE = (
    "on a user's arm whose tasks are drawn (sweeps, tune, the env's random tasks) the gain rule takes J_min and J_max "
    "over the workspace instead of one move: the 21 poses of the default move and 64 poses of a scrambled Sobol "
    "sequence (scipy.stats.qmc.Sobol, seed 0) over the joint ranges (a joint without a range over [-pi, pi]), so "
    "that the gains suit every task a family draws; the same gains for every planner")
WORKSPACE_POSES = 64


def workspace_poses(model: mujoco.MjModel, q0: npt.ArrayLike, qg: npt.ArrayLike, *, samples: int = 21,
                    count: int = WORKSPACE_POSES) -> NDArray[np.float64]:
    """The poses WORKSPACE_RULE sizes gains over: `samples` on the segment q0->qg, then `count` Sobol poses in
    the joint ranges; shape (samples + count, n), rad."""
    from scipy.stats import qmc

    line = segment_poses(model, q0, qg, samples)
    limited = model.jnt_limited.astype(bool)
    low = np.where(limited, model.jnt_range[:, 0], -UNLIMITED_RANGE)
    high = np.where(limited, model.jnt_range[:, 1], UNLIMITED_RANGE)
    unit = qmc.Sobol(d=model.nq, scramble=True, seed=0).random(positive_int("count", count))
    return np.vstack([line, low + unit * (high - low)])


def gain_rule(model: mujoco.MjModel, q0: npt.ArrayLike, qg: npt.ArrayLike, dt: float, *,
              bandwidth: float | None = None, damping: float = 1.0, integral_ratio: float = 0.1,
              workspace: bool = False) -> PIDGains:
    """The default gains (GAIN_RULE): kp = max(J_min w^2, b w) (b the joint's damping), kd = 2 zeta J_min w,
    ki = kp w_low integral_ratio.

    Args:
      q0, qg: the move, shape (n,), rad. dt: control period, s.
      bandwidth: w in rad/s; None for 2 pi / (20 dt).
      workspace: J_min and J_max over WORKSPACE_RULE's poses instead of the move's.
    """
    w = 2 * np.pi / (20 * positive("dt", dt)) if bandwidth is None else positive("bandwidth", bandwidth)
    zeta = positive("damping", damping)
    ratio = positive("integral_ratio", integral_ratio)
    lightest, heaviest = (free_inertia_at(model, workspace_poses(model, q0, qg)) if workspace
                          else free_inertia(model, q0, qg))
    w_low = w * np.sqrt(lightest / heaviest)
    # a joint whose own damping dominates its inertia at w (b > J w) responds as b qd = kp e: kp = b w gives it the
    # bandwidth w (zero damping, as on the UR5: kp = J w^2 exactly)
    kp = np.maximum(lightest * w**2, model.dof_damping * w)
    return PIDGains.create(kp, kp * ratio * w_low, 2 * zeta * lightest * w, model.nv)
