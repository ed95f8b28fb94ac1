"""Sequential quadratic programming for the nonlinear planners (`Shooting` problems): the Gauss-Newton Hessian, then
the Lagrangian's.

Each iteration linearises the rollout at the current torques u (transition Jacobians, `Shooting.jacobians`; forward
sensitivities S_k = dx_k/du) and solves the condensed QP

    min_d 1/2 d^T (s H_GN) d + g^T d   s.t.   S_N d = -(x_N - x_g),   -u_max - u <= d <= u_max - u,
                                             h_r + (dh_r/du) d >= 0 for the path rows r near their limits,

with H_GN = R + sum_k S_k^T Q S_k (`Shooting.gauss_newton`), exactly, by DAQP's dual active-set method (Arnström,
Bemporad and Axehill, 2022). This is the structure of an SQP for optimal control with full condensing and a dense
active-set QP solver (as in acados): on the 3-DoF arm the condensed QP has N n = 300 variables and solves in about
2.5 ms (0.4 ms for the effort bound, whose Hessian is diagonal). The step is accepted by an Armijo line search
on the l1 merit f + rho (|x_N - x_g|_1 + the scaled path violations), with a second-order correction when the full
step is refused (the Maratos effect near the solution). Where that is refused too, the line search runs along the
projected path (`projector`, the projection operator of Hauser's PRONTO, 2002; the forward pass of iLQR and DDP is
of the same kind): the model tracks the states the QP's linearisation predicts for the step t d under LQR feedback,
so that the trial stays near that prediction. An open-loop step of single shooting is amplified along the rollout's
100 steps; far from the solution its trials missed the prediction, and the line search cut the step to 1/16 or 1/32
for tens of iterations. Only where no projected step decreases the merit does it backtrack along d itself. The
factor s starts at `curvature_scale` (short first steps, the role of SLSQP's first curvature model) and is divided
by `shrink` after every full, corrected or projected step down to 1, where the iteration is Gauss-Newton's: linear
convergence, fast where the dynamics' second derivatives, weighted by the multipliers, are small against R and Q
(with the paper's weights: about 8 iterations), slow where they are not (the effort bound's Q = 0; see
`mjtraj.core.planners.nonlinear.SOLVERS`). So once the iteration is seen converging slowly (SLOW), and after
SECOND_ORDER_AFTER iterations in any case, the Hessian becomes the Lagrangian's: H_GN plus that curvature, weighted
by the last QP's multipliers (`Shooting.second_order`, about 10 ms at N = 100), made positive definite on the
constraints' null space by an augmented term (AUGMENT) and damped where a step is cut (DAMPING): Newton's method,
locally quadratic. A solve given the plan of an earlier start (`join`) stops
once its iterate comes within JOIN of it: it is converging to the same minimum.

The torque bound is a box on u: iterates never leave it (each is put back on the box's end that rounding took it a
few ulps past). Path rows are screened as in SLSQP's solve (SCREEN); a row left out enters once an iterate nears
it. A QP whose linearised constraints cannot all hold is solved again asking them to close only part of the way
(RELAXED), then with the path rows soft (DAQP's soft constraints), so that the terminal condition still holds and
the merit decides.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from mjtraj.core.planners.shooting import SCREEN, PathLimits, Shooting, input_blocks
from mjtraj.core.planners.tracking import bryson_gains
from mjtraj.exceptions import SolverError

ARMIJO = 1e-4
"""Sufficient decrease of the merit, as a fraction of its predicted decrease."""
MIN_STEP = 2.0 ** -20
"""The line search gives up below this step."""
FEASIBLE = 1e-10
"""Converged once |x_N - x_g| (rad, rad/s) and every path violation (relative to its limit) are within this ..."""
STALL = 1e-10
"""... and the objective changed by at most this fraction over the last step."""
SECOND_ORDER_AFTER = 20
"""From the iteration after this at the latest (SLOW: sooner where the iteration converges slowly), each QP's Hessian
adds the dynamics' curvature weighted by the last QP's
multipliers (`Shooting.second_order`): the Lagrangian's Hessian, with which the iteration converges as Newton's
method does where Gauss-Newton's converges slowly (the effort bound's Q = 0; see the module docstring). Chosen by
`mjtraj.core.planners.nonlinear.SQP_MAX_ITER`'s validation rule (180 tasks: most plans at SLSQP's optimum or lower,
then the least mean time) over 5, 10, 20 and never: each had 179, in a mean of 0.53, 0.53, 0.48 and 1.26 s a plan
(SLSQP planned 3, 3, 2 and 8 of them); with 5, 10 and 20 nominal 92 costs 0.123, 64 % less than SLSQP's 0.344."""
SLOW = (8, 3, 0.7)
"""(after, run, contraction): from the iteration after `after`, the Hessian becomes the Lagrangian's once `run`
iterations in a row were slow: the line search shortened the step (a projected step below t = 1, or a backtracked
one), or the QP's step was longer than `contraction` times the one before. On the bound's slowest tasks Gauss-Newton
contracts by 0.5 to 0.8 an iteration for 20 iterations (nominal 92 and 145 of seed 1). Chosen for the tail targets
of `mjtraj bench planners` (its 298 tasks of seed 1; the study's test tasks are seed 0's and the paper's) by the
rule: every plan at the optimum known or lower, then both targets met (90th percentile <= 100, largest <= 300
times the linear plan, each timed beside its task), then the least mean time, over (10, 3, 0.5), (8, 4, 0.6),
(8, 3, 0.7), (5, 5, 0.5), (5, 3, 0.5) and none. Every one kept every plan within 5e-11 of its optimum. (8, 4, 0.6)
and (8, 3, 0.7) met both targets (90th percentile 99 and 95, largest 253 and 289; none: 95 and 386); their mean
times, 0.0725 and 0.0739 s, differ by less than two runs of the same code do (5 %), so the last step could not
separate them, and (8, 3, 0.7) was kept for its margin at the 90th percentile. Those runs preceded the compiled
gains and the tree-linearised tracked start; `mjtraj bench planners` times the linear plans together, first, and
reports higher multiples (docs/speed.md)."""
AUGMENT = 10.0 ** np.arange(8)
"""The Lagrangian's Hessian is indefinite; where it is positive definite on the null space of the terminal rows and
the last QP's active path rows A, H + rho A^T A is positive definite for a large enough rho, and the QP's solution on
those rows is unchanged. rho is tried at these multiples of max diag(H) / max diag(A^T A), smallest first; where none
makes H positive definite, the iteration keeps the Gauss-Newton Hessian."""
DAMPING = (0.1, 4.0)
"""Levenberg-Marquardt damping of the second-order Hessian, as a multiple of R's diagonal: a step neither full nor
corrected (projected or backtracked) sets it to at least the first number, or multiplies it by the second; a full
(or corrected) step divides it by the second, and below the first it is zero."""
NEWTON_REUSE = 5
"""The Lagrangian's Hessian (and its factor) is used again for up to this many iterations after the one it was made
in, while the curvature scale, the damping and the path rows are unchanged (every step full or corrected, no row
added): near the solution the multipliers and the torques move little, and the Hessian (about 10 ms at N = 100,
the dynamics' curvature by differences) would be made again for a step of 1e-4. Newton's method with a Hessian so
reused converges linearly, at a small rate. Chosen over 0 (made every iteration), 2, 5 and 1000, each with SLOW and
with SLOW (6, 3, 0.6), on the 298 tasks of `mjtraj bench planners`' tail (seed 1; the study's test tasks are seed 0's
and the paper's), timed in turn beside each task, by the rule: every plan within 1e-9 of the best objective found
for its task (all eight settings kept every plan within 5.3e-11), then the least mean time, where settings within
1 % of it tie, and among those the least worst multiple of the linear plan. Means 0.0436, 0.0424, 0.0422 and
0.0423 s with SLOW (0.0429, 0.0418, 0.0416 and 0.0416 with (6, 3, 0.6), within the noise between runs of the same
code, so SLOW was kept); 2, 5 and 1000 tie, and 5 had the least worst multiple (181 against 196 and 184; 218
without reuse)."""
JOIN = 1e-1
"""An iterate within this distance of an earlier start's plan, relative to that plan's norm, joins it. On the 180
validation tasks of `mjtraj.core.planners.nonlinear.SQP_MAX_ITER`, the bound's second start headed for another
point on 3 (none of them converged there) and came no closer than 5.8e-2 to the first plan; on the 166 where it
reached the first plan, it crossed 1e-3 a median of 4 iterations before its own convergence test passed (43 % of
those solves' iterations). With the projected line search, 1e-2 and 1e-3 gave the same plans, bit for bit, on all
480 validation tasks, in a mean of 0.073 s a plan against 0.078 s. With the slow switch (SLOW), the second start run
to its own convergence on those 480 tasks (none joined) reached another point on 7, all converged there (6 lower, so
kept); none came within 0.31 of the first plan, and no second start that came within 0.2 of it went elsewhere. So
the threshold was raised to the largest of 2e-2, 5e-2, 1e-1 and 2e-1 below a third of that closest approach, 1e-1:
the same plans, bit for bit, on the 298 tasks of `mjtraj bench planners`' tail, 1.4 iterations fewer a plan on the
480 (7 % of the tail's time; its 90th percentile 109 became 101 times the linear plan in a paired run)."""
RELAXED = (0.5, 0.25)
"""Where the linearised constraints admit no step, the QP asks them to close only this share of the way, largest
first: the terminal residual and each violated path row's violation scaled by it (d = 0 meets the constraints at
share 0, so a small enough share always admits a step); where neither does, the path rows are made soft. On
nominal 110 of seed 1 the soft QP's step had raised the merit's penalty to 1.5e7, after which the line search took
10 steps of 1e-4 to 1e-6 of d (22 iterations, 0.75 s); half the way, once, makes it 16 (0.30 s). Shares down to
2^-10 kept alive starts whose soft QP fails at once, and the next start is quicker there (nominal 57 and 120: 0.1 s
became 0.6 s)."""
DAQP_TOL = 1e-12
"""DAQP's primal and dual tolerances (the QP's rows are of order one)."""
SENSE_FREE, SENSE_EQUAL, SENSE_SOFT = 0, 5, 8
"""DAQP's constraint kinds: inequality, equality, soft inequality."""


@dataclass(frozen=True)
class SqpResult:
    """u: the last iterate (N n,), or the plan it joined; converged: whether it met FEASIBLE and STALL or joined;
    rows: path rows in the last QP; joined: whether it stopped at JOIN from the plan given."""

    u: NDArray[np.float64]
    iterations: int
    rows: int
    converged: bool
    message: str
    joined: bool = False


def violation(problem: Shooting, limits: PathLimits, u: NDArray[np.float64]) -> float:
    """|x_N - x_g|_1 plus every path row's violation relative to its limit at u (its rollout)."""
    U, X = problem.states(u)
    h = limits.values(U, X) / limits.scale(problem.steps)
    return float(np.abs(X[-1] - problem.xg).sum() + np.maximum(0.0, -h).sum())


def _qp(H: NDArray[np.float64], g: NDArray[np.float64], C: NDArray[np.float64], c: NDArray[np.float64],
        G: NDArray[np.float64], h: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64],
        soft: bool, back: NDArray[np.float64] | None = None, iter_limit: int | None = None
        ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """argmin 1/2 d^T H d + g^T d s.t. C d = -c, G d >= -h, low <= d <= high by DAQP: (d, the multipliers of the
    rows C, G), or None if DAQP finds no solution. H is a matrix, or the diagonal (its 1-d array) of a diagonal one.
    Solved in z = L^T d (H = L L^T), where the Hessian is the identity: DAQP's own factorisation of a dense H of 300
    rows took 5 ms of the 5.5, this takes 2.5 in all. Where H is diagonal (the effort bound's: Q = 0 and a diagonal
    R), L is too and the box stays a box in z: DAQP takes it as simple bounds, not as 300 rows, and the QP solves in
    about 0.4 ms instead of 3. back: L^-T of a dense H where it is known (`_inverse_factor`). iter_limit: DAQP's
    iteration cap (None: its default); a solve that reaches it returns None."""
    import daqp  # here, not at import: only the nonlinear planners need it

    if H.ndim == 1:
        diagonal = H
        if np.any(diagonal <= 0.0):
            raise SolverError("the QP's Hessian is not positive definite (a diagonal entry <= 0)")
        root = np.sqrt(diagonal)
        inverse = 1.0 / root  # L^-T, diagonal: d = inverse * z

        def to_d(z: NDArray[np.float64]) -> NDArray[np.float64]:
            return inverse * z

        f = inverse * g
        general = np.vstack([C * inverse, G * inverse])
        bounds = (high * root, low * root)  # the box, as simple bounds on z
    else:
        back = _inverse_factor(H) if back is None else back  # L^-T: d = L^-T z

        def to_d(z: NDArray[np.float64]) -> NDArray[np.float64]:
            return back @ z  # type: ignore[no-any-return]

        f = back.T @ g
        general = np.vstack([back, C @ back, G @ back])  # the box as general rows
        bounds = (high, low)
    rows = len(h)
    upper = np.concatenate([bounds[0], -c, np.full(rows, np.inf)])
    lower = np.concatenate([bounds[1], -c, -h])
    sense = np.concatenate([np.full(len(g), SENSE_FREE), np.full(len(c), SENSE_EQUAL),
                            np.full(rows, SENSE_SOFT if soft else SENSE_FREE)]).astype(np.intc)
    capped = {} if iter_limit is None else {"iter_limit": iter_limit}
    z, _, status, info = daqp.solve(np.eye(len(g)), f, general, upper, lower, sense, primal_tol=DAQP_TOL,
                                    dual_tol=DAQP_TOL, **capped)
    if status < 1:
        return None
    return to_d(np.asarray(z, dtype=np.float64)), np.asarray(info["lam"], dtype=np.float64)[len(g):]


def _inverse_factor(H: NDArray[np.float64], factor: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """L^-T for the dense H = L L^T (given L, `factor`, where it is known; its upper triangle zero).

    Raises:
      SolverError: H is not positive definite.
    """
    info = 0
    if factor is None:
        factor, info = scipy.linalg.lapack.dpotrf(H, lower=1, clean=1)
    if info == 0:
        factor, info = scipy.linalg.lapack.dtrtri(factor, lower=1)  # L^-1
    if info != 0:
        raise SolverError(f"the QP's Hessian is not positive definite (LAPACK info {info})")
    return factor.T  # type: ignore[no-any-return]


def _step_qp(H: NDArray[np.float64], g: NDArray[np.float64], C: NDArray[np.float64], c: NDArray[np.float64],
             G: NDArray[np.float64], h: NDArray[np.float64], low: NDArray[np.float64], high: NDArray[np.float64],
             back: NDArray[np.float64] | None = None
             ) -> tuple[NDArray[np.float64], NDArray[np.float64], float, bool] | None:
    """The SQP's step QP (`_qp`'s arguments, the constraints C d = -c, G d >= -h): (d, multipliers, share, soft).
    Where the constraints admit no step, they are asked to close only `share` of the way (RELAXED: c and every
    negative h scaled by it); where no share does, the rows G are made soft (share 1). None where even that fails,
    or where the rows C alone admit no step in the box: the soft solve is then not tried (on a dense Hessian DAQP
    took 0.23 s to give it up, nominal 120 of seed 1 for `nonlinear_optimal`; the check took 0.03 s). `back`: a
    dense H's L^-T where already known (`gauss_newton_sqp` factors it once per step), else each solve factors H."""
    solved = _qp(H, g, C, c, G, h, low, high, False, back)
    if solved is not None:
        return (*solved, 1.0, False)
    for share in RELAXED:
        solved = _qp(H, g, C, share * c, G, np.maximum(h, share * h), low, high, False, back)
        if solved is not None:
            return (*solved, share, False)
    if _qp(H, g, C, c, G[:0], h[:0], low, high, False, back) is None:
        return None  # the terminal rows alone admit no step in the box: no soft path row can change that
    solved = _qp(H, g, C, c, G, h, low, high, True, back)
    return None if solved is None else (*solved, 1.0, True)


_Lagrangian = tuple[NDArray[np.float64], NDArray[np.float64], tuple[float, float, bytes], int]
"""The last Lagrangian Hessian, its L^-T, what it was made for (scale, damping, path rows), and its reuses."""


def gauss_newton_sqp(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], *, curvature_scale: float,
                     shrink: float, max_iter: int, join: NDArray[np.float64] | None = None,
                     second_order_after: int | None = SECOND_ORDER_AFTER) -> SqpResult:
    """Minimise `problem`'s objective from u (N n,), within the torque box, subject to x_N = x_g and the path limits
    (module docstring). Returns the last iterate whether or not it converged, or `join` (a converged plan of the
    same problem, (N n,)) once an iterate comes within JOIN of it (see SqpResult). After `second_order_after`
    iterations (None: never) the Hessian is the Lagrangian's (SECOND_ORDER_AFTER).

    Raises:
      SolverError: the rollout of u diverged.
    """
    N, n = problem.steps, problem.n
    size = N * n
    u_max = np.tile(limits.u_max, N)
    path_scale = limits.scale(N)[:4 * size]
    diagonal = problem.diagonal_hessian  # the Hessian as its diagonal where it is diagonal (the effort bound's)
    scale, penalty, damping = float(curvature_scale), 0.0, 0.0
    last: float | None = None
    rows = np.zeros(0, dtype=np.intp)
    multipliers: tuple[NDArray[np.float64], NDArray[np.intp]] | None = None  # the last QP's, and its path rows
    slow_after, slow_run, contraction = SLOW
    slow, last_length = 0, float("inf")  # slow iterations in a row; the last QP step's length
    lagrangian: _Lagrangian | None = None
    for iteration in range(1, max_iter + 2):  # the last pass only tests the last step's iterate
        if join is not None and np.linalg.norm(u - join) <= JOIN * np.linalg.norm(join):
            return SqpResult(join, iteration - 1, int(rows.size), True, "joined the plan given", joined=True)
        U, X = problem.states(u)
        f = problem.objective(u)
        terminal = X[-1] - problem.xg
        h = limits.values(U, X)[:4 * size]
        if _converged(terminal, h, path_scale, f, last):
            return SqpResult(u, iteration - 1, int(rows.size), True, "converged")
        if iteration > max_iter:
            break
        S = problem.evaluate(u)[3]
        g = problem.gradient(u)
        now = violation(problem, limits, u)
        rows = np.union1d(rows, np.flatnonzero(h < (1.0 - SCREEN) * path_scale))
        G = limits.jacobian(S, rows) / path_scale[rows, None]
        second_order_after = _second_order_from(second_order_after, iteration, slow, slow_after, slow_run)
        H, back, newton, lagrangian = _hessian(problem, limits, u, diagonal, scale, damping, rows, path_scale,
                                               multipliers, lagrangian, second_order_after, iteration)
        solved = _step_qp(H, g, S[-1], terminal, G, h[rows] / path_scale[rows], -u_max - u, u_max - u, back)
        if solved is None:
            return SqpResult(u, iteration, int(rows.size), False, "the linearised constraints admit no step")
        d, lam, share, soft = solved
        multipliers = (lam, rows)
        penalty = max(penalty, 2.0 * float(np.abs(lam).max(initial=0.0)))
        merit = f + penalty * now
        slope = float(g @ d) - penalty * share * now  # the merit's predicted change along d
        point = _full_or_corrected(problem, limits, u, d, H, g, S, rows, path_scale, soft, back, share, merit, slope,
                                   penalty)
        if newton:
            damping = _next_damping(damping, point is not None)
        shortened, trusted = False, True
        if point is None:
            searched = _searched_step(problem, limits, u, d, merit, slope, penalty)
            if searched is None:
                return SqpResult(u, iteration, int(rows.size), False, "the line search found no decrease")
            point, shortened, trusted = searched
        if trusted:
            scale = max(1.0, scale / shrink)  # a full, corrected or projected step: trust the model more
        length = float(np.linalg.norm(d))
        slow = slow + 1 if shortened or length > contraction * last_length else 0
        last, last_length = f, length
        u = np.clip(point, -u_max, u_max)  # u + (-u_max - u) can round a few ulps past the box's end
    return SqpResult(u, max_iter, int(rows.size), False, f"no convergence in {max_iter} iterations")


def _converged(terminal: NDArray[np.float64], h: NDArray[np.float64], path_scale: NDArray[np.float64], f: float,
               last: float | None) -> bool:
    """Whether an iterate has converged: its terminal residual and path violations within FEASIBLE, and its
    objective `f` within STALL of the `last` iterate's."""
    return bool(np.abs(terminal).max() <= FEASIBLE and np.all(h >= -FEASIBLE * path_scale) and last is not None
                and abs(last - f) <= STALL * abs(f))


def _second_order_from(second_order_after: int | None, iteration: int, slow: int, slow_after: int,
                       slow_run: int) -> int | None:
    """The iteration after which the Hessian is the Lagrangian's: `second_order_after`, or this iteration's last
    once the iteration converges slowly (SLOW: `slow` slow iterations in a row, past `slow_after`)."""
    if second_order_after is not None and iteration > slow_after and slow >= slow_run:
        return min(second_order_after, iteration - 1)  # converging slowly: Newton from here on
    return second_order_after


def _hessian(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], diagonal: NDArray[np.float64] | None,
             scale: float, damping: float, rows: NDArray[np.intp], path_scale: NDArray[np.float64],
             multipliers: tuple[NDArray[np.float64], NDArray[np.intp]] | None, lagrangian: _Lagrangian | None,
             second_order_after: int | None, iteration: int
             ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, bool, _Lagrangian | None]:
    """The step QP's Hessian at u, its L^-T (None for a diagonal one), whether it is the Lagrangian's, and the
    Lagrangian Hessian kept. The Gauss-Newton Hessian times `scale` (its `diagonal` where diagonal); after
    `second_order_after` iterations, once the last QP's `multipliers` are known, the Lagrangian's
    (`_lagrangian_hessian`), `lagrangian` reused while made for the same scale, damping and path rows (NEWTON_REUSE),
    where one is made."""
    H = scale * (problem.gauss_newton(u) if diagonal is None else diagonal)
    newton, back = False, None
    if second_order_after is not None and iteration > second_order_after and multipliers is not None:
        made_for = (scale, damping, rows.tobytes())
        if lagrangian is None or lagrangian[2] != made_for or lagrangian[3] >= NEWTON_REUSE:
            made = _lagrangian_hessian(problem, limits, u, H, *multipliers, path_scale, damping)
            lagrangian = None if made is None else (*made, made_for, 0)
        else:
            lagrangian = (*lagrangian[:3], lagrangian[3] + 1)
        if lagrangian is not None:
            newton, (H, back) = True, lagrangian[:2]
    if H.ndim == 2 and back is None:
        back = _inverse_factor(H)  # once, for the step's QPs and its second-order correction
    return H, back, newton, lagrangian


def _full_or_corrected(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], d: NDArray[np.float64],
                       H: NDArray[np.float64], g: NDArray[np.float64], S: NDArray[np.float64],
                       rows: NDArray[np.intp], path_scale: NDArray[np.float64], soft: bool,
                       back: NDArray[np.float64] | None, share: float, merit: float, slope: float, penalty: float
                       ) -> NDArray[np.float64] | None:
    """The full step u + d where the merit decreases enough (ARMIJO), else its second-order correction
    (`_second_order`; none after a relaxed QP, `share` < 1) where that does, else None."""
    full = u + d
    point: NDArray[np.float64] | None = full  # the next iterate, as the line search tried it
    if _merit(problem, limits, full, penalty) > merit + ARMIJO * slope:
        correction = None if share < 1.0 else _second_order(problem, limits, u, d, H, g, S, rows, path_scale,
                                                            soft, back)
        point = None if correction is None else u + correction
        if point is not None and _merit(problem, limits, point, penalty) > merit + ARMIJO * slope:
            point = None
    return point


def _next_damping(damping: float, accepted: bool) -> float:
    """The Lagrangian Hessian's damping after a step (DAMPING): divided by its factor after a full or corrected
    step (`accepted`), else at least its low end or multiplied by the factor; zero below the low end."""
    low, factor = DAMPING
    damping = damping / factor if accepted else max(low, damping * factor)
    return damping if damping >= low else 0.0


def _searched_step(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], d: NDArray[np.float64],
                   merit: float, slope: float, penalty: float) -> tuple[NDArray[np.float64], bool, bool] | None:
    """Where neither the full nor the corrected step decreases the merit: the projected line search (`_projected`),
    else backtracking along d (`_backtrack`). (the next iterate, whether its step was cut, whether it was
    projected), or None where neither finds a decrease."""
    projected = _projected(problem, limits, u, d, merit, slope, penalty)
    if projected is not None:
        point, t = projected
        return point, t < 1.0, True
    backtracked = _backtrack(problem, limits, u, d, merit, slope, penalty)
    return None if backtracked is None else (backtracked, True, False)


def _lagrangian_hessian(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], H: NDArray[np.float64],
                        lam: NDArray[np.float64], rows: NDArray[np.intp], path_scale: NDArray[np.float64],
                        damping: float) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The Lagrangian's Hessian at u, (N n, N n), and its L^-T (`_inverse_factor`): H (the Gauss-Newton Hessian, or
    its diagonal) plus the dynamics' curvature weighted by the QP multipliers `lam` (the terminal rows', then the
    path `rows`'), made positive definite by AUGMENT and damped by `damping` times R's diagonal; None where the
    curvature is not the plant's or no rho of AUGMENT makes it positive definite."""
    N, n = problem.steps, problem.n
    U, X, _, S = problem.evaluate(u)
    terminal, path = lam[:2 * n], lam[2 * n:]
    w = limits.on_states(rows, path / path_scale[rows], N, n)  # h's rows were divided by their scales
    w[1:] += (X[1:] - problem.xg) @ (0.5 * (problem.Q + problem.Q.T))  # the objective's own state terms
    w[N] += terminal
    curvature = problem.second_order(u, w)
    if curvature is None:
        return None
    base = np.diag(H) if H.ndim == 1 else H
    hessian = base + curvature
    active = rows[np.abs(path) > 0.0]
    A = np.vstack([S[-1], limits.jacobian(S, active) / path_scale[active, None]])
    AtA = A.T @ A
    unit = float(np.max(np.diag(hessian))) / max(float(np.max(np.diag(AtA))), np.finfo(float).tiny)
    damped = damping * np.tile(np.diag(problem.R), N)
    for rho in unit * AUGMENT:
        augmented = hessian + rho * AtA
        augmented[np.diag_indices_from(augmented)] += damped
        factor, info = scipy.linalg.lapack.dpotrf(augmented, lower=1, clean=1)
        if info == 0:
            return augmented, _inverse_factor(augmented, factor)
    return None


def _merit(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], penalty: float) -> float:
    """The l1 merit at u; infinite where the rollout diverges."""
    try:
        return problem.objective(u) + penalty * violation(problem, limits, u)
    except SolverError:
        return float("inf")


def _backtrack(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], d: NDArray[np.float64],
               merit: float, slope: float, penalty: float) -> NDArray[np.float64] | None:
    """u + t d for the largest t = 1/2, 1/4, ... >= MIN_STEP with enough decrease, else None."""
    t = 0.5
    while t >= MIN_STEP:
        trial = u + t * d
        if _merit(problem, limits, trial, penalty) <= merit + ARMIJO * t * slope:
            return trial
        t *= 0.5
    return None


def _projected(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], d: NDArray[np.float64],
               merit: float, slope: float, penalty: float) -> tuple[NDArray[np.float64], float] | None:
    """(`projector`'s torques, t) for the largest t = 1, 1/2, ... >= MIN_STEP with enough decrease, else None."""
    project = projector(problem, limits, u, d)
    t = 1.0
    while t >= MIN_STEP:
        try:
            trial: NDArray[np.float64] | None = project(t)
        except SolverError:
            trial = None
        if trial is not None and _merit(problem, limits, trial, penalty) <= merit + ARMIJO * t * slope:
            return trial, t
        t *= 0.5
    return None


def projector(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], d: NDArray[np.float64]
              ) -> Callable[[float], NDArray[np.float64]]:
    """t -> the torques (N n,) with which the model tracks the linearised prediction of the step t d from u (N n,):
    its rollout under u_k + t d_k + K_k (x_k + t (S d)_k - x'_k), x'_k its own state, clipped to the torque bound
    (`Shooting.tracked`; K_k: `tracking.bryson_gains` on the Jacobians of u's rollout, S: its sensitivities). Its
    torques are u + t d to first order in t, and its motion stays near the predicted states where the open-loop
    step of the same t drifts away from them (module docstring). The returned function raises SolverError where
    that rollout diverges."""
    N, n = problem.steps, problem.n
    U, X, A, S = problem.evaluate(u)
    K = bryson_gains(A, input_blocks(S), limits.u_max)
    predicted, D = S @ d, d.reshape(N, n)

    def project(t: float) -> NDArray[np.float64]:
        return problem.tracked(U + t * D, X + t * predicted, K, limits.u_max).ravel()

    return project


def _second_order(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], d: NDArray[np.float64],
                  H: NDArray[np.float64], g: NDArray[np.float64], S: NDArray[np.float64], rows: NDArray[np.intp],
                  path_scale: NDArray[np.float64], soft: bool, back: NDArray[np.float64] | None
                  ) -> NDArray[np.float64] | None:
    """The second-order correction of a refused step d: the QP again (`back`: its Hessian's L^-T where known) with
    the constraints' values at u + d linearised back to u (their curvature along d), or None."""
    try:
        U, X = problem.states(u + d)
    except SolverError:
        return None
    size = len(u)
    G = limits.jacobian(S, rows) / path_scale[rows, None]
    terminal = X[-1] - problem.xg - S[-1] @ d
    h = limits.values(U, X)[:4 * size][rows] / path_scale[rows] - G @ d
    u_max = np.tile(limits.u_max, problem.steps)
    solved = _qp(H, g, S[-1], terminal, G, h, -u_max - u, u_max - u, soft, back)
    return None if solved is None else solved[0]
