"""The nonlinear planners' problem in single-shooting form: the torques U are the variables, the states their exact
rollout on the nominal MuJoCo model (its own integrator and timestep, one step per control period).

`Shooting` rolls out (MuJoCo's own loop, mujoco.rollout), differentiates each step (analytically where the model's
hinge tree reproduces the rollout, `mjtraj.core.planners.rigid_body`; else by forward differences, all N (3n)
perturbed steps in one mujoco.batch call, on every CPU: bit-identical at any thread count; MuJoCo's
mjd_transitionFD does not support RK4), propagates the forward sensitivities S_k = dx_k/dU, and gives the
objective, its gradient and its Gauss-Newton Hessian. It steps a copy of the model without collision detection
where no two geoms can touch (`_collision_free`): the same steps bit for bit, 15 % sooner. `PathLimits` holds the
path constraints (joint ranges, speed limit, torque bound) as rows h >= 0.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout
from mujoco.batch import Batch
from numpy.typing import NDArray

from mjtraj.core.model import control_range
from mjtraj.core.planners.numba_cache import njit
from mjtraj.core.planners.rigid_body import RigidBody
from mjtraj.exceptions import SolverError

UNSTABLE = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)
"""MuJoCo's warnings of a simulation it had to reset."""
SCREEN = 0.6
"""A path-constraint row enters a solve once its value is beyond this fraction of its limit (speed, torque) or of
the way from the range's middle to its end (positions)."""


@dataclass
class Shooting:
    """One task's single-shooting problem on `model`: the rollout, its sensitivities, objective and constraints.

    Variables u: the torques U (N, n) flattened, N m. States X (N+1, 2n) = [q; qd] of the rollout from x0. The
    objective is 1/2 sum_{k=1..N} (x_k - xg)^T Q (x_k - xg) + 1/2 sum_{k=0..N-1} u_k^T R u_k.
    """

    model: mujoco.MjModel
    x0: NDArray[np.float64]
    xg: NDArray[np.float64]
    Q: NDArray[np.float64]
    R: NDArray[np.float64]
    steps: int
    eps: float
    partial: bool = False
    """Difference only the samples the hinge tree does not reproduce, and hold the plant's dry friction and
    per-body gravity compensation in the tree (`RigidBody.of(plant_forces=True)`): the floor's solves on the true
    plants. The planners keep the tree for every sample or for none, as their published plans were made."""
    _cache: dict[str, Any] = field(default_factory=dict)
    _states: dict[bytes, NDArray[np.float64]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.n = self.model.nv
        self._stepped = _collision_free(self.model)  # what rollouts and their differences step
        self.data = mujoco.MjData(self._stepped)
        # each control's upper end (inf where unlimited): MuJoCo clamps ctrl there, so `jacobians` differences a
        # torque on it backwards (a forward difference would see no effect)
        self._ctrl_high = control_range(self.model)[1]
        self._rigid_body = RigidBody.of(self.model, plant_forces=self.partial)
        self.jacobian_counts = {"analytic": 0, "differenced": 0}
        # the state `_start` sets, as mujoco.rollout takes it, and where qpos and qvel sit in a state
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self._start()
        self._initial_state = np.empty((1, mujoco.mj_stateSize(self._stepped, spec)))  # a batch of one
        mujoco.mj_getState(self._stepped, self.data, self._initial_state[0], spec)
        self._warmstart = np.zeros((1, self.model.nv))  # mj_resetData's
        self._roller = mj_rollout.Rollout(nthread=0)  # on the calling thread, made once
        start, nq = mujoco.mj_stateSize(self._stepped, mujoco.mjtState.mjSTATE_TIME), self.model.nq
        self._qpos_qvel = np.concatenate([start + np.arange(nq), start + nq + np.arange(self.n)])  # time, qpos, qvel

    def rollout(self, U: NDArray[np.float64]) -> NDArray[np.float64]:
        """States x_0..x_N of the model under U (N, n) from x0; shape (N+1, 2n). MuJoCo's own loop (mujoco.rollout)
        steps it: the same steps as `tracked`'s bit for bit (a reset state, no warm start), about 15 % sooner; its
        arguments are made here to its shapes, so its checks are skipped (25 us of 0.8 ms).

        Raises:
          SolverError: MuJoCo had to reset the simulation (the rollout diverged).
        """
        n, d, steps = self.n, self.data, U.shape[0]
        d.warning.number[:] = 0
        states = np.empty((1, steps, self._initial_state.shape[1]))
        self._roller.rollout([self._stepped], [d], self._initial_state, np.ascontiguousarray(U[None], dtype=float),
                             skip_checks=True, nstep=steps, initial_warmstart=self._warmstart, state=states,
                             sensordata=np.empty((1, steps, self._stepped.nsensordata)))
        states = states[0]  # (N, nstate): the only batch
        self._check_stable("the rollout of an iterate")
        X = np.empty((steps + 1, 2 * n))
        X[0] = self.x0
        X[1:] = states[:, self._qpos_qvel]
        return X

    def tracked(self, U: NDArray[np.float64], X_ref: NDArray[np.float64], K: NDArray[np.float64],
                u_max: NDArray[np.float64]) -> NDArray[np.float64]:
        """The torques (N, n) with which the model tracks the states X_ref (N+1, 2n) from x0 under the feedback
        u_k = clip(U_k + K_k (X_ref_k - x_k), -u_max, u_max), K (N, n, 2n); rolled out step by step, so that their
        open-loop rollout (`rollout`) is the tracked motion, bit for bit: `states` of them is that motion, without
        another rollout.

        Raises:
          SolverError: MuJoCo had to reset the simulation (the tracked motion diverged).
        """
        n, d, steps = self.n, self.data, U.shape[0]
        torques = np.empty((steps, n))
        X = np.empty((steps + 1, 2 * n))
        X[0] = self.x0
        self._start()
        qpos, qvel, ctrl, low = d.qpos, d.qvel, d.ctrl, -u_max
        error, feedback = np.empty(2 * n), np.empty(n)
        for k in range(steps):  # in place: allocation and np.clip's wrappers took a fifth of the loop
            np.subtract(X_ref[k], X[k], out=error)
            np.matmul(K[k], error, out=feedback)
            np.add(U[k], feedback, out=feedback)
            np.minimum(np.maximum(feedback, low, out=feedback), u_max, out=torques[k])  # np.clip's values
            ctrl[:] = torques[k]
            mujoco.mj_step(self._stepped, d)
            X[k + 1, :n] = qpos
            X[k + 1, n:] = qvel
        self._check_stable("the tracked rollout")
        self._remember(torques.tobytes(), X)
        return torques

    def _start(self) -> None:
        """Reset `data` (warnings and warm start included) and put it at x0."""
        mujoco.mj_resetData(self._stepped, self.data)
        self.data.qpos[:], self.data.qvel[:] = self.x0[:self.n], self.x0[self.n:]

    def _check_stable(self, what: str) -> None:
        """Raise SolverError if MuJoCo had to reset `data`'s simulation (`what` diverged)."""
        if any(self.data.warning.number[w] for w in UNSTABLE):
            raise SolverError(f"{what} diverged (MuJoCo reset the simulation)")

    def states(self, u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(U, X) at u without derivatives (a line search's trial point); the last point is cached."""
        key = u.tobytes()
        if self._cache.get("key") == key:
            U, X, _, _ = self._cache["value"]
            return U, X
        if key not in self._states:
            self._remember(key, self.rollout(u.reshape(self.steps, self.n)))
        return u.reshape(self.steps, self.n), self._states[key]

    def _remember(self, key: bytes, X: NDArray[np.float64]) -> None:
        """Keep X (N+1, 2n) as the states of the torques whose bytes are `key`: the last trial point's only."""
        self._states.clear()
        self._states[key] = X

    def jacobians(self, X: NDArray[np.float64], U: NDArray[np.float64]
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """A_k (N, 2n, 2n) and B_k (N, 2n, n) of one control period at each (x_k, u_k): analytic where the model's
        hinge tree reproduces this rollout (`mjtraj.core.planners.rigid_body`), else forward differences from the
        rollout's own steps X[k+1]; backward for a torque within eps of its control's upper end, which MuJoCo clamps
        (a forward difference there sees no effect, and a plan's torques sit on their bound). `jacobian_counts`
        counts the two kinds."""
        if self._rigid_body is not None and self.partial:
            A, B, reproduced = self._rigid_body.jacobians_where(X, U)
            missed = np.flatnonzero(~reproduced)
            if missed.size:
                A[missed], B[missed] = self.differenced(X, U, missed)
            self.jacobian_counts["analytic"] += int(reproduced.sum())
            self.jacobian_counts["differenced"] += missed.size
            return A, B
        if self._rigid_body is not None:
            found = self._rigid_body.jacobians(X, U)
            if found is not None:
                self.jacobian_counts["analytic"] += 1
                return found
        self.jacobian_counts["differenced"] += 1
        return self.differenced(X, U)

    def tree_jacobians(self, X: NDArray[np.float64], U: NDArray[np.float64]
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """A_k (M, 2n, 2n) and B_k (M, 2n, n) of one control period at each (x_k, u_k) (X (M, 2n), U (M, n)) by the
        model's hinge tree, not checked against MuJoCo's step (for feedback gains about a path that is no rollout of
        the model); None where the model has no tree."""
        if self._rigid_body is None:
            return None
        _, jacobian = self._rigid_body.step(X, U)
        return jacobian[:, :, :2 * self.n], jacobian[:, :, 2 * self.n:]

    def differenced(self, X: NDArray[np.float64], U: NDArray[np.float64], samples: NDArray[np.intp] | None = None
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """`jacobians` by forward differences of MuJoCo's step alone (all N (3n) perturbed steps in one batch), at
        every sample or at `samples` only (their A_k, B_k in that order)."""
        n = self.n
        samples = np.arange(self.steps) if samples is None else samples
        N = samples.size
        point = np.concatenate([X[samples], U[samples]], axis=1)
        steps = np.full((N, 3 * n), self.eps)
        steps[:, 2 * n:] = np.where(U[samples] + self.eps > self._ctrl_high, -self.eps, self.eps)
        z = (point[:, None, :] + steps[:, :, None] * np.eye(3 * n)[None]).reshape(-1, 3 * n)
        batch, (qpos, qvel, ctrl), reset_state = self._differencer
        rows = slice(0, N * 3 * n)
        batch.state[rows] = reset_state  # Batch.reset's rows, without the call
        qpos[rows], qvel[rows], ctrl[rows] = z[:, :n], z[:, n:2 * n], z[:, 2 * n:]
        batch.step(None if N == self.steps else np.arange(N * 3 * n), 1)
        after = np.concatenate([qpos[rows], qvel[rows]], axis=1).reshape(N, 3 * n, 2 * n)
        jac = ((after - X[samples + 1, None, :]) / steps[:, :, None]).transpose(0, 2, 1)
        return jac[:, :, :2 * n], jac[:, :, 2 * n:]

    @cached_property
    def _differencer(self) -> tuple[Batch, tuple[NDArray[np.float64], ...], NDArray[np.float64]]:
        """The batch of N (3n) simulations `differenced` steps, its qpos, qvel and ctrl, and a simulation's state as
        reset; made on first use (about 0.6 ms: a plan whose Jacobians are all analytic never needs it). On every
        CPU, but on one for the floor (`partial`), whose parallelism is across scenarios."""
        batch = Batch(self._stepped, self.steps * 3 * self.n, nthread=1 if self.partial else 0)
        batch.reset([0], stage=mujoco.mjtStage.mjSTAGE_NONE)
        return batch, (batch.bind("qpos"), batch.bind("qvel"), batch.bind("ctrl")), batch.state[0].copy()

    def evaluate(self, u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                                                        NDArray[np.float64]]:
        """(U, X, A, S) at u, where S (N+1, 2n, N n) holds dx_k/du; the last point is cached. S is one array that every
        evaluation fills again (1.5 MB at N = 100, n = 3, made once): it is valid until the next point is evaluated."""
        key = u.tobytes()
        if self._cache.get("key") != key:
            U, X = self.states(u)
            analytic = self.jacobian_counts["analytic"]
            A, B = self.jacobians(X, U)
            S = self._sensitivities
            _propagate(A, B, S)
            self._cache.update(key=key, value=(U, X, A, S), analytic=self.jacobian_counts["analytic"] > analytic)
        return self._cache["value"]  # type: ignore[no-any-return]

    def objective(self, u: NDArray[np.float64]) -> float:
        U, X = self.states(u)
        d = X[1:] - self.xg
        return 0.5 * float(np.sum((d @ self.Q) * d) + np.sum((U @ self.R) * U))

    def gradient(self, u: NDArray[np.float64]) -> NDArray[np.float64]:
        U, X, _, S = self.evaluate(u)
        d = X[1:] - self.xg
        return (U @ self.R).ravel() + (d @ self.Q.T).ravel() @ S[1:].reshape(-1, S.shape[2])

    @cached_property
    def _input_hessian(self) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """R's block diagonal (N n, N n), and where its (n, n) blocks sit; made on first use (a plan whose Hessian is
        diagonal never needs them)."""
        N, n = self.steps, self.n
        hessian = np.zeros((N * n, N * n))
        blocks = np.zeros((N * n, N * n), dtype=bool)
        on = np.arange(N)
        hessian.reshape(N, n, N, n)[on, :, on, :] = self.R
        blocks.reshape(N, n, N, n)[on, :, on, :] = True
        return hessian, blocks

    @cached_property
    def _sensitivities(self) -> NDArray[np.float64]:
        """The array `evaluate` fills, (N+1, 2n, N n), zero where it never writes."""
        return np.zeros((self.steps + 1, 2 * self.n, self.steps * self.n))

    @cached_property
    def diagonal_hessian(self) -> NDArray[np.float64] | None:
        """The Gauss-Newton Hessian's diagonal (N n,) where the Hessian is diagonal at every u (Q = 0 and a diagonal
        R: the effort bound's), else None."""
        if self.Q.any() or np.count_nonzero(self.R) != np.count_nonzero(np.diag(self.R)):
            return None
        return np.tile(np.diag(self.R), self.steps)  # type: ignore[no-any-return]

    def gauss_newton(self, u: NDArray[np.float64]) -> NDArray[np.float64]:
        """The objective's Gauss-Newton Hessian R (block diagonal) + sum_{k=1..N} S_k^T Q S_k at u, shape (N n, N n).

        Stage by stage: with P_N = Q and P_k = Q + A_k^T P_{k+1} A_k (the Q-weighted sum of the state's futures), its
        block (i, j), i <= j, is S_{j+1}[:, block i]^T P_{j+1} B_j, so the upper triangle's block column j is
        S_{j+1}^T (P_{j+1} B_j) (S_{j+1} is zero right of block j): N small products, not an (N 2n, N n) square.
        """
        _, _, A, S = self.evaluate(u)
        n, N = self.n, self.steps
        H, diagonal = self._input_hessian
        if not self.Q.any():
            return H.copy()
        Q = 0.5 * (self.Q + self.Q.T)
        P = np.empty((N + 1, 2 * n, 2 * n))
        P[N] = Q
        for k in range(N - 1, 0, -1):
            P[k] = Q + A[k].T @ P[k + 1] @ A[k]
        columns = np.matmul(S[1:].transpose(0, 2, 1), P[1:] @ input_blocks(S))  # (N, N n, n): the upper triangle's
        upper = columns.transpose(1, 0, 2).reshape(N * n, N * n)                # block columns
        return H + np.where(diagonal, upper, upper + upper.T)  # type: ignore[no-any-return]

    def second_order(self, u: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The Hessian (N n, N n) of sum_{k=1..N} w_k^T x_k(u), w (N+1, 2n) (w_0 unused): the dynamics' curvature
        that the Gauss-Newton Hessian leaves out, weighted by w (a Lagrangian's multipliers). None where the model's
        tree does not give this rollout's Jacobians (`jacobians`): its curvature would not be the plant's.

        Stage by stage: the adjoint p_k = w_{k+1} + A_{k+1}^T p_{k+1} (p_{N-1} = w_N) weights step k's next state; M_k,
        the Hessian of p_k^T x_{k+1} in (x_k, u_k) (`RigidBody.curvature`), enters as S_k^T Mxx_k S_k + the cross
        and input terms. With P_N = 0 and P_k = Mxx_k + A_k^T P_{k+1} A_k, block (i, j), i < j, is
        S_j[:, block i]^T (Mxu_j + A_j^T P_{j+1} B_j) and block (j, j) is Muu_j + B_j^T P_{j+1} B_j, as in
        `gauss_newton`.
        """
        U, X, A, S = self.evaluate(u)
        if not self._cache["analytic"]:
            return None
        assert self._rigid_body is not None
        n, N = self.n, self.steps
        p = np.empty((N, 2 * n))
        p[N - 1] = w[N]
        for k in range(N - 2, -1, -1):
            p[k] = w[k + 1] + A[k + 1].T @ p[k + 1]
        B = input_blocks(S)
        M = self._rigid_body.curvature(X[:-1], U, p, np.concatenate([A, B], axis=2))
        P = np.zeros((N + 1, 2 * n, 2 * n))
        for k in range(N - 1, 0, -1):
            P[k] = M[k, :2 * n, :2 * n] + A[k].T @ P[k + 1] @ A[k]
        PB = P[1:] @ B
        columns = np.matmul(S[:-1].transpose(0, 2, 1), M[:, :2 * n, 2 * n:] + A.transpose(0, 2, 1) @ PB)
        upper = columns.transpose(1, 0, 2).reshape(N * n, N * n)  # block (i, j) for i < j; zero on and below
        H = upper + upper.T
        blocks = np.arange(N)
        H.reshape(N, n, N, n)[blocks, :, blocks, :] += M[:, 2 * n:, 2 * n:] + B.transpose(0, 2, 1) @ PB
        return H  # type: ignore[no-any-return]


@njit
def _propagate(A: NDArray[np.float64], B: NDArray[np.float64], S: NDArray[np.float64]) -> None:
    """S_{k+1} = A_k S_k + [0 .. B_k .. 0] for k = 0..N-1 into S (N+1, 2n, N n), whose S_0 is zero: only the blocks
    left of k + 1 are written, the rest stays zero (x_{k+1} does not depend on later torques). Compiled: NumPy's 100
    small products took 0.23 ms, this 0.09."""
    N, two_n, n = B.shape
    for k in range(N):
        width = k * n
        for r in range(two_n):
            row = S[k + 1, r]
            for c in range(width):
                row[c] = 0.0
            for m in range(two_n):
                a = A[k, r, m]
                source = S[k, m]
                for c in range(width):
                    row[c] += a * source[c]
            for c in range(n):
                row[width + c] = B[k, r, c]


def input_blocks(S: NDArray[np.float64]) -> NDArray[np.float64]:
    """B_j = dx_{j+1}/du_j, (N, 2n, n), read from the sensitivities S (N+1, 2n, N n): S_{j+1}'s block j."""
    steps, n = S.shape[0] - 1, S.shape[2] // (S.shape[0] - 1)
    return np.stack([S[j + 1, :, j * n:(j + 1) * n] for j in range(steps)])


def _collision_free(model: mujoco.MjModel) -> mujoco.MjModel:
    """A copy of `model` with collision detection disabled if no contact can arise in it (no geom's contype
    matches another's conaffinity, no explicit pair, no flex), else `model` itself. Its steps are `model`'s bit for
    bit: detection that can find nothing changes nothing but the time."""
    types, affinities = model.geom_contype, model.geom_conaffinity
    if model.npair or model.nflex or (types[:, None] & affinities[None, :]).any():
        return model
    free = copy.copy(model)
    free.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    return free


@dataclass(frozen=True)
class PathLimits:
    """Every path constraint as rows h(U, X) >= 0 in natural units."""

    u_max: NDArray[np.float64]
    q_low: NDArray[np.float64]
    q_high: NDArray[np.float64]
    v_max: NDArray[np.float64]
    _scales: dict[int, NDArray[np.float64]] = field(default_factory=dict, compare=False, repr=False)

    def values(self, U: NDArray[np.float64], X: NDArray[np.float64]) -> NDArray[np.float64]:
        """h, shape (6 N n,): q_high - q, q - q_low, v_max - qd, v_max + qd (k = 1..N), u_max - u, u_max + u."""
        n = U.shape[1]
        q, qd = X[1:, :n], X[1:, n:]
        return np.concatenate([(self.q_high - q).ravel(), (q - self.q_low).ravel(), (self.v_max - qd).ravel(),
                               (self.v_max + qd).ravel(), (self.u_max - U).ravel(), (self.u_max + U).ravel()])

    def scale(self, steps: int) -> NDArray[np.float64]:
        """Each row's natural size, shape (6 N n,): half the range width, the speed limit, the torque bound; made
        once per `steps` (read-only)."""
        if steps not in self._scales:
            half = np.tile(0.5 * (self.q_high - self.q_low), steps)
            made = np.concatenate([half, half, np.tile(self.v_max, 2 * steps), np.tile(self.u_max, 2 * steps)])
            made.setflags(write=False)
            self._scales[steps] = made
        return self._scales[steps]

    def near(self, U: NDArray[np.float64], X: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Rows within reach of their limit (see SCREEN)."""
        return self.values(U, X) < (1.0 - SCREEN) * self.scale(U.shape[0])

    def jacobian(self, S: NDArray[np.float64], rows: NDArray[np.intp]) -> NDArray[np.float64]:
        """dh/du of `rows`, shape (len(rows), N n), from the sensitivities S (N+1, 2n, N n)."""
        n = S.shape[1] // 2
        size = S.shape[2]
        steps = S.shape[0] - 1
        state, sign, k, component, rest = _targets(rows, steps, n)
        out = np.zeros((len(rows), size))
        out[state] = sign[state, None] * S[k[state] + 1, component[state]]
        out[~state, rest[~state]] = sign[~state]  # torques: -+1 on u_k itself
        return out

    def on_states(self, rows: NDArray[np.intp], weights: NDArray[np.float64], steps: int, n: int
                  ) -> NDArray[np.float64]:
        """sum_r weights_r dh_r/dx_k over `rows`, (steps+1, 2n): the rows' weights on the states they bound (the
        range and speed rows are linear in x_k; the torque rows do not involve the states)."""
        state, sign, k, component, _ = _targets(rows, steps, n)
        out = np.zeros((steps + 1, 2 * n))
        np.add.at(out, (k[state] + 1, component[state]), sign[state] * weights[state])
        return out


def _targets(rows: NDArray[np.intp], steps: int, n: int
             ) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Where each path row of `PathLimits.values` acts: (a state row?, its sign in x or u, its sample k (x_{k+1} or
    u_k), its state component, its index within the group)."""
    group, rest = np.divmod(np.asarray(rows, dtype=np.intp), steps * n)
    k, joint = np.divmod(rest, n)
    sign = np.where(group % 2 == 0, -1.0, 1.0)  # the upper ends: -x; the lower: +x
    component = np.where(group < 2, joint, n + joint)  # ranges: q; speeds: qd
    return group < 4, sign, k, component, rest
