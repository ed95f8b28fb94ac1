"""The clairvoyant floor of J_exec: the least score any controller can reach on one execution.

For a deterministic plant with a known start and reference, every controller (classical, learned, predictive)
applies some sequence of corrective torques within the saturation. The floor minimises J_exec over all such sequences
on the true plant, among executions that reach the goal (the benchmark's goal rule, a terminal constraint):

    min_U  sum_{k=0..N-1} (x_k - x_ref,k)^T Q (x_k - x_ref,k) + u_k^T R u_k
    s.t.   x_{k+1} = F(x_k, u_k) (the plant's own MuJoCo step),  |u_k| <= limit,  |q_N - q_ref,N| <= goal_radius,

with Q, R the scenario's scoring weights (J_exec's; x_N is not scored, hence the terminal constraint). It is a
nonlinear least-squares problem with a box and one smooth inequality.

Protocol v2 (`mjtraj.core.settle`) scores the whole episode, the motion and the settle window that follows it (the
reference holding the goal q_g), and succeeds only at rest: its floor is the same problem over the episode's N + S
periods (J_settle) with the at-rest rule as the terminal constraint, 4 n linear rows on x_{N+S} instead of the ball
(`AtRest`): |q_{N+S} - q_g| <= band and |qd_{N+S}| <= speed, joint by joint. It is solved by a Gauss-Newton SQP on the
residual vector [sqrt(Q) (x_k - x_ref,k); sqrt(R) u_k]: the states' sensitivities to the torques come from the
nonlinear planners' single-shooting machinery (`mjtraj.core.planners.shooting` with `partial`: analytic step
Jacobians of the plant's hinge tree, its dry friction and per-link gravity compensation included, at every sample
whose step the tree reproduces, forward differences of MuJoCo's step at the others), the Gauss-Newton Hessian is
accumulated along the chain, each step's QP (the box, the linearised terminal constraint) is solved in closed form
where the box is not active and by DAQP where it is, and a Levenberg-Marquardt trust region on the l1 merit accepts
the steps. The starts (the executed torques of the controllers) are ranked and the best solved, or every one
(`every_start`), the lowest goal-reaching result kept. The problem is not convex: on a smooth plant (nominal,
aggressive) the starts agree to solver precision; with dry friction (the mismatch plants) the objective is not
smooth and the best found is an upper estimate of the true floor. The caller replays the torques through the one
closed loop (`mjtraj.domain.floor`), which is the floor's own check.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from mjtraj.checks import frozen
from mjtraj.core.planners.shooting import Shooting
from mjtraj.core.planners.sqp import _qp
from mjtraj.exceptions import InvalidInputError, MjtrajError, SolverError
from mjtraj.threads import single_blas_thread


@dataclass(frozen=True)
class FloorSettings:
    """The floor solver's tunables, with their rules (docs/floor.md, "The floor", gives the measurements behind
    them). Pass one to `clairvoyant_floor(settings=...)`; the defaults are the published floors'.

    Attributes:
      max_iter: Gauss-Newton iterations per start at most.
      stall: a start has converged when its feasible cost changes by less than this fraction between iterations.
      first_damping: the Levenberg-Marquardt damping a start begins with, relative to the Gauss-Newton Hessian's mean
        diagonal.
      accept: a trial step is accepted where the merit falls by at least this fraction of the QP model's predicted
        fall.
      max_damping: past this damping (a refused step doubles the growth of the next) the start has converged as far
        as the merit's model allows (at a kink of the dry friction).
      fd_eps: forward-difference step of the step Jacobians where they are differenced (as the nonlinear planners').
      goal_margin: the solves aim inside the terminal rule (the goal ball, or the at-rest band and speed) at this
        fraction of it, so that the replay's last bits keep it.
      feasible: a solve has converged only where the terminal rule's largest row exceeds the aimed bound by at most
        this fraction of it.
      reached: a start's result reaches the goal where that row exceeds the aimed bound by at most this fraction
        (still inside the rule: goal_margin leaves 1e-3; with DAQP 0.5, the declared floor, the last iterates
        approach the aimed bound from outside and stall near 3e-5 above it).
    """

    max_iter: int = 60
    stall: float = 1e-6
    first_damping: float = 1e-3
    accept: float = 1e-4
    max_damping: float = 1e4
    fd_eps: float = 1e-7
    goal_margin: float = 0.999
    feasible: float = 1e-5
    reached: float = 5e-4

    def __post_init__(self) -> None:
        for name, value in dataclasses.asdict(self).items():
            if not (np.isfinite(value) and value > 0) or (name == "goal_margin" and value > 1):
                bound = " and <= 1" if name == "goal_margin" else ""
                raise InvalidInputError(f"settings.{name}: expected a number > 0{bound}, got {value!r}")


DEFAULT_SETTINGS = FloorSettings()
"""The published floors' settings."""


@dataclass(frozen=True)
class AtRest:
    """Protocol v2's success rule as the floor's terminal constraint: at the episode's last state every joint within
    `band` (rad) of `goal` ((n,), rad) and slower than `speed` (rad/s)."""

    goal: NDArray[np.float64]
    band: float
    speed: float


@dataclass(frozen=True)
class FloorSolution:
    """The best goal-reaching torques found and how they were found.

    Attributes:
      torques: the applied corrective torques, shape (N, n), N m.
      cost: J_exec of their rollout on the plant (the solver's own evaluation; the replay is the caller's).
      terminal_err: |q_ref,N - q_N| of that rollout, rad (with `AtRest`: the largest joint's |q_N - q_g|).
      start: the name of the start it came from.
      iterations: Gauss-Newton iterations of that start.
      converged: that start's iterations stopped by the convergence test (not by settings.max_iter).
      starts: each start's final cost (inf where it did not reach the goal or failed, NaN where it was not solved).
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
    rest: AtRest | None = None
    """The at-rest rule the solve aims inside (its band and speed already narrowed by settings.goal_margin), in place
    of the ball."""

    def rollout(self, u: NDArray[np.float64]) -> tuple[float, Violation, NDArray[np.float64]]:
        """(J, the terminal constraint's value, X) at u (N n,): |q_N - q_ref,N| / radius - 1 (a float), or with
        `rest` the 4 n rows [dq / band; -dq / band; qd_N / speed; -qd_N / speed] - 1 (dq = q_N - q_g); <= 0 holds."""
        U, X = self.shooting.states(u)
        d = (X - self.x_ref)[:-1] * self.q_root
        cost = float(np.sum(d * d) + np.sum((U * self.r_root) ** 2))
        n = self.shooting.n
        if self.rest is not None:
            scaled = self._rest_scale() * np.concatenate([X[-1, :n] - self.rest.goal, X[-1, n:]])
            return cost, np.concatenate([scaled, -scaled]) - 1.0, X
        miss = X[-1, :n] - self.x_ref[-1, :n]
        return cost, float(np.linalg.norm(miss)) / self.radius - 1.0, X

    def _rest_scale(self) -> NDArray[np.float64]:
        """1 / band per joint position, 1 / speed per joint speed, (2n,)."""
        assert self.rest is not None
        n = self.shooting.n
        return np.concatenate([np.full(n, 1.0 / self.rest.band), np.full(n, 1.0 / self.rest.speed)])

    def linearised(self, u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                           NDArray[np.float64]]:
        """The Gauss-Newton Hessian J^T J (N n, N n), the gradient J^T r (N n,) (both of J_exec / 2) and the terminal
        constraint's gradient (N n,) at u (with `rest`: its rows' Jacobian, (4n, N n)).

        By the chain's structure rather than as the product of the (N-1) 2n by N n sensitivities: with W = Q and
        P_m = W + A_m^T P_{m+1} A_m (P_N = 0: x_N is not scored) the weight of everything from x_m on, the block
        (i, j), i <= j, is S_{j+1}[:, i]^T P_{j+1} B_j, and the gradient's block j is B_j^T lambda_{j+1} with
        lambda_m = W (x_m - x_ref,m) + A_m^T lambda_{m+1}: O(N^2 n^3) instead of O(N^3 n^3) (0.3 ms instead of
        1.6 at N = 100, n = 3)."""
        U, X, A, S = self.shooting.evaluate(u)
        N, n = U.shape
        W = self.q_root**2
        weights = np.diag(W)
        error = (X - self.x_ref) * W
        hessian = np.zeros((N * n, N * n))
        P = np.zeros((2 * n, 2 * n))
        adjoint = np.zeros(2 * n)
        gradient = np.empty(N * n)
        for j in range(N - 1, -1, -1):  # P and lambda at j + 1, then column block j
            if j + 1 < N:
                P = weights + A[j + 1].T @ P @ A[j + 1]
                adjoint = error[j + 1] + A[j + 1].T @ adjoint
            B = S[j + 1, :, j * n:(j + 1) * n]
            column = S[j + 1, :, :(j + 1) * n].T @ (P @ B)
            hessian[:(j + 1) * n, j * n:(j + 1) * n] = column
            hessian[j * n:(j + 1) * n, :j * n] = column[:j * n].T
            gradient[j * n:(j + 1) * n] = B.T @ adjoint
        hessian[np.diag_indices(N * n)] += np.tile(self.r_root**2, N)
        gradient += (U * self.r_root**2).ravel()
        if self.rest is not None:
            rows = self._rest_scale()[:, None] * S[N]
            return hessian, gradient, np.concatenate([rows, -rows])
        miss = X[-1, :n] - self.x_ref[-1, :n]
        size = max(float(np.linalg.norm(miss)), 1e-12 * self.radius)
        terminal = (miss @ S[N, :n]) / (size * self.radius)
        return hessian, gradient, terminal


Violation = float | NDArray[np.float64]
"""A terminal constraint's value at a point: the ball's one row (a float) or the at-rest rule's rows; <= 0 holds."""


def _excess(constraint: Violation) -> float:
    """The l1 merit's measure of a terminal constraint's violation: the sum of its rows' positive parts."""
    if isinstance(constraint, float):
        return max(0.0, constraint)
    return float(np.sum(np.maximum(constraint, 0.0)))


def _worst(constraint: Violation) -> float:
    """The largest row of a terminal constraint (<= 0: it holds)."""
    return constraint if isinstance(constraint, float) else float(np.max(constraint))


def _step(hessian: NDArray[np.float64], gradient: NDArray[np.float64], terminal: NDArray[np.float64],
          constraint: Violation, low: NDArray[np.float64], high: NDArray[np.float64]
          ) -> tuple[NDArray[np.float64], float]:
    """argmin 1/2 d^T H d + g^T d s.t. terminal d <= -constraint, low <= d <= high: (d, the terminal rows' largest
    multiplier). With one row (the ball) and the box not active the inequality is solved in closed form on H's
    Cholesky factor (0.5 ms at 300 torques); with the at-rest rows the unconstrained step is taken where it keeps
    them; else by DAQP (`mjtraj.core.planners.sqp._qp`, 1.5 ms)."""
    if terminal.ndim == 2:
        return _rows_step(hessian, gradient, terminal, np.asarray(constraint), low, high)
    assert isinstance(constraint, float)
    try:
        factor = scipy.linalg.cho_factor(hessian, lower=True, check_finite=False)
    except np.linalg.LinAlgError as e:
        raise SolverError("the floor's Gauss-Newton Hessian is not positive definite") from e
    free = -scipy.linalg.cho_solve(factor, gradient, check_finite=False)
    excess = constraint + float(terminal @ free)
    multiplier = 0.0
    if excess > 0.0:  # the linearised goal row binds: step back along H^-1 terminal onto it
        along = scipy.linalg.cho_solve(factor, terminal, check_finite=False)
        multiplier = excess / float(terminal @ along)
        free = free - multiplier * along
    if np.all(free >= low) and np.all(free <= high):
        return free, multiplier
    solved = _qp(hessian, gradient, np.zeros((0, gradient.size)), np.zeros(0), -terminal[None], np.array([-constraint]),
                 low, high, True)
    if solved is None:
        raise SolverError("the floor's QP has no solution within the torque box")
    step, multipliers = solved
    return step, float(np.abs(multipliers).max(initial=0.0))


def _rows_step(hessian: NDArray[np.float64], gradient: NDArray[np.float64], terminal: NDArray[np.float64],
               constraint: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], float]:
    """`_step` with several terminal rows (the at-rest rule's 4 n)."""
    try:
        factor = scipy.linalg.cho_factor(hessian, lower=True, check_finite=False)
    except np.linalg.LinAlgError as e:
        raise SolverError("the floor's Gauss-Newton Hessian is not positive definite") from e
    free = -scipy.linalg.cho_solve(factor, gradient, check_finite=False)
    if np.all(constraint + terminal @ free <= 0.0) and np.all(free >= low) and np.all(free <= high):
        return free, 0.0
    solved = _qp(hessian, gradient, np.zeros((0, gradient.size)), np.zeros(0), -terminal, -constraint, low, high,
                 True)
    if solved is None:
        raise SolverError("the floor's QP has no solution within the torque box")
    step, multipliers = solved
    return step, float(np.abs(multipliers).max(initial=0.0))


def _merit(cost: float, constraint: Violation, weight: float) -> float:
    return cost + weight * _excess(constraint)


def _solve(problem: _Problem, u: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64],
           settings: FloorSettings) -> tuple[NDArray[np.float64], float, Violation, int, bool]:
    """Gauss-Newton SQP from u with a Levenberg-Marquardt trust region: (u, cost, constraint, iterations,
    converged). Each trial step is the QP's at the current damping, taken whole and accepted where the l1 merit
    falls by at least `settings.accept` of what the QP's model predicts; the damping follows the ratio (Nielsen's
    rule), and a refused step is retried at more damping on the same linearisation (one rollout a trial, not a line
    search's several). Past `settings.max_damping` the start has converged as far as the merit's model allows (a
    kink of the dry friction)."""
    cost, constraint, _ = problem.rollout(u)
    weight = 10.0 * max(cost, 1e-12)
    damping, growth = settings.first_damping, 2.0
    iteration = 0
    linearised = None
    while True:
        if linearised is None:
            if iteration == settings.max_iter:
                return u, cost, constraint, settings.max_iter, False
            iteration += 1
            hessian, gradient, terminal = linearised = problem.linearised(u)
            scale = float(np.mean(np.diag(hessian)))
            diagonal = hessian.diagonal().copy()
        damped = hessian.copy()
        damped[np.diag_indices_from(damped)] = diagonal + damping * scale
        step, multiplier = _step(damped, gradient, terminal, constraint, low - u, high - u)
        weight = max(weight, 2.0 * multiplier + 1e-12)
        linear = terminal @ step
        after = constraint + (float(linear) if isinstance(constraint, float) else linear)
        predicted = (-(2.0 * float(gradient @ step) + float(step @ hessian @ step))
                     + weight * (_excess(constraint) - _excess(after)))
        trial = np.clip(u + step, low, high)
        try:
            c_trial, g_trial, _ = problem.rollout(trial)
            ratio = (_merit(cost, constraint, weight) - _merit(c_trial, g_trial, weight)) / predicted
        except SolverError:  # the trial's rollout diverged
            ratio = -np.inf
        if not predicted > 0.0 or not ratio >= settings.accept:
            damping, growth = max(damping, settings.first_damping) * growth, 2.0 * growth
            if damping > settings.max_damping:
                return u, cost, constraint, iteration, _worst(constraint) <= settings.feasible
            continue
        damping *= max(1.0 / 3.0, 1.0 - (2.0 * ratio - 1.0) ** 3)
        growth = 2.0
        previous = cost
        u, cost, constraint = trial, c_trial, g_trial
        linearised = None
        converged = abs(previous - cost) <= settings.stall * max(abs(cost), 1e-300)
        if _worst(constraint) <= settings.feasible and converged:
            return u, cost, constraint, iteration, True


def _check(q_ref: NDArray[np.float64], qd_ref: NDArray[np.float64], q_diag: NDArray[np.float64],
           r_diag: NDArray[np.float64], limit: NDArray[np.float64], starts: Mapping[str, NDArray[np.float64]],
           goal_radius: float | None, at_rest: AtRest | None) -> None:
    """InvalidInputError unless `clairvoyant_floor`'s arguments agree (shapes, a start, one terminal rule)."""
    n = q_ref.shape[1]
    if not starts:
        raise InvalidInputError("starts: expected at least one start, got none")
    if q_diag.shape != (2 * n,) or r_diag.shape != (n,) or limit.shape != (n,) or qd_ref.shape != q_ref.shape:
        raise InvalidInputError(f"q_ref, qd_ref, q_diag, r_diag, limit: expected shapes (N+1, {n}) twice, "
                                f"({2 * n},), ({n},), ({n},); got {q_ref.shape}, {qd_ref.shape}, {q_diag.shape}, "
                                f"{r_diag.shape}, {limit.shape}")
    if (goal_radius is None) == (at_rest is None):
        raise InvalidInputError(f"goal_radius, at_rest: expected exactly one terminal rule, got goal_radius="
                                f"{goal_radius!r}, at_rest={at_rest!r}")
    if at_rest is not None and (np.shape(at_rest.goal) != (n,) or not at_rest.band > 0 or not at_rest.speed > 0):
        raise InvalidInputError(f"at_rest: expected a goal of shape ({n},), a band and a speed > 0; got "
                                f"{np.shape(at_rest.goal)}, {at_rest.band!r}, {at_rest.speed!r}")


@single_blas_thread
def clairvoyant_floor(plant: mujoco.MjModel, q_ref: NDArray[np.float64], qd_ref: NDArray[np.float64],
                      q_diag: NDArray[np.float64], r_diag: NDArray[np.float64], limit: NDArray[np.float64], *,
                      starts: Mapping[str, NDArray[np.float64]], goal_radius: float | None = None,
                      at_rest: AtRest | None = None, first_fixed: bool = False, every_start: bool = False,
                      settings: FloorSettings = DEFAULT_SETTINGS) -> FloorSolution:
    """The least J_exec over corrective torques within `limit` that end within `goal_radius` of the goal (or, with
    `at_rest`, at rest at it: protocol v2's floor, whose reference is the whole episode, its settle window held).

    Args:
      plant: the true plant (its own fields set; one MuJoCo step is one control period; native gravity compensation).
      q_ref, qd_ref: the reference, shape (N+1, n), rad and rad/s; the plant starts at its first sample.
      q_diag, r_diag: J_exec's diagonal weights, (2n,) and (n,).
      limit: the saturation per joint, (n,), N m.
      goal_radius: the largest |q_N - q_ref,N| that reaches the goal, rad.
      at_rest: the at-rest rule at x_N instead (exactly one of the two).
      settings: the solver's tunables (`FloorSettings`; the default: the published floors').
      starts: name -> applied torques (N, n) to start a solve from (clipped into the box).
      first_fixed: the first period's torque is zero (a one-period actuation delay).
      every_start: solve from every start and keep the least result (the check that the starts agree). By default
        the starts are ranked, those that reach the goal first by their J_exec, the others after them by their l1
        merit, and only the first is solved (the next where it fails to reach the goal). The solve accepts only
        decreases of the merit, so the floor is never above a start that reached the goal. On smooth plants every
        start reaches the same floor; on the mismatched plants (dry friction) solving all of them lowers it a little
        at four times the time (docs/floor.md).

    Raises:
      InvalidInputError: shapes disagree, there is no start, or not exactly one terminal rule.
      SolverError: no start reached the goal.
    """
    clock = time.perf_counter()
    N, n = q_ref.shape[0] - 1, q_ref.shape[1]
    _check(q_ref, qd_ref, q_diag, r_diag, limit, starts, goal_radius, at_rest)
    x_ref = np.concatenate([q_ref, qd_ref], axis=1)
    shooting = Shooting(plant, x_ref[0].copy(), x_ref[-1].copy(), np.zeros((2 * n, 2 * n)), np.zeros((n, n)), N,
                        settings.fd_eps, partial=True)
    margin = settings.goal_margin
    aimed = None if at_rest is None else AtRest(np.asarray(at_rest.goal, dtype=np.float64), margin * at_rest.band,
                                                margin * at_rest.speed)
    problem = _Problem(shooting, x_ref, np.sqrt(q_diag), np.sqrt(r_diag),
                       settings.goal_margin * (goal_radius if goal_radius is not None else np.inf), aimed)
    high = np.tile(limit, N)
    low = -high
    if first_fixed:
        low[:n] = high[:n] = 0.0
    found: dict[str, float] = {name: float("nan") for name in starts}
    best: tuple[float, str, NDArray[np.float64], int, bool] | None = None
    ranked = []
    for name, torques in starts.items():
        start = np.clip(np.asarray(torques, dtype=np.float64).reshape(-1), low, high)
        if start.size != N * n:
            raise InvalidInputError(f"starts[{name!r}]: expected shape ({N}, {n}), got {np.shape(torques)}")
        try:
            cost, constraint, _ = problem.rollout(start)
        except MjtrajError:
            found[name] = float("inf")
            continue
        merit = _merit(cost, constraint, 10.0 * max(cost, 1e-12))
        ranked.append((_worst(constraint) > settings.reached, merit, name, start))
    for _, _, name, start in sorted(ranked, key=lambda r: r[:2]):
        try:
            u, cost, constraint, iterations, converged = _solve(problem, start, low, high, settings)
        except MjtrajError:
            found[name] = float("inf")
            continue
        reached = _worst(constraint) <= settings.reached
        found[name] = cost if reached else float("inf")
        if reached and (best is None or cost < best[0]):
            best = (cost, name, u, iterations, converged)
        if best is not None and not every_start:
            break
    if best is None:
        raise SolverError(f"the floor: no start reached the goal ({', '.join(found)})")
    cost, name, u, iterations, converged = best
    _, X = shooting.states(u)
    terminal = (float(np.linalg.norm(X[-1, :n] - q_ref[-1])) if at_rest is None
                else float(np.max(np.abs(X[-1, :n] - at_rest.goal))))
    return FloorSolution(frozen(u.reshape(N, n).copy()), cost, terminal, name, iterations, converged, found,
                         time.perf_counter() - clock)
