"""The stated PID gain rule and the discrete-time stability check of the linearised closed loop."""

from __future__ import annotations

from collections.abc import Iterable

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj._validate import positive, positive_int, vector
from mjtraj.controller import PIDGains
from mjtraj.feedforward import feedforward
from mjtraj.linearize import discretize_zoh, linearize
from mjtraj.reference import Reference

GAIN_RULE = (
    "joint i presents the inertia 1/(D(q)^-1)_ii with the other joints free; over 21 poses on the segment q0->qg "
    "its least is J_min and its largest J_max. Tune the lightest case to natural frequency w = 2 pi/(20 dt) (a "
    "twentieth of the sampling rate) with damping ratio 1, and put the integral corner a decade below the lowest "
    "natural frequency the joint reaches along the move, w_low = w sqrt(J_min/J_max): kp = J_min w^2, "
    "kd = 2 J_min w, ki = kp w_low/10")


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
    a, b = vector("q0", q0, model.nq), vector("qg", qg, model.nq)
    poses = a + np.linspace(0.0, 1.0, positive_int("samples", samples))[:, None] * (b - a)
    inertia = np.array([1.0 / np.diag(np.linalg.inv(mass_matrix(model, q))) for q in poses])
    return inertia.min(axis=0), inertia.max(axis=0)


def gain_rule(model: mujoco.MjModel, q0: npt.ArrayLike, qg: npt.ArrayLike, dt: float, *,
              bandwidth: float | None = None, damping: float = 1.0, integral_ratio: float = 0.1) -> PIDGains:
    """The default gains (GAIN_RULE): kp = J_min w^2, kd = 2 zeta J_min w, ki = kp w_low integral_ratio.

    Args:
      q0, qg: the move, shape (n,), rad. dt: control period, s.
      bandwidth: w in rad/s; None for 2 pi / (20 dt).
    """
    w = 2 * np.pi / (20 * positive("dt", dt)) if bandwidth is None else positive("bandwidth", bandwidth)
    zeta = positive("damping", damping)
    ratio = positive("integral_ratio", integral_ratio)
    lightest, heaviest = free_inertia(model, q0, qg)
    w_low = w * np.sqrt(lightest / heaviest)
    kp = lightest * w**2
    return PIDGains.create(kp, kp * ratio * w_low, 2 * zeta * lightest * w, model.nv)


def closed_loop_map(Ad: NDArray[np.float64], Bd: NDArray[np.float64], gains: PIDGains,
                    dt: float) -> NDArray[np.float64]:
    """Linearised error dynamics of plant + PID over one period; shape (3n, 3n).

    State [dq_k; dqd_k; I_{k-1}] with dq = q - q_ref: u_k = -(Kp + Ki dt) dq_k - Kd dqd_k + Ki I_{k-1},
    I_k = I_{k-1} - dq_k dt, [dq; dqd]_{k+1} = Ad [dq; dqd]_k + Bd u_k (saturation inactive).
    """
    n = Bd.shape[1]
    K = np.hstack([np.diag(-(gains.kp + gains.ki * dt)), np.diag(-gains.kd)])
    top = np.hstack([Ad + Bd @ K, Bd @ np.diag(gains.ki)])
    bottom = np.hstack([-dt * np.eye(n), np.zeros((n, n)), np.eye(n)])
    return np.vstack([top, bottom])


def spectral_radius_along(model: mujoco.MjModel, gains: PIDGains, references: Iterable[Reference], *,
                          moving: bool = True, every: int = 1) -> float:
    """Largest frozen-time spectral radius of the closed-loop map over the samples of each reference.

    moving=True linearises at (q_ref,k, qd_ref,k, tau_ff,k), the reference as executed; its Coriolis terms
    make even the open loop locally unstable (radius slightly above 1), so it is an indicator. moving=False
    linearises at rest at each reference pose: below 1 means the gains suit the inertia at every pose.
    """
    worst = 0.0
    for ref in references:
        ff = feedforward(model, ref) if moving else np.zeros((ref.steps, ref.n))
        for k in range(0, ref.steps, positive_int("every", every)):
            if moving:
                A, B = linearize(model, ref.q[k], ref.qd[k], np.clip(ff[k], -60.0, 60.0))
            else:
                A, B = linearize(model, ref.q[k])
            Ad, Bd = discretize_zoh(A, B, ref.dt)
            worst = max(worst, float(np.max(np.abs(np.linalg.eigvals(closed_loop_map(Ad, Bd, gains, ref.dt))))))
    return worst
