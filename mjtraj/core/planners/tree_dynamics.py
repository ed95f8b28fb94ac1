"""The forward dynamics of a tree of hinge joints and its first derivatives, compiled by numba: the inner loop of
the nonlinear planners' analytic Jacobians (`mjtraj.core.planners.rigid_body`).

At each of P points (q, qd, tau) `derivatives` gives the acceleration a = M(q)^-1 (tau - b(q, qd)), da/dq, da/dqd
and M^-1 = da/dtau, as Pinocchio's computeABADerivatives does (Carpentier and Mansard, 2018), by the recursive
Newton-Euler algorithm (Featherstone, 2008) in the joints' frames with Pinocchio's conventions: n passes with
qd = 0, no gravity and qdd = e_j (only joint j and the joints beyond it move) give M's columns; one pass with
qdd = 0 gives b; one pass at qdd = a, carried forward with the 2n tangents d/dq_j, d/dqd_j of every velocity,
acceleration and force (forward-mode differentiation written out), gives dtau/dq and dtau/dqd at fixed qdd, and
da/dx = -M^-1 dtau/dx.

All P points run in one compiled call: Pinocchio's Python API takes one point per call, and at N = 100 steps of
RK4 (4 N points per Jacobian) the calls cost more than the arithmetic (about 1.7 ms against 0.72 ms per 400
points on one core of this machine; a test holds the values to Pinocchio's within 1e-11). The compiled code is
cached on disk (numba's cache, in the folder `mjtraj.core.planners.numba_cache` chooses): the first call in a new
installation compiles it (about 9 s here; `mjtraj doctor --warm-up` does it ahead), later processes load it.
`HingeTree.rk4` chains these derivatives through the four stages of an RK4 step of MuJoCo's arm (damping, the input
map, clamped controls, dry friction, per-body gravity compensation) in the same compiled code: the step and its
Jacobian in (x, u), 0.79 ms per 100 states where NumPy's chain over the same compiled derivatives took 0.99.

Spatial vectors are pairs of 3-vectors (linear, angular), each a row of a (rows, 3) array addressed by its index:
numba makes a view of an array row at a cost, and the passes take hundreds of them per point. A motion in the
parent's frame is brought into joint i's frame by X_i^-1: w' = R_i^T w, l' = R_i^T (l - t_i x w), where
R_i = placement_R_i Rot(axis_i, q_i) and t_i = placement_t_i; a force goes back by X_i: l' = R_i l,
w' = R_i w + t_i x (R_i l).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.core.planners.numba_cache import njit

_compiled = njit(error_model="numpy")
"""numba's compilation of the kernels: NumPy's error model (a division by zero gives inf or nan, not an exception),
which leaves out the checks around every division (5 % of `derivatives`' time; the same values, bit for bit)."""
_inline = njit(inline="always", error_model="numpy")


@_inline
def _motion_to_child(R: Any, t: Any, i: int, l: Any, w: Any, r: int, out_l: Any, out_w: Any, o: int) -> None:
    """(out_l, out_w)[o] = X_i^-1 (l, w)[r] (see the module docstring)."""
    w0, w1, w2 = w[r, 0], w[r, 1], w[r, 2]
    t0, t1, t2 = t[i, 0], t[i, 1], t[i, 2]
    d0 = l[r, 0] - (t1 * w2 - t2 * w1)
    d1 = l[r, 1] - (t2 * w0 - t0 * w2)
    d2 = l[r, 2] - (t0 * w1 - t1 * w0)
    for k in range(3):
        out_l[o, k] = R[i, 0, k] * d0 + R[i, 1, k] * d1 + R[i, 2, k] * d2
        out_w[o, k] = R[i, 0, k] * w0 + R[i, 1, k] * w1 + R[i, 2, k] * w2


@_inline
def _add_force_to_parent(R: Any, t: Any, i: int, l: Any, w: Any, r: int, out_l: Any, out_w: Any, o: int) -> None:
    """(out_l, out_w)[o] += X_i (l, w)[r] (see the module docstring)."""
    x0 = R[i, 0, 0] * l[r, 0] + R[i, 0, 1] * l[r, 1] + R[i, 0, 2] * l[r, 2]
    x1 = R[i, 1, 0] * l[r, 0] + R[i, 1, 1] * l[r, 1] + R[i, 1, 2] * l[r, 2]
    x2 = R[i, 2, 0] * l[r, 0] + R[i, 2, 1] * l[r, 1] + R[i, 2, 2] * l[r, 2]
    t0, t1, t2 = t[i, 0], t[i, 1], t[i, 2]
    out_l[o, 0] += x0
    out_l[o, 1] += x1
    out_l[o, 2] += x2
    for k in range(3):
        out_w[o, k] += R[i, k, 0] * w[r, 0] + R[i, k, 1] * w[r, 1] + R[i, k, 2] * w[r, 2]
    out_w[o, 0] += t1 * x2 - t2 * x1
    out_w[o, 1] += t2 * x0 - t0 * x2
    out_w[o, 2] += t0 * x1 - t1 * x0


@_inline
def _inertia_times(mass: Any, lever: Any, inertia: Any, i: int, l: Any, w: Any, r: int, out_l: Any, out_w: Any,
                   o: int) -> None:
    """(out_l, out_w)[o] = body i's spatial inertia times the motion (l, w)[r]: f = m (l - c x w),
    n = I_c w + c x f (c: the centre of mass, I_c: the rotational inertia about it)."""
    c0, c1, c2 = lever[i, 0], lever[i, 1], lever[i, 2]
    w0, w1, w2 = w[r, 0], w[r, 1], w[r, 2]
    f0 = mass[i] * (l[r, 0] - (c1 * w2 - c2 * w1))
    f1 = mass[i] * (l[r, 1] - (c2 * w0 - c0 * w2))
    f2 = mass[i] * (l[r, 2] - (c0 * w1 - c1 * w0))
    out_l[o, 0] = f0
    out_l[o, 1] = f1
    out_l[o, 2] = f2
    out_w[o, 0] = inertia[i, 0, 0] * w0 + inertia[i, 0, 1] * w1 + inertia[i, 0, 2] * w2 + c1 * f2 - c2 * f1
    out_w[o, 1] = inertia[i, 1, 0] * w0 + inertia[i, 1, 1] * w1 + inertia[i, 1, 2] * w2 + c2 * f0 - c0 * f2
    out_w[o, 2] = inertia[i, 2, 0] * w0 + inertia[i, 2, 1] * w1 + inertia[i, 2, 2] * w2 + c0 * f1 - c1 * f0


@_inline
def _add_force_cross(vl: Any, vw: Any, v: int, fl: Any, fw: Any, f: int, out_l: Any, out_w: Any, o: int) -> None:
    """(out_l, out_w)[o] += (vl, vw)[v] x* (fl, fw)[f] = (vw x fl, vw x fw + vl x fl)."""
    a0, a1, a2 = vw[v, 0], vw[v, 1], vw[v, 2]
    b0, b1, b2 = vl[v, 0], vl[v, 1], vl[v, 2]
    l0, l1, l2 = fl[f, 0], fl[f, 1], fl[f, 2]
    n0, n1, n2 = fw[f, 0], fw[f, 1], fw[f, 2]
    out_l[o, 0] += a1 * l2 - a2 * l1
    out_l[o, 1] += a2 * l0 - a0 * l2
    out_l[o, 2] += a0 * l1 - a1 * l0
    out_w[o, 0] += a1 * n2 - a2 * n1 + b1 * l2 - b2 * l1
    out_w[o, 1] += a2 * n0 - a0 * n2 + b2 * l0 - b0 * l2
    out_w[o, 2] += a0 * n1 - a1 * n0 + b0 * l1 - b1 * l0


@_inline
def _add_cross(s0: float, s1: float, s2: float, a: Any, r: int, sign: float, out: Any, o: int) -> None:
    """out[o] += sign (s x a[r])."""
    out[o, 0] += sign * (s1 * a[r, 2] - s2 * a[r, 1])
    out[o, 1] += sign * (s2 * a[r, 0] - s0 * a[r, 2])
    out[o, 2] += sign * (s0 * a[r, 1] - s1 * a[r, 0])


@_compiled
def _newton_euler(parents: Any, R: Any, t: Any, axes: Any, mass: Any, lever: Any, inertia: Any, qd: Any, qdd: Any,
                  vl: Any, vw: Any, pl: Any, pw: Any, al: Any, aw: Any, fl: Any, fw: Any, scratch_l: Any,
                  scratch_w: Any, tau: Any) -> None:
    """tau (n,) = RNEA(q, qd, qdd) for the frames R, t of q. Row n of vl, vw, al, aw is the base (zero velocity; its
    acceleration, -gravity or zero, set by the caller). Leaves each joint's velocity (vl, vw), its parent's
    acceleration in its frame (pl, pw), its acceleration (al, aw) and its force with its subtree's (fl, fw)."""
    n = qd.shape[0]
    for i in range(n):
        p = parents[i]
        _motion_to_child(R, t, i, vl, vw, p, vl, vw, i)
        _motion_to_child(R, t, i, al, aw, p, pl, pw, i)
        s0, s1, s2 = axes[i, 0] * qd[i], axes[i, 1] * qd[i], axes[i, 2] * qd[i]
        vw[i, 0] += s0
        vw[i, 1] += s1
        vw[i, 2] += s2
        # a_i = X_i^-1 a_p + v_i x S qd_i + S qdd_i, with (l, w) x (0, s) = (l x s, w x s)
        al[i, 0] = pl[i, 0] + vl[i, 1] * s2 - vl[i, 2] * s1
        al[i, 1] = pl[i, 1] + vl[i, 2] * s0 - vl[i, 0] * s2
        al[i, 2] = pl[i, 2] + vl[i, 0] * s1 - vl[i, 1] * s0
        aw[i, 0] = pw[i, 0] + vw[i, 1] * s2 - vw[i, 2] * s1 + axes[i, 0] * qdd[i]
        aw[i, 1] = pw[i, 1] + vw[i, 2] * s0 - vw[i, 0] * s2 + axes[i, 1] * qdd[i]
        aw[i, 2] = pw[i, 2] + vw[i, 0] * s1 - vw[i, 1] * s0 + axes[i, 2] * qdd[i]
        # f_i = I_i a_i + v_i x* I_i v_i
        _inertia_times(mass, lever, inertia, i, al, aw, i, fl, fw, i)
        _inertia_times(mass, lever, inertia, i, vl, vw, i, scratch_l, scratch_w, 0)
        _add_force_cross(vl, vw, i, scratch_l, scratch_w, 0, fl, fw, i)
    for i in range(n - 1, -1, -1):
        tau[i] = axes[i, 0] * fw[i, 0] + axes[i, 1] * fw[i, 1] + axes[i, 2] * fw[i, 2]
        if parents[i] < n:
            _add_force_to_parent(R, t, i, fl, fw, i, fl, fw, parents[i])


@_compiled
def _mass_column(j: int, parents: Any, below: Any, R: Any, t: Any, axes: Any, mass: Any, lever: Any, inertia: Any,
                 al: Any, aw: Any, fl: Any, fw: Any, column: Any) -> None:
    """M's column j (n,): `_newton_euler` with qd = 0, no gravity and qdd = e_j, where only joint j and the joints
    beyond it accelerate (a_j = S_j, a_i = X_i^-1 a_p) and no velocity term arises."""
    n = column.shape[0]
    for i in range(n):
        if not below[j, i]:
            fl[i, :] = 0.0
            fw[i, :] = 0.0
            continue
        if i == j:
            al[i, :] = 0.0
            aw[i, 0], aw[i, 1], aw[i, 2] = axes[i, 0], axes[i, 1], axes[i, 2]
        else:
            _motion_to_child(R, t, i, al, aw, parents[i], al, aw, i)
        _inertia_times(mass, lever, inertia, i, al, aw, i, fl, fw, i)
    for i in range(n - 1, -1, -1):
        column[i] = axes[i, 0] * fw[i, 0] + axes[i, 1] * fw[i, 1] + axes[i, 2] * fw[i, 2]
        if parents[i] < n:
            _add_force_to_parent(R, t, i, fl, fw, i, fl, fw, parents[i])


@_compiled
def _newton_euler_tangents(parents: Any, below: Any, R: Any, t: Any, axes: Any, mass: Any, lever: Any, inertia: Any,
                           qd: Any, vl: Any, vw: Any, pl: Any, pw: Any, fl: Any, fw: Any, vlt: Any, vwt: Any,
                           alt: Any, awt: Any, flt: Any, fwt: Any, scratch_l: Any, scratch_w: Any, dtau: Any) -> None:
    """dtau (n, 2n) = d RNEA / d(q, qd) at fixed qdd, about the `_newton_euler` pass just run (its vl .. fw).
    Tangent rows: joint i's tangent along direction d (q_0 .. q_n-1, then qd_0 .. qd_n-1) is row i 2n + d; the
    base's rows (n 2n ..) are zero. A joint's velocity and acceleration move only with the joints on its path to the
    base (below[j, i]: joint i is j or below it): the other rows are never written and stay zero."""
    n = qd.shape[0]
    T = 2 * n
    for i in range(n):
        p = parents[i]
        for d in range(T):
            if below[d % n, i]:
                _motion_to_child(R, t, i, vlt, vwt, p * T + d, vlt, vwt, i * T + d)
                _motion_to_child(R, t, i, alt, awt, p * T + d, alt, awt, i * T + d)
        along_q, along_qd = i * T + i, i * T + n + i
        s0, s1, s2 = axes[i, 0], axes[i, 1], axes[i, 2]
        # d/dq_i X_i^-1 m = -S x X_i^-1 m, S = (0, s), S x (l, w) = (s x l, s x w); S x v_i = S x X_i^-1 v_p
        _add_cross(s0, s1, s2, vl, i, -1.0, vlt, along_q)
        _add_cross(s0, s1, s2, vw, i, -1.0, vwt, along_q)
        _add_cross(s0, s1, s2, pl, i, -1.0, alt, along_q)
        _add_cross(s0, s1, s2, pw, i, -1.0, awt, along_q)
        vwt[along_qd, 0] += s0
        vwt[along_qd, 1] += s1
        vwt[along_qd, 2] += s2
        x0, x1, x2 = s0 * qd[i], s1 * qd[i], s2 * qd[i]
        for d in range(T):  # the tangent of v_i x S qd_i along v_i's
            if below[d % n, i]:
                r = i * T + d
                _add_cross(-x0, -x1, -x2, vlt, r, 1.0, alt, r)
                _add_cross(-x0, -x1, -x2, vwt, r, 1.0, awt, r)
        _add_cross(-s0, -s1, -s2, vl, i, 1.0, alt, along_qd)  # ... and along qd_i: v_i x S
        _add_cross(-s0, -s1, -s2, vw, i, 1.0, awt, along_qd)
        _inertia_times(mass, lever, inertia, i, vl, vw, i, scratch_l, scratch_w, 0)
        for d in range(T):  # f_i = I a_i + v_i x* I v_i (zero along the other joints' directions)
            r = i * T + d
            if not below[d % n, i]:
                flt[r, :] = 0.0
                fwt[r, :] = 0.0
                continue
            _inertia_times(mass, lever, inertia, i, alt, awt, r, flt, fwt, r)
            _add_force_cross(vlt, vwt, r, scratch_l, scratch_w, 0, flt, fwt, r)
            _inertia_times(mass, lever, inertia, i, vlt, vwt, r, scratch_l, scratch_w, 1)
            _add_force_cross(vl, vw, i, scratch_l, scratch_w, 1, flt, fwt, r)
    for i in range(n - 1, -1, -1):
        for d in range(T):
            r = i * T + d
            dtau[i, d] = axes[i, 0] * fwt[r, 0] + axes[i, 1] * fwt[r, 1] + axes[i, 2] * fwt[r, 2]
        p = parents[i]
        if p < n:
            for d in range(T):
                _add_force_to_parent(R, t, i, flt, fwt, i * T + d, flt, fwt, p * T + d)
            # d/dq_i X_i f_i = X_i (S x* f_i), S x* (l, w) = (s x l, s x w)
            scratch_l[2, :] = 0.0
            scratch_w[2, :] = 0.0
            _add_cross(axes[i, 0], axes[i, 1], axes[i, 2], fl, i, 1.0, scratch_l, 2)
            _add_cross(axes[i, 0], axes[i, 1], axes[i, 2], fw, i, 1.0, scratch_w, 2)
            _add_force_to_parent(R, t, i, scratch_l, scratch_w, 2, flt, fwt, p * T + i)


@_inline
def _rotations(placement_R: Any, axes: Any, q: Any, R: Any) -> None:
    """R_i = placement_R_i Rot(axis_i, q_i) for every joint (Rodrigues)."""
    for i in range(q.shape[0]):
        a0, a1, a2 = axes[i, 0], axes[i, 1], axes[i, 2]
        c, s = np.cos(q[i]), np.sin(q[i])
        C = 1.0 - c
        r00, r01, r02 = c + a0 * a0 * C, a0 * a1 * C - a2 * s, a0 * a2 * C + a1 * s
        r10, r11, r12 = a1 * a0 * C + a2 * s, c + a1 * a1 * C, a1 * a2 * C - a0 * s
        r20, r21, r22 = a2 * a0 * C - a1 * s, a2 * a1 * C + a0 * s, c + a2 * a2 * C
        for r in range(3):
            p0, p1, p2 = placement_R[i, r, 0], placement_R[i, r, 1], placement_R[i, r, 2]
            R[i, r, 0] = p0 * r00 + p1 * r10 + p2 * r20
            R[i, r, 1] = p0 * r01 + p1 * r11 + p2 * r21
            R[i, r, 2] = p0 * r02 + p1 * r12 + p2 * r22


@_inline
def _workspace(n: int) -> Any:
    """The arrays the Newton-Euler passes and their tangents fill, for a tree of n joints: the frames R (n, 3, 3);
    each joint's velocity, acceleration, its parent's acceleration and its force (rows 0..n-1; row n the base), and
    their tangents along the 2n directions (row i 2n + d). The velocities, accelerations and tangents start at zero:
    a row a pass never writes (the base's; a joint's tangent along a direction it does not move with) stays zero
    from one point to the next, so they are never cleared again."""
    rows = (n + 1) * 2 * n
    return (np.empty((n, 3, 3)), np.zeros((n + 1, 3)), np.zeros((n + 1, 3)), np.zeros((n + 1, 3)),
            np.zeros((n + 1, 3)), np.empty((n + 1, 3)), np.empty((n + 1, 3)), np.empty((n + 1, 3)),
            np.empty((n + 1, 3)), np.zeros((rows, 3)), np.zeros((rows, 3)), np.zeros((rows, 3)), np.zeros((rows, 3)),
            np.empty((rows, 3)), np.empty((rows, 3)), np.empty((3, 3)), np.empty((3, 3)))


@_compiled
def _gravity_derivatives(parents: Any, below: Any, placement_R: Any, placement_t: Any, axes: Any, mass: Any,
                         lever: Any, gravity: Any, q: Any, torque: Any, d_torque: Any) -> None:
    """`HingeTree.gravity`, compiled: `_newton_euler` and its tangents at qd = 0, qdd = 0 with the base accelerating
    at -gravity. Angular accelerations and their tangents along q stay zero there, so a body's rotational inertia
    never enters (it is passed as zeros) and only mass times lever, the body's first moment, does."""
    P, n = q.shape
    inertia = np.zeros((n, 3, 3))
    R, vl, vw, al, aw, pl, pw, fl, fw, vlt, vwt, alt, awt, flt, fwt, scratch_l, scratch_w = _workspace(n)
    still = np.zeros(n)
    tau, dtau = np.empty(n), np.empty((n, 2 * n))
    for k in range(P):
        _rotations(placement_R, axes, q[k], R)
        al[n, 0], al[n, 1], al[n, 2] = -gravity[0], -gravity[1], -gravity[2]
        _newton_euler(parents, R, placement_t, axes, mass, lever, inertia, still, still, vl, vw, pl, pw, al, aw, fl,
                      fw, scratch_l, scratch_w, tau)
        _newton_euler_tangents(parents, below, R, placement_t, axes, mass, lever, inertia, still, vl, vw, pl, pw,
                               fl, fw, vlt, vwt, alt, awt, flt, fwt, scratch_l, scratch_w, dtau)
        for i in range(n):
            torque[k, i] = tau[i]
            for j in range(n):
                d_torque[k, i, j] = dtau[i, j]


@_compiled
def _derivatives(parents: Any, below: Any, placement_R: Any, placement_t: Any, axes: Any, mass: Any, lever: Any,
                 inertia: Any, armature: Any, gravity: Any, q: Any, qd: Any, tau: Any, acceleration: Any, da_dq: Any,
                 da_dqd: Any, inverse_mass: Any) -> None:
    """`derivatives`, compiled; parents here use n for the base; below[j, i]: joint i is joint j or beyond it."""
    P, n = q.shape
    T = 2 * n
    R, vl, vw, al, aw, pl, pw, fl, fw, vlt, vwt, alt, awt, flt, fwt, scratch_l, scratch_w = _workspace(n)
    M, L, Mi = np.empty((n, n)), np.zeros((n, n)), np.empty((n, n))
    column, bias, still = np.empty(n), np.empty(n), np.zeros(n)
    dtau = np.empty((n, T))
    for k in range(P):
        _rotations(placement_R, axes, q[k], R)
        for j in range(n):
            _mass_column(j, parents, below, R, placement_t, axes, mass, lever, inertia, al, aw, fl, fw, column)
            M[:, j] = column
        for i in range(n):
            M[i, i] += armature[i]
        for i in range(n):  # M = L L^T
            for j in range(i + 1):
                x = M[i, j]
                for m in range(j):
                    x -= L[i, m] * L[j, m]
                L[i, j] = np.sqrt(x) if i == j else x / L[j, j]
        for j in range(n):  # M^-1's columns: L y = e_j, L^T x = y
            for i in range(n):
                x = 1.0 if i == j else 0.0
                for m in range(i):
                    x -= L[i, m] * column[m]
                column[i] = x / L[i, i]
            for i in range(n - 1, -1, -1):
                x = column[i]
                for m in range(i + 1, n):
                    x -= L[m, i] * Mi[m, j]
                Mi[i, j] = x / L[i, i]
        al[n, 0], al[n, 1], al[n, 2] = -gravity[0], -gravity[1], -gravity[2]
        _newton_euler(parents, R, placement_t, axes, mass, lever, inertia, qd[k], still, vl, vw, pl, pw, al, aw, fl,
                      fw, scratch_l, scratch_w, bias)
        for i in range(n):
            x = 0.0
            for j in range(n):
                x += Mi[i, j] * (tau[k, j] - bias[j])
            acceleration[k, i] = x
        _newton_euler(parents, R, placement_t, axes, mass, lever, inertia, qd[k], acceleration[k], vl, vw, pl, pw,
                      al, aw, fl, fw, scratch_l, scratch_w, bias)
        _newton_euler_tangents(parents, below, R, placement_t, axes, mass, lever, inertia, qd[k], vl, vw, pl, pw,
                               fl, fw, vlt, vwt, alt, awt, flt, fwt, scratch_l, scratch_w, dtau)
        for i in range(n):
            for j in range(n):
                x, y = 0.0, 0.0
                for m in range(n):
                    x -= Mi[i, m] * dtau[m, j]
                    y -= Mi[i, m] * dtau[m, n + j]
                da_dq[k, i, j] = x
                da_dqd[k, i, j] = y
                inverse_mass[k, i, j] = Mi[i, j]


RK4_ALONG = (0.0, 0.5, 0.5, 1.0)
"""The classical Runge-Kutta stages (MuJoCo's mjINT_RK4): each stage's fraction of the step along the previous
stage's derivative ..."""
RK4_WEIGHT = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)
"""... and its weight in the step."""


@_compiled
def _rk4_steps(parents: Any, below: Any, placement_R: Any, placement_t: Any, axes: Any, mass: Any, lever: Any,
               inertia: Any, armature: Any, gravity: Any, held_by: Any, qpos0: Any, actuation: Any, ctrl_low: Any,
               ctrl_high: Any, damping: Any, frictionloss: Any, timestep: float, x: Any, U: Any, after: Any,
               jacobian: Any) -> None:
    """`HingeTree.rk4`, compiled: at each of the P states x (P, 2n) under the controls U (P, nu), the RK4 step
    after (P, 2n) and its Jacobian in (x, u), jacobian (P, 2n, 2n + nu); each stage's dynamics and derivatives at
    all P points in one `_derivatives` call. held_by: None where the tree's own gravity holds the bodies, else the
    arrays of the tree whose `HingeTree.gravity` is the torque gravity takes (parents, below, placement_R,
    placement_t, axes, mass, lever, gravity). frictionloss (n,): zero for none."""
    P, nu = U.shape
    n = qpos0.shape[0]
    width = 2 * n + nu
    tau, inputs = np.zeros((P, n)), np.empty((P, n, nu))  # the joint torques; per control, zero outside its range
    for k in range(P):
        for j in range(nu):
            inside = ctrl_low[j] <= U[k, j] <= ctrl_high[j]
            clipped = min(max(U[k, j], ctrl_low[j]), ctrl_high[j])
            for i in range(n):
                tau[k, i] += clipped * actuation[i, j]
                inputs[k, i, j] = actuation[i, j] if inside else 0.0
    q, v, passive = np.empty((P, n)), np.empty((P, n)), np.empty((P, n))
    acceleration, inverse_mass = np.empty((P, n)), np.empty((P, n, n))
    da_dq, da_dv = np.empty((P, n, n)), np.empty((P, n, n))
    held, d_held = np.empty((P, n)), np.empty((P, n, n))
    slope, total = np.zeros((P, 2 * n)), np.zeros((P, 2 * n))
    d_slope, d_total = np.zeros((P, 2 * n, width)), np.zeros((P, 2 * n, width))
    d_stage = np.empty((2 * n, width))
    for s in range(4):
        c = timestep * RK4_ALONG[s]
        for k in range(P):
            for i in range(n):
                q[k, i] = x[k, i] + c * slope[k, i] - qpos0[i]
                v[k, i] = x[k, n + i] + c * slope[k, n + i]
                passive[k, i] = tau[k, i] - v[k, i] * damping[i] - frictionloss[i] * np.sign(v[k, i])
        if held_by is not None:
            h_parents, h_below, h_placement_R, h_placement_t, h_axes, h_mass, h_lever, h_gravity = held_by
            _gravity_derivatives(h_parents, h_below, h_placement_R, h_placement_t, h_axes, h_mass, h_lever,
                                 h_gravity, q, held, d_held)
            for k in range(P):
                for i in range(n):
                    passive[k, i] -= held[k, i]
        _derivatives(parents, below, placement_R, placement_t, axes, mass, lever, inertia, armature, gravity, q, v,
                     passive, acceleration, da_dq, da_dv, inverse_mass)
        for k in range(P):
            F, D, Mi = da_dq[k], da_dv[k], inverse_mass[k]
            for i in range(n):
                for m in range(n):
                    if held_by is not None:
                        z = 0.0
                        for j in range(n):
                            z += Mi[i, j] * d_held[k, j, m]
                        F[i, m] -= z
                    D[i, m] -= Mi[i, m] * damping[m]  # the damping torque -D v
            for r in range(2 * n):
                for col in range(width):
                    d_stage[r, col] = (1.0 if r == col else 0.0) + c * d_slope[k, r, col]
            for i in range(n):  # d f/d z = [[0, I], [F, D]] d_stage + [0; M^-1 inputs] on the controls' columns
                for col in range(width):
                    d_slope[k, i, col] = d_stage[n + i, col]
                    z = 0.0
                    for m in range(n):
                        z += F[i, m] * d_stage[m, col] + D[i, m] * d_stage[n + m, col]
                    d_slope[k, n + i, col] = z
                for j in range(nu):
                    z = 0.0
                    for m in range(n):
                        z += Mi[i, m] * inputs[k, m, j]
                    d_slope[k, n + i, 2 * n + j] += z
            for i in range(n):
                slope[k, i] = v[k, i]
                slope[k, n + i] = acceleration[k, i]
            for r in range(2 * n):
                total[k, r] += RK4_WEIGHT[s] * slope[k, r]
                for col in range(width):
                    d_total[k, r, col] += RK4_WEIGHT[s] * d_slope[k, r, col]
    for k in range(P):
        for r in range(2 * n):
            after[k, r] = x[k, r] + timestep * total[k, r]
            for col in range(width):
                jacobian[k, r, col] = (1.0 if r == col else 0.0) + timestep * d_total[k, r, col]


class HingeTree:
    """A tree of n hinge joints as the arrays `derivatives` reads, in Pinocchio's conventions (joint i's frame in
    its parent's is placement_R[i], placement_t[i], then a turn of q_i about axes[i]; parents[i] < i, -1 for the
    base). Body masses (n,) kg, centres of mass (n, 3) m and rotational inertias about them (n, 3, 3) kg m^2 in the
    joints' frames; armature (n,) kg m^2; gravity (3,) m/s^2."""

    def __init__(self, parents: NDArray[np.int64], placement_R: NDArray[np.float64],
                 placement_t: NDArray[np.float64], axes: NDArray[np.float64], mass: NDArray[np.float64],
                 lever: NDArray[np.float64], inertia: NDArray[np.float64], armature: NDArray[np.float64],
                 gravity: NDArray[np.float64]) -> None:
        n = len(parents)
        assert np.all(parents < np.arange(n)), "a joint's parent comes before it"
        self.n = n
        self._arrays = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in
                             (placement_R, placement_t, axes, mass, lever, inertia, armature, gravity))
        self._parents = np.where(parents < 0, n, parents).astype(np.int64)  # the base is row n
        self._below = np.eye(n, dtype=np.bool_)  # [j, i]: joint i is joint j or beyond it (parents come first)
        for i in range(n):
            if parents[i] >= 0:
                self._below[:, i] |= self._below[:, parents[i]]

    def derivatives(self, q: NDArray[np.float64], qd: NDArray[np.float64], tau: NDArray[np.float64]
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """At P points, q, qd (rad, rad/s) and tau (N m) of shape (P, n): the acceleration (P, n), da/dq, da/dqd and
        M^-1 (P, n, n)."""
        P, n = q.shape[0], self.n
        acceleration, da_dq, da_dqd, inverse_mass = (np.empty((P, n)), np.empty((P, n, n)), np.empty((P, n, n)),
                                                     np.empty((P, n, n)))
        placement_R, placement_t, axes, mass, lever, inertia, armature, gravity = self._arrays
        q, qd, tau = (np.ascontiguousarray(a, dtype=np.float64) for a in (q, qd, tau))
        _derivatives(self._parents, self._below, placement_R, placement_t, axes, mass, lever, inertia, armature,
                     gravity, q, qd, tau, acceleration, da_dq, da_dqd, inverse_mass)
        return acceleration, da_dq, da_dqd, inverse_mass


    def rk4(self, x: NDArray[np.float64], U: NDArray[np.float64], *, qpos0: NDArray[np.float64],
            actuation: NDArray[np.float64], ctrl_low: NDArray[np.float64], ctrl_high: NDArray[np.float64],
            damping: NDArray[np.float64], frictionloss: NDArray[np.float64] | None, timestep: float,
            held_by: HingeTree | None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The RK4 step of MuJoCo's arm of this tree from each state x (P, 2n) under the controls U (P, nu) and its
        Jacobian: (x' (P, 2n), dx'/d(x, u) (P, 2n, 2n + nu)), compiled (`_rk4_steps`; see `RigidBody`, whose
        attributes the arguments are)."""
        P, n = x.shape[0], self.n
        after, jacobian = np.empty((P, 2 * n)), np.empty((P, 2 * n, 2 * n + U.shape[1]))
        held = None if held_by is None else (held_by._parents, held_by._below, *held_by._arrays[:5],
                                             held_by._arrays[7])
        placement_R, placement_t, axes, mass, lever, inertia, armature, gravity = self._arrays
        x, U = (np.ascontiguousarray(a, dtype=np.float64) for a in (x, U))
        _rk4_steps(self._parents, self._below, placement_R, placement_t, axes, mass, lever, inertia, armature, gravity,
                   held, qpos0, actuation, ctrl_low, ctrl_high, damping,
                   np.zeros(n) if frictionloss is None else frictionloss, float(timestep), x, U, after, jacobian)
        return after, jacobian

    def gravity(self, q: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """At P points q (P, n), rad: the joint torques that hold the tree still against its gravity, G(q) (P, n),
        N m, and dG/dq (P, n, n). Only the bodies' masses and centres of mass enter (the tree's inertias do not)."""
        P, n = q.shape[0], self.n
        torque, d_torque = np.empty((P, n)), np.empty((P, n, n))
        placement_R, placement_t, axes, mass, lever, _, _, gravity = self._arrays
        _gravity_derivatives(self._parents, self._below, placement_R, placement_t, axes, mass, lever, gravity,
                             np.ascontiguousarray(q, dtype=np.float64), torque, d_torque)
        return torque, d_torque
