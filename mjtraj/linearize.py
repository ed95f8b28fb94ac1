"""Linearisation of the gravity-compensated plant by central finite differences through MuJoCo, and ZOH."""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt
import scipy.linalg
from numpy.typing import NDArray

from mjtraj._validate import positive, vector


def dynamics(model: mujoco.MjModel, data: mujoco.MjData, q: NDArray[np.float64], qd: NDArray[np.float64],
             u: NDArray[np.float64]) -> NDArray[np.float64]:
    """f(x, u) = [qd; qdd] of the plant with torque G(q) + u; shape (2n,).

    Gravity compensation is the model's own (body gravcomp routed to the actuators), so
    qdd = D(q)^-1 (u - C(q, qd) qd), the paper's eq. (3).
    """
    data.qpos[:] = q
    data.qvel[:] = qd
    data.ctrl[:] = u
    mujoco.mj_forward(model, data)
    return np.concatenate([qd, data.qacc])


def linearize(model: mujoco.MjModel, q: npt.ArrayLike, qd: npt.ArrayLike | None = None,
              u: npt.ArrayLike | None = None, *, eps: float = 1e-6
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Continuous-time A_c = df/dx, B_c = df/du at (x, u) = ([q; qd], u) by central differences.

    Args:
      q: joint positions, shape (n,), rad. qd: velocities, shape (n,), rad/s (default 0).
      u: corrective torque, shape (n,), N m (default 0). eps: difference step.

    Returns:
      A_c of shape (2n, 2n) and B_c of shape (2n, n).
    """
    n = model.nv
    q0 = vector("q", q, n)
    qd0 = vector("qd", np.zeros(n) if qd is None else qd, n)
    u0 = vector("u", np.zeros(n) if u is None else u, n)
    eps = positive("eps", eps)
    data = mujoco.MjData(model)
    x0 = np.concatenate([q0, qd0])
    A = np.empty((2 * n, 2 * n))
    B = np.empty((2 * n, n))
    for i in range(2 * n):
        dx = np.zeros(2 * n)
        dx[i] = eps
        plus, minus = x0 + dx, x0 - dx
        A[:, i] = (dynamics(model, data, plus[:n], plus[n:], u0) - dynamics(model, data, minus[:n], minus[n:], u0)) \
            / (2 * eps)
    for j in range(n):
        du = np.zeros(n)
        du[j] = eps
        B[:, j] = (dynamics(model, data, q0, qd0, u0 + du) - dynamics(model, data, q0, qd0, u0 - du)) / (2 * eps)
    return A, B


def discretize_zoh(A: npt.ArrayLike, B: npt.ArrayLike, dt: float
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Zero-order-hold pair A_d = e^{A dt}, B_d = int_0^dt e^{A s} ds B, from one matrix exponential.

    Uses expm([[A, B], [0, 0]] dt) = [[A_d, B_d], [0, I]].
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    nx, nu = B.shape
    block = np.zeros((nx + nu, nx + nu))
    block[:nx, :nx] = A
    block[:nx, nx:] = B
    phi = scipy.linalg.expm(block * positive("dt", dt))
    return phi[:nx, :nx], phi[:nx, nx:]
