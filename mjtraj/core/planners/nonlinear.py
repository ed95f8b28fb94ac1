"""The paper's objective on the true nonlinear dynamics, with the joint ranges and the speed limit enforced.

min 1/2 sum_{k=1..N} (x_k - x_g)^T Q (x_k - x_g) + 1/2 sum_{k=0..N-1} u_k^T R u_k  over the corrective torques u_k,
subject to x_{k+1} = F(x_k, u_k) (one control period of the nominal MuJoCo model: RK4, gravity compensated, the
plant itself), x_N = x_g = [qg; 0], |u_k| <= u_max, and at every sample k = 1..N q_k within the joint ranges
(`NonlinearSettings.range_margin` inside) and |qd_k| <= the speed limit. `nonlinear_min_effort` is the case Q = 0:
the least corrective effort with which the nominal arm can make the move, the effort bound of the study.

Method: sequential quadratic programming in single-shooting form (`mjtraj.core.planners.shooting`). The variables
are the N n torques; every iterate is rolled out exactly on the model, so every plan is realisable. The transition's
Jacobians A_k, B_k are analytic where Pinocchio holds the model and the tree reproduces the rollout to 1e-9 (the
forward dynamics' derivatives, compiled by numba, chained through the RK4 stages, `mjtraj.core.planners.rigid_body`
and `tree_dynamics`), else forward
finite differences of mj_step about the rollout's own steps (backward for a torque on its control's upper end, where
MuJoCo clamps), all N (3n) perturbed steps in one mujoco.batch call (MuJoCo's mjd_transitionFD does not support
RK4); the plan's info counts each kind. Forward sensitivities dx_k/dU give the constraints' Jacobians and
the objective's gradient. The path constraints (ranges, speed, torque) are screened: only rows within reach of their
limit enter a solve; the returned plan is checked against every constraint. The start is the linear optimal
planner's plan for the same weights when its rollout keeps every path constraint, else the linear minimum-effort
plan (Q = 0: the zero-order-held slow move). Where a solver fails from it (with keep='lowest', always), it starts
once more from the tracked start: the torques with which the model follows that linear plan's states under LQR
feedback (on some tasks the open-loop torques drift into a joint's end, where the linearised terminal condition
cannot be met). The problem is not convex: the plan is a local minimum, reached from its start (the plan's info says
which). Where the SQP stops short from both starts, the least violation of the constraints is sought from where it
stopped (`mjtraj.core.planners.restoration`): a feasible point found, the SQP runs again from it; a positive least
violation from both, the task is reported infeasible, locally (a stationary point of the violation, not a proof);
else SLSQP decides. Two solvers (see SOLVERS):

- the Gauss-Newton SQP (`mjtraj.core.planners.sqp`): about 8 iterations with the paper's weights (0.06 s at N = 100 on
  one core), and 10 to 20 with Q = 0 from each start (0.08 s for a bound plan); from its 21st iteration at the latest
  its Hessian is the Lagrangian's (`SqpSettings.second_order_after`), with which the solves that Gauss-Newton's
  linear convergence left to SLSQP converge. The default of both planners ('auto': SLSQP where it does not
  converge). `nonlinear_optimal` keeps the plan from the first start from which it converges,
  `nonlinear_min_effort` runs it from both starts and keeps the lower plan (`keep`; see KEEPS): a bound is a
  minimum, and with Q = 0 the starts can reach different local minima (on the paper task 0.0985 from the linear
  start, a strict local minimum, and 0.0613 from the tracked one). The second start's solve is given the first
  start's plan and stops once it comes within `SqpSettings.join_distance` of it (heading for the same minimum);
- scipy's SLSQP, which keeps a quasi-Newton model of the Lagrangian's curvature, the dynamics' second derivatives
  included. That model starts at the identity, so the solve runs in variables v = L^T u in which the identity is a
  multiple of the Gauss-Newton Hessian (see `_Metric`): without this SLSQP spent one iteration per variable
  learning the objective's scale (on the paper task `nonlinear_optimal` took 499 iterations; 207 with it). Rows
  left out that an iterate violates enter a new solve. Objective and constraints are scaled to order one at the
  start. A solve that fails (SLSQP's own failure, a constraint left violated, an iterate whose rollout diverged) is
  tried once more with `NonlinearSettings.retry_factor` times the curvature scale. SLSQP's path is sensitive to
  the last bits of its inputs, so the plan is the same bit for bit only under the same BLAS thread count (the
  `mjtraj` command and sweep workers use one). A plan at N = 100 takes about half a second, some a minute.

Both planners are registered on request (`mjtraj bench planners` prints their times): they are bounds for the audit,
not planners for the inner loop, and never run unless named. Their tunables besides the planners' options are
`NonlinearSettings` (the SQP's nested, `mjtraj.core.planners.sqp.SqpSettings`), passed as `settings=`; docs/design.md
("The nonlinear planners' settings") gives the measurements behind their defaults.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import mujoco
import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from mjtraj.checks import choice, in_range, nonnegative_int, positive, positive_int
from mjtraj.core.linearize import discretize_zoh, linearize_many
from mjtraj.core.model import JointInfo
from mjtraj.core.planners.base import Planner, register
from mjtraj.core.planners.optimal import Optimal, check_weight_options, planner_weights
from mjtraj.core.planners.restoration import LeastViolation, least_violation
from mjtraj.core.planners.shooting import PathLimits, Shooting
from mjtraj.core.planners.sqp import SqpResult, SqpSettings, changes, gauss_newton_sqp
from mjtraj.core.planners.tracking import bryson_gains
from mjtraj.core.reference import Reference
from mjtraj.core.scoring import JOINT_SPEED_LIMIT
from mjtraj.core.task import Task
from mjtraj.exceptions import InfeasibleError, InvalidInputError, SolverError


@dataclass(frozen=True)
class NonlinearSettings:
    """The nonlinear planners' tunables besides their options, each with its rule; the defaults are the published
    plans'. docs/design.md, "The nonlinear planners' settings", gives the measurements behind each default.

    Pass one as `make("nonlinear_optimal", settings=NonlinearSettings(...))` (or to `nonlinear_min_effort`), the
    SQP's inside it: `NonlinearSettings(sqp=SqpSettings(stall=1e-8))`. A plan's info records the settings that
    differ from the defaults under 'settings' (`changes`, joined by '; ': 'sqp.stall=1e-08; retry_factor=10.0'); a
    plan made with the defaults has no such key, so the published records read as before.

    Raises:
      InvalidInputError: a value out of its range (the message names it as `settings.NAME`).
    """

    sqp: SqpSettings = field(default_factory=SqpSettings)
    """The Gauss-Newton SQP's (`mjtraj.core.planners.sqp.SqpSettings`)."""
    retry_factor: float = 30.0
    """An SLSQP solve from the linear start that fails is tried once more with this multiple of the planner's
    `curvature_scale` (shorter first steps)."""
    max_rounds: int = 8
    """SLSQP solves of one start, each with the path rows the last one violated added, before the start fails."""
    slsqp_max_torques: int = 400
    """'auto' turns to SLSQP only where the plan has at most this many torques (N n; SLSQP factors a dense matrix of
    them every iteration); above it a plan the Gauss-Newton SQP does not converge is refused with that reason."""
    range_margin: float = 1e-4
    """rad: the plans keep this far inside each joint's range (less where the start or the goal is nearer its end),
    clear of MuJoCo's range constraint, a force the rollout's derivatives do not see."""

    def __post_init__(self) -> None:
        if not isinstance(self.sqp, SqpSettings):
            raise InvalidInputError(f"settings.sqp: expected an SqpSettings (mjtraj.core.planners.sqp), got "
                                    f"{self.sqp!r}")
        checked = {"retry_factor": positive("settings.retry_factor", self.retry_factor),
                   "max_rounds": positive_int("settings.max_rounds", self.max_rounds),
                   "slsqp_max_torques": nonnegative_int("settings.slsqp_max_torques", self.slsqp_max_torques),
                   "range_margin": in_range("settings.range_margin", self.range_margin, 0.0, np.inf,
                                            low_open=False)}
        for name, value in checked.items():
            object.__setattr__(self, name, value)  # normalised: floats and ints

    def changes(self) -> list[str]:
        """The settings that differ from the defaults, as 'name=value' in field order, the SQP's as
        'sqp.name=value' ([]: the defaults)."""
        return changes(self)


DEFAULT_SETTINGS = NonlinearSettings()
"""The published plans' settings."""


@dataclass(frozen=True)
class _Metric:
    """The change of variables v = L^T u under which SLSQP's quasi-Newton model, which starts at the identity, starts
    at H = L L^T: `curvature_scale` times the scaled objective's Gauss-Newton Hessian R + sum_k S_k^T Q S_k at u."""

    L: NDArray[np.float64]

    @classmethod
    def at(cls, problem: Shooting, u: NDArray[np.float64], scale: float) -> _Metric:
        """The metric of `problem` at u (N n,), the objective multiplied by `scale`."""
        H = problem.gauss_newton(u)
        return cls(np.linalg.cholesky(scale * 0.5 * (H + H.T)))

    def to_v(self, u: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.L.T @ u

    def to_u(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        return scipy.linalg.solve_triangular(self.L.T, v, lower=False)  # type: ignore[no-any-return]

    def pull(self, jac: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rows of derivatives in u, shape (m, N n), as derivatives in v: jac L^-T."""
        return scipy.linalg.solve_triangular(self.L, jac.T, lower=True).T  # type: ignore[no-any-return]


SOLVERS = ("auto", "sqp", "slsqp")
"""The nonlinear planners' solvers (see NonlinearOptimal.solver). The Gauss-Newton SQP ignores the dynamics' second
derivatives; with the paper's state weight Q they are small against Q and it converges in about 8 iterations to
SLSQP's optimum. With Q = 0 (the effort bound), weighted by the terminal condition's multipliers, they are of the
order of R: it converges more slowly (10 to 20 iterations, some over 40, hence the Lagrangian's Hessian from the
21st at the latest, `SqpSettings.second_order_after`), and from different starts it can reach different local
minima, as SLSQP can. On the paper task the SQP from the linear start stops at 0.0985, a strict local minimum
(second-order sufficiency is tested with the Lagrangian's exact Hessian), and from the tracked start at 0.0613,
SLSQP's; hence keep='lowest' for the bound (KEEPS)."""
CONSTRAINT_NAMES = ("the joint range (upper end)", "the joint range (lower end)", "the joint speed limit",
                    "the joint speed limit", "the torque bound", "the torque bound")


KEEPS = ("first", "lowest")
"""Which plan the Gauss-Newton SQP returns: 'first' = the plan from the first start (in START_NAMES order) from which
it converges; 'lowest' = it runs from every start and keeps the plan of least objective. The problem is not convex,
and the starts can reach different local minima (see SOLVERS)."""
START_NAMES = ("linear", "tracked")
"""The solvers' starts, in the order tried (see `NonlinearOptimal._start` and `_tracked_start`). A plan's info names
its start: one of these, or 'restored' (the SQP stopped short from both, and ran again from a feasible point that
the least violation's search found, `NonlinearOptimal._restored`)."""


class _Starts:
    """The starts of one plan by name: the linear one given, the tracked one computed when first asked for."""

    def __init__(self, linear: NDArray[np.float64], tracked: Callable[[], NDArray[np.float64]]) -> None:
        self._made: dict[str, NDArray[np.float64]] = {"linear": linear}
        self._tracked = tracked

    def get(self, name: str) -> NDArray[np.float64]:
        """The start `name` (N n,).

        Raises:
          SolverError: the tracked rollout diverged.
        """
        if name not in self._made:
            self._made[name] = self._tracked()
        return self._made[name]


@register("nonlinear_optimal", on_request=True)
@dataclass(frozen=True)
class NonlinearOptimal(Planner):
    """The optimal planner's objective on the nominal nonlinear model (module docstring).

    Attributes:
      state_weight, input_weight, alpha, split: the weights, exactly as the optimal planner's (Bryson's rule by
        default; see `mjtraj.core.planners.optimal.Optimal`).
      torque_bound: |u_k| bound, shape (n,) or scalar, N m; None for the model's ctrlrange.
      speed_limit: |qd_k| bound on every joint, rad/s (default pi, the UR5's rated joint speed).
      max_iter: SLSQP iterations per solve.
      tol: SLSQP's tolerance on the scaled objective; the plan must also meet x_N = x_g to 1e-8 and every path
        constraint to 1e-8 (relative to its limit).
      fd_eps: forward-difference step of the transition Jacobians where they are differenced.
      curvature_scale: SLSQP's quasi-Newton model starts at this multiple of the Gauss-Newton Hessian (see `_Metric`);
        larger values take shorter first steps. The problem is not convex, and the value decides which local
        minimum SLSQP finds (docs/design.md, "The nonlinear planners' settings", has the measurements behind 30).
      solver: 'auto' (the default) = the Gauss-Newton SQP (`mjtraj.core.planners.sqp`) for at most sqp_max_iter
        iterations from each start, then SLSQP if it has not converged from either; 'sqp' = the Gauss-Newton SQP
        alone (an error if it does not converge from either start); 'slsqp' = SLSQP alone (see SOLVERS).
      sqp_max_iter: the Gauss-Newton SQP's iterations from each start, after which 'auto' turns to SLSQP (40 by the
        validation rule of docs/design.md, "The nonlinear planners' settings").
      keep: which of the Gauss-Newton SQP's plans (see KEEPS): 'first' here, 'lowest' for nonlinear_min_effort.
      settings: the solvers' tunables (`NonlinearSettings`, the SQP's nested; the default: the published plans').
        A plan's info records those that differ from the defaults ('settings').
    """

    state_weight: tuple[float, ...] | None = None
    input_weight: tuple[float, ...] | None = None
    alpha: float = 1.0
    split: float = 0.5
    torque_bound: float | tuple[float, ...] | None = None
    speed_limit: float = float(JOINT_SPEED_LIMIT)
    max_iter: int = 1000
    tol: float = 1e-10
    fd_eps: float = 1e-7
    curvature_scale: float = 30.0
    solver: str = "auto"
    sqp_max_iter: int = 40
    keep: str = "first"
    settings: NonlinearSettings = DEFAULT_SETTINGS
    name: ClassVar[str] = "nonlinear_optimal"

    def __post_init__(self) -> None:
        check_weight_options(self)
        choice("solver", self.solver, SOLVERS)
        choice("keep", self.keep, KEEPS)
        positive_int("sqp_max_iter", self.sqp_max_iter)
        positive("speed_limit", self.speed_limit)
        positive_int("max_iter", self.max_iter)
        positive("tol", self.tol)
        positive("fd_eps", self.fd_eps)
        positive("curvature_scale", self.curvature_scale)
        if not isinstance(self.settings, NonlinearSettings):
            raise InvalidInputError(f"settings: expected a NonlinearSettings (mjtraj.core.planners.nonlinear), got "
                                    f"{self.settings!r}")
        self.linear()  # validates torque_bound now

    def linear(self) -> Optimal:
        """The linear optimal planner with these weights and bound: the starting guess."""
        return Optimal(state_weight=self.state_weight, input_weight=self.input_weight, alpha=self.alpha,
                       split=self.split, torque_bound=self.torque_bound)

    def plan(self, task: Task, model: mujoco.MjModel) -> Reference:
        """Plan `task` on the nominal `model`.

        Raises:
          InfeasibleError: the linearised arm cannot make the move within the torque bound (no start), the least
            violation of the constraints is positive from every start at which the SQP stopped (local
            infeasibility, `_restored`), or no plan meets every constraint (names which).
          SolverError: SLSQP failed (its message).
        """
        clock = time.perf_counter()
        problem, limits, starts = self.problem(task, model)
        if self.solver != "slsqp":
            failures = []
            found: list[tuple[float, str, SqpResult]] = []
            stopped: list[tuple[str, NDArray[np.float64]]] = []  # the SQP's last iterates where it stopped short
            for name in START_NAMES:
                try:
                    result, failure = self._sqp(problem, limits, starts.get(name), found[0][2].u if found else None)
                except SolverError as e:
                    failures.append(f"from the {name} start: {e}")
                    continue
                if failure is None:
                    found.append((problem.objective(result.u), name, result))
                    if self.keep == "first":
                        break
                else:
                    failures.append(f"from the {name} start: {failure}")
                    stopped.append((name, result.u))
            if not found and stopped:
                found = self._restored(problem, limits, stopped, failures)
            if found:
                objective, name, result = min(found, key=lambda plan: plan[0])  # the first of equals
                U, X = problem.states(result.u)
                return self._reference(task, U, X, objective, "sqp", name, result.iterations, 1, result.rows, 0,
                                       time.perf_counter() - clock, problem.jacobian_counts, converged=len(found))
            failure = "; ".join(failures)
            if self.solver == "sqp":
                raise SolverError(f"{self.name}: the Gauss-Newton SQP stopped {failure}")
            cap = self.settings.slsqp_max_torques
            if problem.steps * problem.n > cap:
                raise SolverError(f"{self.name}: the Gauss-Newton SQP stopped {failure}; SLSQP, the fallback, is not "
                                  f"run on more than {cap} torques (N n = {problem.steps * problem.n}: "
                                  f"it factors a dense matrix of them every iteration; solver='slsqp' runs it anyway)")
            try:
                u, name, rounds, iterations, rows, retried = self._slsqp(problem, limits, starts)
            except (InfeasibleError, SolverError) as e:
                raise type(e)(f"{e} (before SLSQP, the Gauss-Newton SQP stopped {failure})") from None
        else:
            u, name, rounds, iterations, rows, retried = self._slsqp(problem, limits, starts)
        U, X, _, _ = problem.evaluate(u)
        return self._reference(task, U, X, problem.objective(u), "slsqp", name, iterations, rounds, rows, retried,
                               time.perf_counter() - clock, problem.jacobian_counts)

    def problem(self, task: Task, model: mujoco.MjModel) -> tuple[Shooting, PathLimits, _Starts]:
        """`task`'s problem on `model` as `plan` solves it: the shooting problem, its path limits (the joint ranges
        `settings.range_margin` inside), and its starts.

        Raises:
          InfeasibleError: the linearised arm cannot make the move within the torque bound (no start).
        """
        joints = JointInfo.of(model)
        task.check_limits(model, joints)
        bound = self.linear().bounds(task, model, joints)
        n = task.n
        Q, R = planner_weights(task, bound, self.state_weight, self.input_weight, self.alpha, self.split)
        inside = np.minimum(task.q0, task.qg), np.maximum(task.q0, task.qg)  # a margin never excludes these
        margin = self.settings.range_margin
        limits = PathLimits(bound, np.minimum(joints.lower + margin, inside[0]),
                            np.maximum(joints.upper - margin, inside[1]), np.full(n, float(self.speed_limit)))
        x0 = np.concatenate([task.q0, np.zeros(n)])
        xg = np.concatenate([task.qg, np.zeros(n)])
        problem = Shooting(model, x0, xg, Q, R, task.steps, self.fd_eps)
        start, linear_plan = self._start(task, model, problem, limits)
        return problem, limits, _Starts(start, lambda: self._tracked_start(task, linear_plan, problem, limits))

    def _sqp(self, problem: Shooting, limits: PathLimits, u: NDArray[np.float64],
             join: NDArray[np.float64] | None = None) -> tuple[SqpResult, str | None]:
        """The Gauss-Newton SQP from u (N n,) with this planner's settings (`join` as `gauss_newton_sqp`'s): its
        result, and what its last iterate fails (None: it is a plan).

        Raises:
          SolverError: the rollout of u diverged.
        """
        result = gauss_newton_sqp(problem, limits, u, max_iter=self.sqp_max_iter, join=join,
                                  settings=self.settings.sqp)
        return result, result.message if not result.converged else self._unmet(problem, limits, result.u)

    def _restored(self, problem: Shooting, limits: PathLimits, stopped: list[tuple[str, NDArray[np.float64]]],
                  failures: list[str]) -> list[tuple[float, str, SqpResult]]:
        """Where the SQP stopped short from every start: the least violation of the constraints from each start's last
        iterate (`restoration.least_violation`). From a feasible point found the SQP runs once more: its plan, start
        'restored', if it converges. Else [], the reasons added to `failures`.

        Raises:
          InfeasibleError: every search converged at a positive violation (local infeasibility; the message names
            each one's worst constraint).
        """
        searches = []
        for name, u in stopped:
            try:
                least = least_violation(problem, limits, u)
            except SolverError as e:
                failures.append(f"the least violation from the {name} start's last iterate: {e}")
                return []
            if least.feasible:
                result, failure = self._sqp(problem, limits, least.u)
                if failure is None:
                    return [(problem.objective(result.u), "restored", result)]
                failures.append(f"from the feasible point restored from the {name} start's last iterate: {failure}")
                return []
            searches.append((name, least))
        for name, least in searches:
            if not least.converged:
                failures.append(f"the least violation's search from the {name} start's last iterate did not "
                                f"converge in {least.evaluations} rollouts")
                return []
        found = "; ".join(f"from the {name} start's last iterate {self._worst(least, problem.steps, problem.n)}"
                          for name, least in searches)
        raise InfeasibleError(f"{self.name}: no plan near where the SQP stopped (locally infeasible): the least "
                              f"violation of the constraints is positive {found}. Each is a stationary point of the "
                              "violation on the torque box: not a proof that no plan exists")

    @staticmethod
    def _worst(least: LeastViolation, steps: int, n: int) -> str:
        """The worst constraint at a least violation, and its first-order optimality."""
        worst = least.worst()
        value = least.residual[worst]
        if worst < n:
            what = f"joint {worst} misses its goal by {abs(value):.2g} rad"
        elif worst < 2 * n:
            what = f"joint {worst - n} ends at {abs(value):.2g} rad/s, not at rest"
        else:
            what = f"{NonlinearOptimal._describe(worst - 2 * n, (steps, n))} is exceeded by {-value:.2g} of its size"
        return f"({what}; first-order optimality {least.optimality:.1e})"

    def _slsqp(self, problem: Shooting, limits: PathLimits, starts: _Starts
               ) -> tuple[NDArray[np.float64], str, int, int, int, int]:
        """SLSQP from the linear start, once more with `settings.retry_factor` times the curvature scale if it fails,
        then from the tracked start: (u, the start's name, rounds, iterations, path rows, retries before it)."""
        tries = (("linear", 1.0), ("linear", self.settings.retry_factor), ("tracked", 1.0))
        failures: list[InfeasibleError | SolverError] = []
        for retried, (name, factor) in enumerate(tries):
            try:
                u, rounds, iterations, rows = self._optimise(problem, limits, starts.get(name),
                                                             factor * self.curvature_scale)
                return u, name, rounds, iterations, rows, retried
            except (InfeasibleError, SolverError) as e:
                failures.append(e)
        first, second, tracked = failures
        raise type(second)(f"{second} (also with curvature_scale {self.curvature_scale:g}: {first}) (from the tracked "
                           f"start: {tracked})") from None

    @staticmethod
    def _unmet(problem: Shooting, limits: PathLimits, u: NDArray[np.float64]) -> str | None:
        """What u fails of x_N = x_g (to 1e-8) and the path constraints (to 1e-8 of their limits), or None."""
        U, X = problem.states(u)
        if np.max(np.abs(X[-1] - problem.xg)) > 1e-8:
            return "the terminal state x_N = [qg; 0] is not met to 1e-8"
        scale = limits.scale(U.shape[0])
        h = limits.values(U, X)
        worst = int(np.argmin(h / scale))
        return None if h[worst] >= -1e-8 * scale[worst] else NonlinearOptimal._describe(worst, U.shape)

    def _optimise(self, problem: Shooting, limits: PathLimits, u: NDArray[np.float64], scale: float
                  ) -> tuple[NDArray[np.float64], int, int, int]:
        """SLSQP solves from u (N n,) with a growing set of path-constraint rows (at most `settings.max_rounds`
        solves), `scale` times the Gauss-Newton Hessian as the first curvature model: (the plan's u, rounds, SLSQP
        iterations, path rows).

        Raises:
          InfeasibleError, SolverError: no plan meets every constraint (names which), or SLSQP failed.
        """
        try:
            U, X, _, S = problem.evaluate(u)
        except SolverError as e:
            raise SolverError(f"{self.name}: {e}") from None
        rows = np.flatnonzero(limits.near(U, X))
        f_scale = 1.0 / max(problem.objective(u), 1e-12)
        t_scale = 1.0 / np.maximum(np.linalg.norm(S[-1], axis=1), 1e-12)
        iterations, rounds = 0, 0
        for rounds in range(1, self.settings.max_rounds + 1):  # noqa: B007 (reported in info)
            try:
                result = self._solve(problem, limits, rows, u, f_scale, t_scale, scale)
            except SolverError as e:
                raise SolverError(f"{self.name}: {e}") from None
            iterations += int(result.nit)
            u = result.x
            U, X, _, S = problem.evaluate(u)
            violated = np.flatnonzero(limits.values(U, X) < -1e-8 * limits.scale(U.shape[0]))
            missing = np.setdiff1d(violated, rows)
            rows = np.union1d(rows, np.union1d(missing, np.flatnonzero(limits.near(U, X))))
            if missing.size == 0:
                break
        terminal = float(np.max(np.abs(X[-1] - problem.xg)))
        h = limits.values(U, X)
        worst = int(np.argmin(h / limits.scale(U.shape[0])))
        if terminal > 1e-8 or h[worst] < -1e-8 * limits.scale(U.shape[0])[worst]:
            what = "the terminal state x_N = [qg; 0]" if terminal > 1e-8 else self._describe(worst, U.shape)
            kind = InfeasibleError if result.status in (0, 4) else SolverError
            raise kind(f"{self.name}: no plan meets {what} (SLSQP: {result.message}; terminal residual "
                       f"{terminal:.2g} rad)")
        if result.status != 0:
            raise SolverError(f"{self.name}: SLSQP stopped: {result.message} (status {result.status})")
        return u, rounds, iterations, int(rows.size)

    def _start(self, task: Task, model: mujoco.MjModel, problem: Shooting, limits: PathLimits
               ) -> tuple[NDArray[np.float64], Reference]:
        """The first iterate and the linear plan it comes from: the linear optimal plan with these weights if its
        rollout keeps every path constraint, else the linear minimum-effort plan (Q = 0, the zero-order-held slow
        move); its torques clipped to the bound, flattened (N n,)."""
        candidates = [self.linear()]
        if self.alpha != 0.0 or self.state_weight is not None:
            candidates.append(Optimal(input_weight=self.input_weight, alpha=0.0, torque_bound=self.torque_bound))
        for planner in candidates:
            try:
                plan = planner.plan(task, model)
            except InfeasibleError as e:
                raise InfeasibleError(f"{self.name}: no start to optimise from: {e}") from e
            assert plan.u_plan is not None
            u = np.clip(plan.u_plan, -limits.u_max, limits.u_max).ravel()
            U, X = problem.states(u)
            if np.all(limits.values(U, X) >= 0.0):
                break
        return u, plan

    def _tracked_start(self, task: Task, plan: Reference, problem: Shooting, limits: PathLimits
                       ) -> NDArray[np.float64]:
        """The second start, for a solve that failed from the first: the torques with which the nominal model tracks
        the linear `plan`'s states under time-varying LQR feedback about them (`tracking.bryson_gains` on the model
        linearised along the plan: its hinge tree's step Jacobians, 2.8 ms at N = 100, where it has one; else
        MuJoCo's linearisation by differences, discretised, 9 ms), clipped to the bound; (N n,). The linear plan's
        open-loop torques drift away on the nonlinear arm (on some tasks into a joint's end, where the rollout's
        sensitivities vanish and the linearised terminal condition cannot be met); tracked, the rollout stays
        near the plan's path and ends near the goal.

        Raises:
          SolverError: the tracked rollout diverged.
        """
        assert plan.u_plan is not None
        X_ref = np.concatenate([plan.q, plan.qd], axis=1)
        found = problem.tree_jacobians(X_ref[:-1], plan.u_plan)
        if found is None:  # no hinge tree: the continuous linearisation, discretised
            A, B = linearize_many(problem.model, plan.q[:-1], plan.qd[:-1], plan.u_plan)
            found = discretize_zoh(A, B, task.dt)
        K = bryson_gains(*found, limits.u_max)
        return problem.tracked(plan.u_plan, X_ref, K, limits.u_max).ravel()

    def _solve(self, problem: Shooting, limits: PathLimits, rows: NDArray[np.intp], u: NDArray[np.float64],
               f_scale: float, t_scale: NDArray[np.float64], scale: float) -> scipy.optimize.OptimizeResult:
        """One SLSQP solve from u with the path-constraint `rows`, in the variables v of `_Metric` at u (`scale`
        times the Gauss-Newton Hessian)."""
        import scipy.optimize  # here, not at import: a quarter second of `mjtraj compare`'s start-up otherwise
        row_scale = 1.0 / limits.scale(problem.steps)[rows]
        metric = _Metric.at(problem, u, scale * f_scale)
        to_u, pull = metric.to_u, metric.pull

        def terminal(v: NDArray[np.float64]) -> NDArray[np.float64]:
            return t_scale * (problem.evaluate(to_u(v))[1][-1] - problem.xg)

        def terminal_jac(v: NDArray[np.float64]) -> NDArray[np.float64]:
            return pull(t_scale[:, None] * problem.evaluate(to_u(v))[3][-1])

        def path(v: NDArray[np.float64]) -> NDArray[np.float64]:
            U, X, _, _ = problem.evaluate(to_u(v))
            return row_scale * limits.values(U, X)[rows]

        def path_jac(v: NDArray[np.float64]) -> NDArray[np.float64]:
            return pull(row_scale[:, None] * limits.jacobian(problem.evaluate(to_u(v))[3], rows))

        constraints: list[dict[str, Any]] = [{"type": "eq", "fun": terminal, "jac": terminal_jac}]
        if rows.size:
            constraints.append({"type": "ineq", "fun": path, "jac": path_jac})
        result = scipy.optimize.minimize(lambda v: f_scale * problem.objective(to_u(v)), metric.to_v(u),
                                         jac=lambda v: pull(f_scale * problem.gradient(to_u(v))[None])[0],
                                         method="SLSQP", constraints=constraints,
                                         options={"maxiter": self.max_iter, "ftol": self.tol})
        result.x = to_u(result.x)
        return result

    @staticmethod
    def _describe(row: int, shape: tuple[int, ...]) -> str:
        """Which constraint path row `row` is: its kind, joint and sample."""
        steps, n = shape
        group, rest = divmod(row, steps * n)
        k, joint = divmod(rest, n)
        sample = k if group >= 4 else k + 1
        return f"{CONSTRAINT_NAMES[group]} of joint {joint} at sample {sample}"

    def _reference(self, task: Task, U: NDArray[np.float64], X: NDArray[np.float64], objective: float, solver: str,
                   start: str, iterations: int, rounds: int, rows: int, retried: int, wall: float,
                   jacobians: dict[str, int], *, converged: int = 0) -> Reference:
        """The rollout X (N+1, 2n) under U (N, n) as a Reference: qdd is the ZOH acceleration per step. `jacobians`:
        how many linearisations were analytic and how many differenced (see `Shooting.jacobians`); `converged`: the
        starts from which the Gauss-Newton SQP converged (0 where SLSQP planned). Where `settings` differ from the
        defaults, info['settings'] names those that do (`NonlinearSettings.changes`, joined by '; ')."""
        n = task.n
        terminal = float(np.max(np.abs(X[-1] - np.concatenate([task.qg, np.zeros(n)]))))
        q, qd = X[:, :n].copy(), X[:, n:].copy()
        qdd = np.zeros_like(qd)
        qdd[:-1] = np.diff(qd, axis=0) / task.dt
        q[-1] = task.qg  # within 1e-8 (checked): the samples end exactly on the goal, at rest
        qd[-1] = 0.0
        info = {"objective": objective, "solver": solver, "start": start, "iterations": iterations, "rounds": rounds,
                "path_rows": rows, "retried": retried, "terminal_residual": terminal, "plan_time": wall,
                "sqp_converged": converged, "analytic_jacobians": jacobians["analytic"],
                "differenced_jacobians": jacobians["differenced"]}
        changed = self.settings.changes()
        if changed:
            info["settings"] = "; ".join(changed)
        return Reference(planner=self.name, t=task.times, q=q, qd=qd, qdd=qdd, u_plan=U.copy(), info=info)


@register("nonlinear_min_effort", on_request=True)
@dataclass(frozen=True)
class NonlinearMinEffort(NonlinearOptimal):
    """`nonlinear_optimal` with Q = 0: the least corrective effort sum u^T R u with which the nominal nonlinear arm
    makes the move within its ranges, speed limit and torque bound; the study's effort bound."""

    alpha: float = 0.0
    keep: str = "lowest"
    name: ClassVar[str] = "nonlinear_min_effort"

    def __post_init__(self) -> None:
        if self.alpha != 0.0 or self.state_weight is not None:
            raise InvalidInputError(f"alpha, state_weight: {self.name} has no state weight (Q = 0); use "
                                    "nonlinear_optimal for a weighted plan")
        super().__post_init__()
