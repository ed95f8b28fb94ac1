"""The least violation of a nonlinear planner's constraints, for the tasks on which its SQP stops short from every
start: does a plan exist near where it stopped?

`least_violation` minimises 1/2 |r(u)|^2 over the torque box, r = (x_N - x_g, min(0, h_r / limit_r) for every range
and speed row): the terminal residual (rad, rad/s) and each path row's violation relative to its limit, the terms
of the SQP's l1 violation (`sqp.violation`). Box-constrained nonlinear least squares by scipy's trust-region
reflective method, with the rollout's sensitivities as r's Jacobian. Where it reaches r = 0, the point is feasible
and the SQP starts again from it. Where it converges at r != 0, the point is a stationary point of the violation
(first-order optimal on the box): no feasible plan lies near it. That is local infeasibility, as interior-point and
SQP codes report it (IPOPT's "converged to a point of local infeasibility"), not a proof that no plan exists.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mjtraj.core.planners.shooting import PathLimits, Shooting
from mjtraj.exceptions import SolverError

FEASIBLE = 1e-9
"""A point whose |r| is at most this in every component is feasible (the SQP then polishes it to its own 1e-10)."""
MAX_EVALUATIONS = 3000
"""Rollouts per search; on the six aggressive tasks of the study's effort sweep that the SQP could not plan, the
searches from both starts converged in 326 to 1,873 (1 to 4 s on one core)."""
LARGE_TORQUES = 400
"""Above this many torques (N n; every UR5 task of up to 2.66 s is below it) the search solves its trust-region
subproblems iteratively (scipy's 'lsmr') instead of by an SVD of the dense Jacobian, and stops after
MAX_EVALUATIONS_LARGE rollouts: on a 6-hinge arm (600 torques) an SVD took 0.24 s and 3,000 rollouts 10 minutes."""
MAX_EVALUATIONS_LARGE = 300
"""Rollouts per search above LARGE_TORQUES (about 10 s on a 6-hinge arm)."""
DIVERGED = 1e3
"""r's every component at a trial point whose rollout diverged."""
TOLERANCE = 1e-12
"""scipy's ftol, xtol and gtol: the search stops once the violation, the point or the projected gradient stalls."""


@dataclass(frozen=True)
class LeastViolation:
    """u (N n,): the search's last point; residual: r there (2n terminal, then 4 N n path components); converged:
    whether scipy's tests stopped it (else MAX_EVALUATIONS, or MAX_EVALUATIONS_LARGE, did); optimality: its
    first-order optimality (the projected gradient's largest component); evaluations: its rollouts of r."""

    u: NDArray[np.float64]
    residual: NDArray[np.float64]
    converged: bool
    optimality: float
    evaluations: int

    @property
    def feasible(self) -> bool:
        return bool(np.abs(self.residual).max() <= FEASIBLE)

    def worst(self) -> int:
        """The largest component of `residual`: 0..2n-1 the terminal state's, then the path row's index + 2n."""
        return int(np.argmax(np.abs(self.residual)))


def residual(problem: Shooting, limits: PathLimits, u: NDArray[np.float64]) -> NDArray[np.float64]:
    """r at u (N n,), shape (2n + 4 N n,): x_N - x_g, then min(0, h / limit) over the range and speed rows."""
    U, X = problem.states(u)
    rows = 4 * problem.steps * problem.n
    h = limits.values(U, X)[:rows] / limits.scale(problem.steps)[:rows]
    return np.concatenate([X[-1] - problem.xg, np.minimum(h, 0.0)])


def least_violation(problem: Shooting, limits: PathLimits, u: NDArray[np.float64]) -> LeastViolation:
    """Minimise 1/2 |r|^2 over the torque box from u (N n,) (module docstring).

    Raises:
      SolverError: the rollout of u diverged.
    """
    import scipy.optimize  # here, not at import: a quarter second of `mjtraj compare`'s start-up otherwise

    rows = 4 * problem.steps * problem.n
    u_max = np.tile(limits.u_max, problem.steps)
    scale = limits.scale(problem.steps)[:rows]

    def jacobian(v: NDArray[np.float64]) -> NDArray[np.float64]:
        U, X, _, S = problem.evaluate(v)
        violated = np.flatnonzero(limits.values(U, X)[:rows] < 0.0)
        out = np.zeros((2 * problem.n + rows, len(v)))
        out[:2 * problem.n] = S[-1]
        out[2 * problem.n + violated] = limits.jacobian(S, violated) / scale[violated, None]
        return out

    def trial(v: NDArray[np.float64]) -> NDArray[np.float64]:
        try:
            return residual(problem, limits, v)
        except SolverError:
            return np.full(2 * problem.n + rows, DIVERGED)  # the trust region shrinks

    residual(problem, limits, u)  # raises where the start's rollout diverges
    large = problem.steps * problem.n > LARGE_TORQUES
    options = {"tr_solver": "lsmr", "max_nfev": MAX_EVALUATIONS_LARGE} if large else {"max_nfev": MAX_EVALUATIONS}
    found = scipy.optimize.least_squares(trial, np.clip(u, -u_max, u_max), jac=jacobian, bounds=(-u_max, u_max),
                                         method="trf", ftol=TOLERANCE, xtol=TOLERANCE, gtol=TOLERANCE,
                                         **options)  # type: ignore[arg-type]
    return LeastViolation(np.asarray(found.x, dtype=np.float64), residual(problem, limits, found.x),
                          bool(found.status > 0), float(found.optimality), int(found.nfev))
