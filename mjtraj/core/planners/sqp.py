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
`mjtraj.core.planners.nonlinear.SOLVERS`). So once the iteration is seen converging slowly (`slow`), and after
`second_order_after` iterations in any case, the Hessian becomes the Lagrangian's: H_GN plus that curvature,
weighted by the last QP's multipliers (`Shooting.second_order`, about 10 ms at N = 100), made positive definite on
the constraints' null space by an augmented term (`augment`) and damped where a step is cut (`damping`): Newton's
method, locally quadratic. A solve given the plan of an earlier start (`join`) stops once its iterate comes within
`join_distance` of it: it is converging to the same minimum.

The torque bound is a box on u: iterates never leave it (each is put back on the box's end that rounding took it a
few ulps past). Path rows are screened as in SLSQP's solve (`shooting.SCREEN`); a row left out enters once an
iterate nears it. A QP whose linearised constraints cannot all hold is solved again asking them to close only part
of the way (`relaxed`), then with the path rows soft (DAQP's soft constraints), so that the terminal condition
still holds and the merit decides.

`curvature_scale`, `shrink`, `slow`, `second_order_after`, `augment`, `damping`, `join_distance` and `relaxed`
are fields of `SqpSettings`, each with its rule; docs/design.md ("The nonlinear planners' settings") gives the
measurements behind their defaults.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from mjtraj.checks import in_range, nonnegative_int, positive, positive_int
from mjtraj.core.planners.shooting import SCREEN, PathLimits, Shooting, input_blocks
from mjtraj.core.planners.tracking import bryson_gains
from mjtraj.exceptions import InvalidInputError, SolverError

DAQP_TOL = 1e-12
"""DAQP's primal and dual tolerances in `_qp` (the floor's and the predictive laws' QPs; the SQP's own are
`SqpSettings.daqp_tol`, the same by default): the QPs' rows are of order one."""
SENSE_FREE, SENSE_EQUAL, SENSE_SOFT = 0, 5, 8
"""DAQP's constraint kinds: inequality, equality, soft inequality."""


@dataclass(frozen=True)
class SqpSettings:
    """The Gauss-Newton SQP's tunables, each with its rule; the defaults are the published plans'. docs/design.md,
    "The nonlinear planners' settings", gives the measurements behind each default.

    Pass one to the nonlinear planners inside their settings, `make("nonlinear_optimal",
    settings=NonlinearSettings(sqp=SqpSettings(...)))` (`mjtraj.core.planners.nonlinear.NonlinearSettings`), or to
    `gauss_newton_sqp(settings=...)`. A plan records the ones that differ from the defaults (`changes`).

    Raises:
      InvalidInputError: a value out of its range (the message names it as `settings.sqp.NAME`).
    """

    curvature_scale: float = 10.0
    """The first QP's Hessian is this multiple of the Gauss-Newton Hessian: larger values take shorter first steps
    (the role of SLSQP's first curvature model)."""
    shrink: float = 4.0
    """The multiple is divided by this after every full, corrected or projected step, down to 1 (Gauss-Newton's own
    Hessian); >= 1."""
    armijo: float = 1e-4
    """A trial step is accepted where the merit falls by at least this fraction of its predicted fall; in (0, 1)."""
    min_step: float = 2.0 ** -20
    """The line search gives up below this fraction of the QP's step; in (0, 1]."""
    feasible: float = 1e-10
    """An iterate has converged only where |x_N - x_g| (rad, rad/s) and every path violation (relative to its
    limit) are within this, ..."""
    stall: float = 1e-10
    """... and its objective changed by at most this fraction over the last step."""
    second_order_after: int | None = 20
    """From the iteration after this at the latest (`slow`: sooner), each QP's Hessian is the Lagrangian's, the
    dynamics' curvature weighted by the last QP's multipliers added (Newton's method); None: never (Gauss-Newton
    throughout)."""
    slow: tuple[int, int, float] = (8, 3, 0.7)
    """(after, run, contraction): past iteration `after`, the Hessian becomes the Lagrangian's once `run` iterations
    in a row were slow: the line search shortened the step (a projected step below t = 1, or a backtracked one), or
    the QP's step was longer than `contraction` times the one before."""
    augment: tuple[float, ...] = tuple(float(10.0 ** k) for k in range(8))
    """rho of H + rho A^T A (A: the terminal rows and the last QP's active path rows), which makes the indefinite
    Lagrangian's Hessian positive definite without changing the QP's solution on those rows, is tried at these
    multiples of max diag(H) / max diag(A^T A), smallest first; where none does, the iteration keeps the
    Gauss-Newton Hessian."""
    damping: tuple[float, float] = (0.1, 4.0)
    """(low, factor): the Lagrangian Hessian's Levenberg-Marquardt damping, a multiple of R's diagonal. A step
    neither full nor corrected sets it to at least `low` or multiplies it by `factor`; a full or corrected one
    divides it by `factor`; below `low` it is zero."""
    newton_reuse: int = 5
    """The Lagrangian's Hessian (and its factor) is used again for up to this many iterations after the one it was
    made in, while the curvature scale, the damping and the path rows are unchanged (0: made every iteration)."""
    join_distance: float = 1e-1
    """A solve given an earlier start's plan (`gauss_newton_sqp`'s `join`) stops once an iterate is within this
    distance of it, relative to its norm: it is converging to the same minimum."""
    relaxed: tuple[float, ...] = (0.5, 0.25)
    """Where the linearised constraints admit no step, the QP asks them to close only these shares of the way, the
    largest first (the terminal residual and each violated path row scaled by it); where none admits a step, the
    path rows go soft. Each in (0, 1); () goes soft at once."""
    daqp_tol: float = DAQP_TOL
    """DAQP's primal and dual tolerances for the SQP's QPs (their rows are of order one)."""

    def __post_init__(self) -> None:
        checked = {
            "curvature_scale": positive("settings.sqp.curvature_scale", self.curvature_scale),
            "shrink": in_range("settings.sqp.shrink", self.shrink, 1.0, np.inf, low_open=False),
            "armijo": in_range("settings.sqp.armijo", self.armijo, 0.0, 1.0),
            "min_step": in_range("settings.sqp.min_step", self.min_step, 0.0, 1.0, high_open=False),
            "feasible": positive("settings.sqp.feasible", self.feasible),
            "stall": positive("settings.sqp.stall", self.stall),
            "second_order_after": None if self.second_order_after is None else
            nonnegative_int("settings.sqp.second_order_after", self.second_order_after),
            "slow": _slow(self.slow),
            "augment": _shares("settings.sqp.augment", self.augment, np.inf, at_least=1),
            "damping": _damping(self.damping),
            "newton_reuse": nonnegative_int("settings.sqp.newton_reuse", self.newton_reuse),
            "join_distance": positive("settings.sqp.join_distance", self.join_distance),
            "relaxed": _shares("settings.sqp.relaxed", self.relaxed, 1.0),
            "daqp_tol": positive("settings.sqp.daqp_tol", self.daqp_tol),
        }
        for name, value in checked.items():
            object.__setattr__(self, name, value)  # normalised: floats, ints and tuples

    def changes(self) -> list[str]:
        """The settings that differ from the defaults, as 'name=value' in field order ([]: the defaults)."""
        return changes(self)


def changes(settings: Any, prefix: str = "") -> list[str]:
    """The fields of the settings dataclass `settings` that differ from its class's defaults, as 'name=value' (the
    value's repr) in field order; a nested settings dataclass's as 'name.field=value'."""
    default = type(settings)()
    out = []
    for f in dataclasses.fields(settings):
        value = getattr(settings, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            out += changes(value, f"{prefix}{f.name}.")
        elif value != getattr(default, f.name):
            out.append(f"{prefix}{f.name}={value!r}")
    return out


def _slow(value: Any) -> tuple[int, int, float]:
    """`SqpSettings.slow` checked: (a whole number >= 0, a whole number >= 1, a number > 0)."""
    if not (isinstance(value, (tuple, list)) and len(value) == 3):
        raise InvalidInputError(f"settings.sqp.slow: expected (after, run, contraction), got {value!r}")
    after, run, contraction = value
    return (nonnegative_int("settings.sqp.slow[0]", after), positive_int("settings.sqp.slow[1]", run),
            positive("settings.sqp.slow[2]", contraction))


def _damping(value: Any) -> tuple[float, float]:
    """`SqpSettings.damping` checked: (a number > 0, a number > 1)."""
    if not (isinstance(value, (tuple, list)) and len(value) == 2):
        raise InvalidInputError(f"settings.sqp.damping: expected (low, factor), got {value!r}")
    return (positive("settings.sqp.damping[0]", value[0]), in_range("settings.sqp.damping[1]", value[1], 1.0, np.inf))


def _shares(name: str, value: Any, high: float, *, at_least: int = 0) -> tuple[float, ...]:
    """`value` as a tuple of at least `at_least` numbers in (0, high), or InvalidInputError naming `name`."""
    if not isinstance(value, (tuple, list)) or len(value) < at_least:
        raise InvalidInputError(f"{name}: expected {'at least one number' if at_least else 'numbers'} in (0, "
                                f"{high:g}), got {value!r}")
    return tuple(in_range(f"{name}[{i}]", v, 0.0, high) for i, v in enumerate(value))


DEFAULT_SETTINGS = SqpSettings()
"""The published plans' settings."""


@dataclass(frozen=True)
class SqpResult:
    """u: the last iterate (N n,), or the plan it joined; converged: whether it met the convergence test
    (`SqpSettings.feasible` and `stall`) or joined; rows: path rows in the last QP; joined: whether it stopped within
    `SqpSettings.join_distance` of the plan given."""

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
    """argmin 1/2 d^T H d + g^T d s.t. C d = -c, G d >= -h, low <= d <= high by DAQP at DAQP_TOL (`_qp_to`)."""
    return _qp_to(DAQP_TOL, H, g, C, c, G, h, low, high, soft, back, iter_limit)


def _qp_to(tol: float, H: NDArray[np.float64], g: NDArray[np.float64], C: NDArray[np.float64],
           c: NDArray[np.float64], G: NDArray[np.float64], h: NDArray[np.float64], low: NDArray[np.float64],
           high: NDArray[np.float64], soft: bool, back: NDArray[np.float64] | None = None,
           iter_limit: int | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """argmin 1/2 d^T H d + g^T d s.t. C d = -c, G d >= -h, low <= d <= high by DAQP, to its primal and dual
    tolerance `tol`: (d, the multipliers of the
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
    z, _, status, info = daqp.solve(np.eye(len(g)), f, general, upper, lower, sense, primal_tol=tol, dual_tol=tol,
                                    **capped)
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
             back: NDArray[np.float64] | None = None, *, settings: SqpSettings = DEFAULT_SETTINGS
             ) -> tuple[NDArray[np.float64], NDArray[np.float64], float, bool] | None:
    """The SQP's step QP (`_qp`'s arguments, the constraints C d = -c, G d >= -h; DAQP at `settings.daqp_tol`):
    (d, multipliers, share, soft). Where the constraints admit no step, they are asked to close only `share` of the
    way (`settings.relaxed`: c and every negative h scaled by it); where no share does, the rows G are made soft
    (share 1). None where even that fails,
    or where the rows C alone admit no step in the box: the soft solve is then not tried (on a dense Hessian DAQP
    took 0.23 s to give it up, nominal 120 of seed 1 for `nonlinear_optimal`; the check took 0.03 s). `back`: a
    dense H's L^-T where already known (`gauss_newton_sqp` factors it once per step), else each solve factors H."""
    tol = settings.daqp_tol
    solved = _qp_to(tol, H, g, C, c, G, h, low, high, False, back)
    if solved is not None:
        return (*solved, 1.0, False)
    for share in settings.relaxed:
        solved = _qp_to(tol, H, g, C, share * c, G, np.maximum(h, share * h), low, high, False, back)
        if solved is not None:
            return (*solved, share, False)
    if _qp_to(tol, H, g, C, c, G[:0], h[:0], low, high, False, back) is None:
        return None  # the terminal rows alone admit no step in the box: no soft path row can change that
    solved = _qp_to(tol, H, g, C, c, G, h, low, high, True, back)
    return None if solved is None else (*solved, 1.0, True)


_Lagrangian = tuple[NDArray[np.float64], NDArray[np.float64], tuple[float, float, bytes], int]
"""The last Lagrangian Hessian, its L^-T, what it was made for (scale, damping, path rows), and its reuses."""


def gauss_newton_sqp(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], *, max_iter: int,
                     join: NDArray[np.float64] | None = None, settings: SqpSettings = DEFAULT_SETTINGS) -> SqpResult:
    """Minimise `problem`'s objective from u (N n,), within the torque box, subject to x_N = x_g and the path limits
    (module docstring), in at most `max_iter` iterations, with the tunables `settings`. Returns the last iterate
    whether or not it converged, or `join` (a converged plan of the same problem, (N n,)) once an iterate comes
    within `settings.join_distance` of it (see SqpResult).

    Raises:
      SolverError: the rollout of u diverged.
    """
    N, n = problem.steps, problem.n
    size = N * n
    u_max = np.tile(limits.u_max, N)
    path_scale = limits.scale(N)[:4 * size]
    diagonal = problem.diagonal_hessian  # the Hessian as its diagonal where it is diagonal (the effort bound's)
    scale, penalty, damping = settings.curvature_scale, 0.0, 0.0
    second_order_after = settings.second_order_after
    last: float | None = None
    rows = np.zeros(0, dtype=np.intp)
    multipliers: tuple[NDArray[np.float64], NDArray[np.intp]] | None = None  # the last QP's, and its path rows
    slow_after, slow_run, contraction = settings.slow
    slow, last_length = 0, float("inf")  # slow iterations in a row; the last QP step's length
    lagrangian: _Lagrangian | None = None
    for iteration in range(1, max_iter + 2):  # the last pass only tests the last step's iterate
        if join is not None and np.linalg.norm(u - join) <= settings.join_distance * np.linalg.norm(join):
            return SqpResult(join, iteration - 1, int(rows.size), True, "joined the plan given", joined=True)
        U, X = problem.states(u)
        f = problem.objective(u)
        terminal = X[-1] - problem.xg
        h = limits.values(U, X)[:4 * size]
        if _converged(terminal, h, path_scale, f, last, settings):
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
                                               multipliers, lagrangian, second_order_after, iteration, settings)
        solved = _step_qp(H, g, S[-1], terminal, G, h[rows] / path_scale[rows], -u_max - u, u_max - u, back,
                          settings=settings)
        if solved is None:
            return SqpResult(u, iteration, int(rows.size), False, "the linearised constraints admit no step")
        d, lam, share, soft = solved
        multipliers = (lam, rows)
        penalty = max(penalty, 2.0 * float(np.abs(lam).max(initial=0.0)))
        merit = f + penalty * now
        slope = float(g @ d) - penalty * share * now  # the merit's predicted change along d
        point = _full_or_corrected(problem, limits, u, d, H, g, S, rows, path_scale, soft, back, share, merit, slope,
                                   penalty, settings)
        if newton:
            damping = _next_damping(damping, point is not None, settings.damping)
        shortened, trusted = False, True
        if point is None:
            searched = _searched_step(problem, limits, u, d, merit, slope, penalty, settings)
            if searched is None:
                return SqpResult(u, iteration, int(rows.size), False, "the line search found no decrease")
            point, shortened, trusted = searched
        if trusted:
            scale = max(1.0, scale / settings.shrink)  # a full, corrected or projected step: trust the model more
        length = float(np.linalg.norm(d))
        slow = slow + 1 if shortened or length > contraction * last_length else 0
        last, last_length = f, length
        u = np.clip(point, -u_max, u_max)  # u + (-u_max - u) can round a few ulps past the box's end
    return SqpResult(u, max_iter, int(rows.size), False, f"no convergence in {max_iter} iterations")


def _converged(terminal: NDArray[np.float64], h: NDArray[np.float64], path_scale: NDArray[np.float64], f: float,
               last: float | None, settings: SqpSettings) -> bool:
    """Whether an iterate has converged: its terminal residual and path violations within `settings.feasible`, and
    its objective `f` within `settings.stall` of the `last` iterate's."""
    feasible = settings.feasible
    return bool(np.abs(terminal).max() <= feasible and np.all(h >= -feasible * path_scale) and last is not None
                and abs(last - f) <= settings.stall * abs(f))


def _second_order_from(second_order_after: int | None, iteration: int, slow: int, slow_after: int,
                       slow_run: int) -> int | None:
    """The iteration after which the Hessian is the Lagrangian's: `second_order_after`, or this iteration's last
    once the iteration converges slowly (`SqpSettings.slow`: `slow` slow iterations in a row, past `slow_after`)."""
    if second_order_after is not None and iteration > slow_after and slow >= slow_run:
        return min(second_order_after, iteration - 1)  # converging slowly: Newton from here on
    return second_order_after


def _hessian(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], diagonal: NDArray[np.float64] | None,
             scale: float, damping: float, rows: NDArray[np.intp], path_scale: NDArray[np.float64],
             multipliers: tuple[NDArray[np.float64], NDArray[np.intp]] | None, lagrangian: _Lagrangian | None,
             second_order_after: int | None, iteration: int, settings: SqpSettings
             ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, bool, _Lagrangian | None]:
    """The step QP's Hessian at u, its L^-T (None for a diagonal one), whether it is the Lagrangian's, and the
    Lagrangian Hessian kept. The Gauss-Newton Hessian times `scale` (its `diagonal` where diagonal); after
    `second_order_after` iterations, once the last QP's `multipliers` are known, the Lagrangian's
    (`_lagrangian_hessian`), `lagrangian` reused while made for the same scale, damping and path rows
    (`settings.newton_reuse`), where one is made."""
    H = scale * (problem.gauss_newton(u) if diagonal is None else diagonal)
    newton, back = False, None
    if second_order_after is not None and iteration > second_order_after and multipliers is not None:
        made_for = (scale, damping, rows.tobytes())
        if lagrangian is None or lagrangian[2] != made_for or lagrangian[3] >= settings.newton_reuse:
            made = _lagrangian_hessian(problem, limits, u, H, *multipliers, path_scale, damping, settings.augment)
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
                       back: NDArray[np.float64] | None, share: float, merit: float, slope: float, penalty: float,
                       settings: SqpSettings) -> NDArray[np.float64] | None:
    """The full step u + d where the merit decreases enough (`settings.armijo`), else its second-order correction
    (`_second_order`; none after a relaxed QP, `share` < 1) where that does, else None."""
    full = u + d
    point: NDArray[np.float64] | None = full  # the next iterate, as the line search tried it
    armijo = settings.armijo
    if _merit(problem, limits, full, penalty) > merit + armijo * slope:
        correction = None if share < 1.0 else _second_order(problem, limits, u, d, H, g, S, rows, path_scale,
                                                            soft, back, settings.daqp_tol)
        point = None if correction is None else u + correction
        if point is not None and _merit(problem, limits, point, penalty) > merit + armijo * slope:
            point = None
    return point


def _next_damping(damping: float, accepted: bool, rule: tuple[float, float]) -> float:
    """The Lagrangian Hessian's damping after a step (`rule`: `SqpSettings.damping`, (low, factor)): divided by the
    factor after a full or corrected step (`accepted`), else at least `low` or multiplied by the factor; zero below
    `low`."""
    low, factor = rule
    damping = damping / factor if accepted else max(low, damping * factor)
    return damping if damping >= low else 0.0


def _searched_step(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], d: NDArray[np.float64],
                   merit: float, slope: float, penalty: float, settings: SqpSettings
                   ) -> tuple[NDArray[np.float64], bool, bool] | None:
    """Where neither the full nor the corrected step decreases the merit: the projected line search (`_projected`),
    else backtracking along d (`_backtrack`), each with `settings.armijo` and `settings.min_step`. (the next
    iterate, whether its step was cut, whether it was projected), or None where neither finds a decrease."""
    projected = _projected(problem, limits, u, d, merit, slope, penalty, settings.armijo, settings.min_step)
    if projected is not None:
        point, t = projected
        return point, t < 1.0, True
    backtracked = _backtrack(problem, limits, u, d, merit, slope, penalty, settings.armijo, settings.min_step)
    return None if backtracked is None else (backtracked, True, False)


def _lagrangian_hessian(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], H: NDArray[np.float64],
                        lam: NDArray[np.float64], rows: NDArray[np.intp], path_scale: NDArray[np.float64],
                        damping: float, augment: tuple[float, ...]
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The Lagrangian's Hessian at u, (N n, N n), and its L^-T (`_inverse_factor`): H (the Gauss-Newton Hessian, or
    its diagonal) plus the dynamics' curvature weighted by the QP multipliers `lam` (the terminal rows', then the
    path `rows`'), made positive definite by a multiple rho of A^T A (`augment`: `SqpSettings.augment`) and damped
    by `damping` times R's diagonal; None where the curvature is not the plant's or no rho of `augment` makes it
    positive definite."""
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
    for rho in unit * np.asarray(augment):
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
               merit: float, slope: float, penalty: float, armijo: float, min_step: float
               ) -> NDArray[np.float64] | None:
    """u + t d for the largest t = 1/2, 1/4, ... >= `min_step` with enough decrease (`armijo`), else None."""
    t = 0.5
    while t >= min_step:
        trial = u + t * d
        if _merit(problem, limits, trial, penalty) <= merit + armijo * t * slope:
            return trial
        t *= 0.5
    return None


def _projected(problem: Shooting, limits: PathLimits, u: NDArray[np.float64], d: NDArray[np.float64],
               merit: float, slope: float, penalty: float, armijo: float, min_step: float
               ) -> tuple[NDArray[np.float64], float] | None:
    """(`projector`'s torques, t) for the largest t = 1, 1/2, ... >= `min_step` with enough decrease (`armijo`),
    else None."""
    project = projector(problem, limits, u, d)
    t = 1.0
    while t >= min_step:
        try:
            trial: NDArray[np.float64] | None = project(t)
        except SolverError:
            trial = None
        if trial is not None and _merit(problem, limits, trial, penalty) <= merit + armijo * t * slope:
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
                  path_scale: NDArray[np.float64], soft: bool, back: NDArray[np.float64] | None, tol: float
                  ) -> NDArray[np.float64] | None:
    """The second-order correction of a refused step d: the QP again (`back`: its Hessian's L^-T where known; DAQP
    at `tol`) with the constraints' values at u + d linearised back to u (their curvature along d), or None."""
    try:
        U, X = problem.states(u + d)
    except SolverError:
        return None
    size = len(u)
    G = limits.jacobian(S, rows) / path_scale[rows, None]
    terminal = X[-1] - problem.xg - S[-1] @ d
    h = limits.values(U, X)[:4 * size][rows] / path_scale[rows] - G @ d
    u_max = np.tile(limits.u_max, problem.steps)
    solved = _qp_to(tol, H, g, S[-1], terminal, G, h, -u_max - u, u_max - u, soft, back)
    return None if solved is None else solved[0]
