"""The discrete-time stability check of the linearised closed loop (plant + PID), along references.

Every linearisation of a check runs in one batched call, at most MAX_SAMPLES samples per reference (all of them
up to that count), so its cost is bounded whatever N is.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import positive_int
from mjtraj.core.controller import PIDGains
from mjtraj.core.dynamics import DynamicsProbe, without_dry_friction
from mjtraj.core.linearize import discretize_zoh, linearize_many
from mjtraj.core.model import JointInfo
from mjtraj.core.reference import Reference
from mjtraj.threads import single_blas_thread

MAX_SAMPLES = 200
"""Most samples per reference at which the loop is linearised (evenly spread, both ends included)."""


def closed_loop_map(Ad: NDArray[np.float64], Bd: NDArray[np.float64], gains: PIDGains,
                    dt: float) -> NDArray[np.float64]:
    """Linearised error dynamics of plant + PID over one period; shape (..., 3n, 3n) for Ad (..., 2n, 2n).

    State [dq_k; dqd_k; I_{k-1}] with dq = q - q_ref: u_k = -(Kp + Ki dt) dq_k - Kd dqd_k + Ki I_{k-1},
    I_k = I_{k-1} - dq_k dt, [dq; dqd]_{k+1} = Ad [dq; dqd]_k + Bd u_k (saturation inactive).
    """
    n = Bd.shape[-1]
    K = np.hstack([np.diag(-(gains.kp + gains.ki * dt)), np.diag(-gains.kd)])
    batch = Ad.shape[:-2]
    top = np.concatenate([Ad + Bd @ K, Bd @ np.diag(gains.ki)], axis=-1)
    bottom = np.broadcast_to(np.hstack([-dt * np.eye(n), np.zeros((n, n)), np.eye(n)]), (*batch, n, 3 * n))
    return np.concatenate([top, bottom], axis=-2)


def sample_indices(steps: int, max_samples: int = MAX_SAMPLES) -> NDArray[np.intp]:
    """The periods k in 0..N-1 at which a reference of N periods is checked: all, or `max_samples` spread evenly."""
    positive_int("max_samples", max_samples)
    if steps <= max_samples:
        return np.arange(steps)
    return np.unique(np.round(np.linspace(0, steps - 1, max_samples)).astype(np.intp))


@single_blas_thread
def spectral_radii(model: mujoco.MjModel, gains: PIDGains, references: Sequence[Reference], *,
                   max_samples: int = MAX_SAMPLES, nthread: int = 0) -> dict[str, float]:
    """Largest frozen-time spectral radius of the closed-loop map over the sampled periods of `references`.

    'moving' linearises at (q_ref,k, qd_ref,k, tau_ff,k) with the inverse-dynamics feedforward (clipped to the
    saturation), the reference as executed; its Coriolis terms make even the open loop locally unstable (radius
    slightly above 1), so it is an indicator. 'at_rest' linearises at rest at each sampled reference pose: below
    1 means the gains suit the inertia at every pose. The states are evaluated on `nthread` threads of MuJoCo's
    batch (0: one per core); the radii do not depend on it.
    """
    if not references:
        return {"at_rest": 0.0, "moving": 0.0}
    limit = JointInfo.of(model).torque_limit
    q, qd, qdd, dts = [], [], [], []
    for ref in references:
        k = sample_indices(ref.steps, max_samples)
        q.append(ref.q[k])
        qd.append(ref.qd[k])
        qdd.append(ref.qdd[k])
        dts.append(np.full(k.size, ref.dt))
    Q, QD, QDD, dt = (np.concatenate(a) for a in (q, qd, qdd, dts))
    probe = DynamicsProbe(without_dry_friction(model), size=6 * model.nv * Q.shape[0],  # one Batch, three calls
                          nthread=nthread)
    ff = np.clip(probe.inverse(Q, QD, QDD), -limit, limit)
    zero = np.zeros_like(Q)
    out = {}
    for name, (velocity, torque) in (("at_rest", (zero, zero)), ("moving", (QD, ff))):
        A, B = linearize_many(model, Q, velocity, torque, probe=probe)
        worst = 0.0
        for step in np.unique(dt):  # one ZOH per control period (references share one in practice)
            rows = dt == step
            Ad, Bd = discretize_zoh(A[rows], B[rows], float(step))
            radii = np.abs(np.linalg.eigvals(closed_loop_map(Ad, Bd, gains, float(step)))).max(axis=-1)
            worst = max(worst, float(radii.max()))
        out[name] = worst
    return out
