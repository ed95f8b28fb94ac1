"""Linearisation of the gravity-compensated plant by central finite differences through MuJoCo, and ZOH."""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt
import scipy.linalg
from numpy.typing import NDArray

from mjtraj.checks import positive, vector
from mjtraj.core.dynamics import DynamicsProbe, serial_probe, without_dry_friction
from mjtraj.exceptions import InvalidInputError
from mjtraj.threads import single_blas_thread


def _points(name: str, value: npt.ArrayLike | None, shape: tuple[int, int]) -> NDArray[np.float64]:
    if value is None:
        return np.zeros(shape)
    array = np.asarray(value, dtype=np.float64)
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise InvalidInputError(f"{name}: expected finite values of shape {shape}, got shape {array.shape}")
    return array


SERIAL_ROWS = 64
"""Most perturbed states (6n per point) linearised serially on one MjData rather than on a Batch."""


@single_blas_thread
def linearize_many(model: mujoco.MjModel, q: npt.ArrayLike, qd: npt.ArrayLike | None = None,
                   u: npt.ArrayLike | None = None, *, eps: float = 1e-6, probe: DynamicsProbe | None = None
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Continuous-time A_c = df/dx, B_c = df/du of f(x, u) = [qd; qdd] at P operating points, by central differences.

    The plant torque is G(q) + u (the model's own gravity compensation), so qdd = D(q)^-1 (u - C(q, qd) qd),
    the paper's eq. (3). All 2 (2n + n) perturbed states of all points are evaluated in one batched call. Dry
    friction (friction loss) is left out (`without_dry_friction`); a given `probe` must be of such a model.

    Args:
      q: joint positions, shape (P, n), rad. qd: velocities, shape (P, n), rad/s (default 0).
      u: corrective torques, shape (P, n), N m (default 0). eps: difference step.

    Returns:
      A_c of shape (P, 2n, 2n) and B_c of shape (P, 2n, n).
    """
    n = model.nv
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != n or not np.all(np.isfinite(q)):
        raise InvalidInputError(f"q: expected finite values of shape (P, {n}), got shape {q.shape}")
    P = q.shape[0]
    qd, u = _points("qd", qd, (P, n)), _points("u", u, (P, n))
    eps = positive("eps", eps)
    steps = np.concatenate([eps * np.eye(3 * n), -eps * np.eye(3 * n)])      # rows: +e_i then -e_i over [q; qd; u]
    point = np.concatenate([q, qd, u], axis=1)
    perturbed = (point[:, None, :] + steps[None]).reshape(-1, 3 * n)          # (P * 6n, 3n)
    if probe is None:  # one-off: a few points are evaluated serially, cheaper than making a Batch
        model = without_dry_friction(model)
        rows = perturbed.shape[0]
        probe = serial_probe(model, SERIAL_ROWS) if rows <= SERIAL_ROWS else DynamicsProbe(model, size=rows)
    qdd = probe.accelerations(perturbed[:, :n], perturbed[:, n:2 * n], perturbed[:, 2 * n:])
    f = np.concatenate([perturbed[:, n:2 * n], qdd], axis=1).reshape(P, 2, 3 * n, 2 * n)
    jac = (f[:, 0] - f[:, 1]).transpose(0, 2, 1) / (2 * eps)                 # (P, 2n, 3n): df/d[x; u]
    return jac[:, :, :2 * n], jac[:, :, 2 * n:]


def linearize(model: mujoco.MjModel, q: npt.ArrayLike, qd: npt.ArrayLike | None = None,
              u: npt.ArrayLike | None = None, *, eps: float = 1e-6
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """`linearize_many` at one point: q, qd, u of shape (n,) (qd, u default 0); A_c (2n, 2n), B_c (2n, n)."""
    n = model.nv
    q1, qd1, u1 = (vector(name, value, n)[None] if value is not None else None
                   for name, value in (("q", q), ("qd", qd), ("u", u)))
    assert q1 is not None
    A, B = linearize_many(model, q1, qd1, u1, eps=eps)
    return A[0], B[0]


@single_blas_thread
def discretize_zoh(A: npt.ArrayLike, B: npt.ArrayLike, dt: float
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Zero-order-hold pair A_d = e^{A dt}, B_d = int_0^dt e^{A s} ds B, from one matrix exponential.

    Uses expm([[A, B], [0, 0]] dt) = [[A_d, B_d], [0, I]]. A (..., nx, nx) and B (..., nx, nu) may carry
    leading batch axes.
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    nx, nu = B.shape[-2:]
    block = np.zeros(A.shape[:-2] + (nx + nu, nx + nu))
    block[..., :nx, :nx] = A
    block[..., :nx, nx:] = B
    phi = scipy.linalg.expm(block * positive("dt", dt))
    return phi[..., :nx, :nx], phi[..., :nx, nx:]
