"""The clairvoyant floor of J_exec: the least score any controller can reach on one execution.

For a deterministic plant with a known start and reference, every controller (classical, learned, predictive)
applies some sequence of corrective torques within the saturation. The floor minimises J_exec over all such sequences
on the true plant, among executions that reach the goal (the benchmark's goal rule, a terminal constraint):

    min_U  sum_{k=0..N-1} (x_k - x_ref,k)^T Q (x_k - x_ref,k) + u_k^T R u_k
    s.t.   x_{k+1} = F(x_k, u_k) (the plant's own MuJoCo step),  |u_k| <= limit,  |q_N - q_ref,N| <= goal_radius,

with Q, R the scenario's scoring weights (J_exec's; x_N is not scored, hence the terminal constraint). It is a
nonlinear least-squares problem with a box and one smooth inequality. It is solved by a Gauss-Newton SQP on the
residual vector [sqrt(Q) (x_k - x_ref,k); sqrt(R) u_k]: the states' sensitivities to the torques come from the
nonlinear planners' single-shooting machinery (`mjtraj.core.planners.shooting`, analytic step Jacobians where the
plant's hinge tree reproduces MuJoCo's step, else forward differences), each QP (the box, the linearised terminal
constraint) by DAQP, an Armijo line search on the l1 merit. Several starts (the executed torques of the controllers)
are run and the lowest goal-reaching result kept. The problem is not convex: on a smooth plant (nominal, aggressive)
the starts agree to solver precision; with dry friction (the mismatch plants) the objective is not smooth and the
best found is an upper estimate of the true floor. The caller replays the torques through the one closed loop
(`mjtraj.study.floor`), which is the floor's own check.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import frozen
from mjtraj.core.planners.shooting import Shooting
from mjtraj.core.planners.sqp import _qp
from mjtraj.exceptions import InvalidInputError, MjtrajError, SolverError
from mjtraj.threads import single_blas_thread

MAX_ITER = 60
"""Gauss-Newton iterations per start at most."""
STALL = 1e-10
"""A start has converged when its feasible cost changes by less than this fraction between iterations."""
HALVINGS = 10
"""Backtracking halvings of a step before the step is refused (t >= 2^-9)."""
MAX_DAMPING = 1e2
"""A refused step multiplies the Levenberg-Marquardt damping (relative to the Hessian's mean diagonal) by 100, from
1e-4; past this the start has converged as far as the merit's model allows (at a kink of the dry friction)."""
FD_EPS = 1e-7
"""Forward-difference step of the step Jacobians where they are differenced (as the nonlinear planners')."""
GOAL_MARGIN = 0.999
"""The solves aim inside the goal ball, at this fraction of its radius, so that the replay's last bits keep it."""
FEASIBLE = 1e-5
"""A solve has converged only where |q_N - q_ref,N| exceeds the aimed radius by at most this fraction of it."""
REACHED = 5e-4
"""A start's result reaches the goal where |q_N - q_ref,N| exceeds the aimed radius by at most this fraction of it:
still inside the goal ball (GOAL_MARGIN leaves 1e-3). With DAQP 0.5 (the declared floor) the solves' last iterates
approach the aimed radius from outside and stall near 3e-5 above it."""


@dataclass(frozen=True)
class FloorSolution:
    """The best goal-reaching torques found and how they were found.

    Attributes:
      torques: the applied corrective torques, shape (N, n), N m.
      cost: J_exec of their rollout on the plant (the solver's own evaluation; the replay is the caller's).
      terminal_err: |q_ref,N - q_N| of that rollout, rad.
      start: the name of the start it came from.
      iterations: Gauss-Newton iterations of that start.
      converged: that start's iterations stopped by the convergence test (not by MAX_ITER).
      starts: each start's final cost (inf where it did not reach the goal or failed).
      seconds: wall time of the whole solve, s.
    """

    torques: NDArray[np.float64]
    cost: float
    terminal_err: float
    start: str
    iterations: int
    converged: bool
    starts: Mapping[str, float]
    seconds: float


@dataclass
class _Problem:
    """J_exec's residuals on the plant: rollout and sensitivities by `Shooting`, scoring by the weights."""

    shooting: Shooting
    x_ref: NDArray[np.float64]
    """(N+1, 2n): [q_ref; qd_ref]."""
    q_root: NDArray[np.float64]
    """sqrt(diag Q), (2n,)."""
    r_root: NDArray[np.float64]
    """sqrt(diag R), (n,)."""
    radius: float
    """The goal ball's radius the solve aims at, rad."""

    def rollout(self, u: NDArray[np.float64]) -> tuple[float, float, NDArray[np.float64]]:
        """(J_exec, |q_N - q_ref,N| / radius - 1, X) at u (N n,)."""
        U, X = self.shooting.states(u)
        d = (X - self.x_ref)[:-1] * self.q_root
        cost = float(np.sum(d * d) + np.sum((U * self.r_root) ** 2))
        n = self.shooting.n
        miss = X[-1, :n] - self.x_ref[-1, :n]
        return cost, float(np.linalg.norm(miss)) / self.radius - 1.0, X

    def linearised(self, u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                           NDArray[np.float64]]:
        """The Gauss-Newton Hessian J^T J (N n, N n), the gradient J^T r (N n,) (both of J_exec / 2) and the terminal
        constraint's gradient (N n,) at u."""
        U, X, _, S = self.shooting.evaluate(u)
        N, n = U.shape
        states = S[1:N] * self.q_root[None, :, None]  # x_0 is fixed: k = 1..N-1
        flat = states.reshape(-1, N * n)
        residual = ((X - self.x_ref)[1:N] * self.q_root).ravel()
        hessian = flat.T @ flat
        hessian[np.diag_indices(N * n)] += np.tile(self.r_root**2, N)
        gradient = flat.T @ residual + (U * self.r_root**2).ravel()
        miss = X[-1, :n] - self.x_ref[-1, :n]
        size = max(float(np.linalg.norm(miss)), 1e-12 * self.radius)
        terminal = (miss @ S[N, :n]) / (size * self.radius)
        return hessian, gradient, terminal


def _merit(cost: float, constraint: float, weight: float) -> float:
    return cost + weight * max(0.0, constraint)


def _solve(problem: _Problem, u: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64]
           ) -> tuple[NDArray[np.float64], float, float, int, bool]:
    """Gauss-Newton SQP from u: (u, cost, constraint, iterations, converged)."""
    cost, constraint, _ = problem.rollout(u)
    weight = 10.0 * max(cost, 1e-12)
    damping = 0.0
    for iteration in range(1, MAX_ITER + 1):
        hessian, gradient, terminal = problem.linearised(u)
        scale = float(np.mean(np.diag(hessian)))
        hessian[np.diag_indices_from(hessian)] += damping * scale
        solved = _qp(hessian, gradient, np.zeros((0, u.size)), np.zeros(0), -terminal[None], np.array([-constraint]),
                     low - u, high - u, True)
        if solved is None:
            raise SolverError("the floor's QP has no solution within the torque box")
        step, multipliers = solved
        weight = max(weight, 2.0 * float(np.abs(multipliers).max(initial=0.0)) + 1e-12)
        now = _merit(cost, constraint, weight)
        slope = float(gradient @ step) * 2.0 - weight * max(0.0, constraint)
        t, accepted = 1.0, False
        for _ in range(HALVINGS):
            trial = np.clip(u + t * step, low, high)
            try:
                c_trial, g_trial, _ = problem.rollout(trial)
            except SolverError:
                t *= 0.5
                continue
            if _merit(c_trial, g_trial, weight) <= now + 1e-4 * t * min(slope, 0.0):
                accepted = True
                break
            t *= 0.5
        if not accepted:  # a kink of the dry friction, or a poor model of the merit: trust the model less
            if damping < MAX_DAMPING:
                damping = max(100.0 * damping, 1e-4)
                continue
            return u, cost, constraint, iteration, constraint <= FEASIBLE
        damping = damping / 4.0 if t == 1.0 else damping
        previous = cost
        u, cost, constraint = trial, c_trial, g_trial
        if constraint <= FEASIBLE and abs(previous - cost) <= STALL * max(abs(cost), 1e-300):
            return u, cost, constraint, iteration, True
    return u, cost, constraint, MAX_ITER, False


@single_blas_thread
def clairvoyant_floor(plant: mujoco.MjModel, q_ref: NDArray[np.float64], qd_ref: NDArray[np.float64],
                      q_diag: NDArray[np.float64], r_diag: NDArray[np.float64], limit: NDArray[np.float64], *,
                      goal_radius: float, starts: Mapping[str, NDArray[np.float64]], first_fixed: bool = False
                      ) -> FloorSolution:
    """The least J_exec over corrective torques within `limit` that end within `goal_radius` of the goal.

    Args:
      plant: the true plant (its own fields set; one MuJoCo step is one control period; native gravity compensation).
      q_ref, qd_ref: the reference, shape (N+1, n), rad and rad/s; the plant starts at its first sample.
      q_diag, r_diag: J_exec's diagonal weights, (2n,) and (n,).
      limit: the saturation per joint, (n,), N m.
      goal_radius: the largest |q_N - q_ref,N| that reaches the goal, rad.
      starts: name -> applied torques (N, n) to start a solve from (clipped into the box).
      first_fixed: the first period's torque is zero (a one-period actuation delay).

    Raises:
      InvalidInputError: shapes disagree, or there is no start.
      SolverError: no start reached the goal.
    """
    clock = time.perf_counter()
    N, n = q_ref.shape[0] - 1, q_ref.shape[1]
    if not starts:
        raise InvalidInputError("starts: expected at least one start, got none")
    if q_diag.shape != (2 * n,) or r_diag.shape != (n,) or limit.shape != (n,) or qd_ref.shape != q_ref.shape:
        raise InvalidInputError(f"q_ref, qd_ref, q_diag, r_diag, limit: expected shapes (N+1, {n}) twice, "
                                f"({2 * n},), ({n},), ({n},); got {q_ref.shape}, {qd_ref.shape}, {q_diag.shape}, "
                                f"{r_diag.shape}, {limit.shape}")
    x_ref = np.concatenate([q_ref, qd_ref], axis=1)
    shooting = Shooting(plant, x_ref[0].copy(), x_ref[-1].copy(), np.zeros((2 * n, 2 * n)), np.zeros((n, n)), N,
                        FD_EPS)
    problem = _Problem(shooting, x_ref, np.sqrt(q_diag), np.sqrt(r_diag), GOAL_MARGIN * goal_radius)
    high = np.tile(limit, N)
    low = -high
    if first_fixed:
        low[:n] = high[:n] = 0.0
    found: dict[str, float] = {}
    best: tuple[float, str, NDArray[np.float64], int, bool] | None = None
    for name, torques in starts.items():
        start = np.clip(np.asarray(torques, dtype=np.float64).reshape(-1), low, high)
        if start.size != N * n:
            raise InvalidInputError(f"starts[{name!r}]: expected shape ({N}, {n}), got {np.shape(torques)}")
        try:
            u, cost, constraint, iterations, converged = _solve(problem, start, low, high)
        except MjtrajError:
            found[name] = float("inf")
            continue
        found[name] = cost if constraint <= REACHED else float("inf")
        if constraint <= REACHED and (best is None or cost < best[0]):
            best = (cost, name, u, iterations, converged)
    if best is None:
        raise SolverError(f"the floor: no start reached the goal ({', '.join(found)})")
    cost, name, u, iterations, converged = best
    _, X = shooting.states(u)
    terminal = float(np.linalg.norm(X[-1, :n] - q_ref[-1]))
    return FloorSolution(frozen(u.reshape(N, n).copy()), cost, terminal, name, iterations, converged, found,
                         time.perf_counter() - clock)
