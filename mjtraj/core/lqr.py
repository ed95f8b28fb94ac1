"""The paper's QP solved exactly through its banded KKT system, with a primal-dual active set for the bounds.

min 1/2 sum_{k=1..N} x_k^T Q x_k + 1/2 sum_{k=0..N-1} u_k^T R u_k  s.t.  x_{k+1} = Ad x_k + Bd u_k,  x_N = 0,
|u_k| <= u_max. Its first-order conditions, with multipliers lambda_{k+1} of the dynamics, are
R u_k + Bd^T lambda_{k+1} = 0,  Q x_k + Ad^T lambda_{k+1} - lambda_k = 0,  Ad x_k + Bd u_k - x_{k+1} = 0.
Unknowns ordered stage by stage as [lambda_{k+1}, u_k, x_{k+1}] make this one banded matrix, (nu + 2 nx) N square
with 2 nx - 1 bands either side (11 for the 3-joint arm), factorised by LAPACK's banded LU (`gbtrf`, through
SciPy): time linear in N, no condensing. A fixed variable (x_N, an input on its bound) has its row replaced by the
identity; a few fixed inputs are instead solved from the first factorisation by a Schur complement.

Box constraints: inputs in the active set are fixed at their bound and the rest solved; the set changes until the
KKT conditions hold (free inputs inside the box, fixed inputs pushed against their bound by the cost). A convex QP
whose KKT conditions hold is solved: the result is the exact optimum, not an approximation. Problems whose set does
not settle within `max_iter`, or whose free inputs cannot reach x_N = 0, are reported, for an iterative solver
(OSQP) to take over.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class BoxLQRSolution:
    """Solutions of P problems: U (P, N, nu), X (P, N+1, nx); `solved` (P,) marks those whose KKT conditions
    hold; `iterations` (P,) counts active-set iterations; `active` (P, N, nu) is -1/0/+1 for lower/free/upper."""

    U: NDArray[np.float64]
    X: NDArray[np.float64]
    solved: NDArray[np.bool_]
    iterations: NDArray[np.int64]
    active: NDArray[np.int8]


@dataclass(frozen=True)
class _Pattern:
    """Where the KKT matrix's entries go in LAPACK's band storage, for one (nx, nu, N).

    The band array (2 kl + ku + 1, n) is Fortran-ordered, as LAPACK reads it (no copy on the way in), and flat
    indices count column by column. The matrix is block-Toeplitz stage by stage, so every stage's columns hold the
    same band entries: `stage_cells` are their flat indices into one stage's band columns, `source` for each its
    index in the stage template [vec Bd, vec Ad, vec R, vec Bd^T, vec Q, vec Ad^T, -1]; `outside`: flat indices of
    the band cells of rows outside the matrix (the first stage's columns get no Ad^T from a stage before it, the
    last's no Ad from a stage after it). `rows`: (n, kl + ku + 1) flat indices of each row's band cells, `valid`
    marking those inside the matrix."""

    nx: int
    nu: int
    steps: int
    kl: int
    ku: int
    stage_cells: NDArray[np.intp]
    source: NDArray[np.intp]
    outside: NDArray[np.intp]
    rows: NDArray[np.intp]
    valid: NDArray[np.bool_]

    @property
    def size(self) -> int:
        return (self.nu + 2 * self.nx) * self.steps

    @property
    def band_rows(self) -> int:
        return 2 * self.kl + self.ku + 1

    def band(self, Ad: NDArray[np.float64], Bd: NDArray[np.float64], Q: NDArray[np.float64],
             R: NDArray[np.float64]) -> NDArray[np.float64]:
        """The KKT matrix of (Ad, Bd, Q, R), every variable free, in band storage (2 kl + ku + 1, n), Fortran order."""
        template = np.concatenate([Bd.ravel(), Ad.ravel(), R.ravel(), Bd.T.ravel(), Q.ravel(), Ad.T.ravel(), [-1.0]])
        stage = np.zeros((self.nu + 2 * self.nx, self.band_rows))  # its columns, one per row
        stage.reshape(-1)[self.stage_cells] = template[self.source]
        columns = np.tile(stage, (self.steps, 1))
        columns.reshape(-1)[self.outside] = 0.0
        return columns.T


def _blocks(nx: int, nu: int) -> list[tuple[str, int, int, int, int, int]]:
    """The KKT matrix's blocks: (value, row offset, column offset, stage shift, rows, columns), offsets within a
    stage [lambda_{k+1}, u_k, x_{k+1}]; "-I" is -1 on the diagonal."""
    lam, u, x = 0, nx, nx + nu
    return [("Bd", lam, u, 0, nx, nu), ("-I", lam, x, 0, nx, nx), ("Ad", lam, x, -1, nx, nx),
            ("R", u, u, 0, nu, nu), ("BdT", u, lam, 0, nu, nx),
            ("Q", x, x, 0, nx, nx), ("-I", x, lam, 0, nx, nx), ("AdT", x, lam, 1, nx, nx)]


@functools.lru_cache(maxsize=16)
def _pattern(nx: int, nu: int, steps: int) -> _Pattern:
    stage = nu + 2 * nx
    n = stage * steps
    sizes = {"Bd": nx * nu, "Ad": nx * nx, "R": nu * nu, "BdT": nu * nx, "Q": nx * nx, "AdT": nx * nx}
    start = dict(zip(sizes, np.cumsum([0, *sizes.values()])[:-1].tolist(), strict=True))
    minus_one = sum(sizes.values())
    rows, cols, source = [], [], []  # of each block in the columns of one stage, rows relative to that stage
    for name, r0, c0, shift, nr, nc in _blocks(nx, nu):
        if abs(shift) >= steps:  # one stage: no block between stages
            continue
        if name == "-I":  # the diagonal only
            i, j = np.arange(nr), np.arange(nc)
            where = np.full(i.shape, minus_one)
        else:
            i, j = np.arange(nr)[:, None], np.arange(nc)[None, :]
            where = start[name] + nc * i + j
        r, c, w = np.broadcast_arrays(r0 + i - stage * shift, c0 + j, where)
        rows.append(r.ravel())
        cols.append(c.ravel())
        source.append(w.ravel())
    row, col = np.concatenate(rows), np.concatenate(cols)
    kl, ku = int(np.max(row - col)), int(np.max(col - row))
    band_rows = 2 * kl + ku + 1
    stage_cells = col * band_rows + kl + ku + row - col
    matrix_rows = np.arange(n)[:, None] + np.arange(band_rows)[None, :] - kl - ku  # of each band cell, by column
    outside = np.flatnonzero((matrix_rows < 0) | (matrix_rows >= n))
    band_cols = np.arange(n)[:, None] + np.arange(-kl, ku + 1)[None, :]
    valid = (band_cols >= 0) & (band_cols < n)
    row_cells = np.clip(band_cols, 0, n - 1) * band_rows + kl + ku + np.arange(n)[:, None] - band_cols
    return _Pattern(nx, nu, steps, kl, ku, stage_cells, np.concatenate(source), outside, row_cells, valid)


SCHUR_MAX = 6
"""Most inputs on a bound solved from the first factorisation by a Schur complement (one band solve per input);
more are solved by factorising the system with their rows replaced (about the cost of seven band solves)."""


class _KKT:
    """One problem's KKT system with x_N = 0, factorised once with every input free; `solve` fixes inputs.

    Fixing the variables F at v borders the system: K z - E_F mu = rhs, E_F^T z = v, so with the columns
    C = K^-1 E_F (cached per variable) mu = (E_F^T C)^-1 (v - z0[F]) and z = z0 + C mu, where z0 = K^-1 rhs;
    mu is the fixed inputs' cost gradient."""

    def __init__(self, pattern: _Pattern, matrices: tuple[NDArray[np.float64], ...], rhs: NDArray[np.float64],
                 end_index: NDArray[np.intp]) -> None:
        self.pattern, self.matrices, self.rhs, self.end_index = pattern, matrices, rhs, end_index
        self.factor = self._factor(end_index)
        self.z0 = self._solve(*self.factor, rhs) if self.factor is not None else None
        self.columns: dict[int, NDArray[np.float64]] = {}

    def _factor(self, fixed: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.int32]] | None:
        """LU of the KKT matrix of `matrices` (Ad, Bd, Q, R) with the rows `fixed` replaced by the identity; None
        if singular."""
        from scipy.linalg.lapack import dgbtrf

        pattern = self.pattern
        ab = pattern.band(*self.matrices)
        flat = ab.reshape(-1, order="F")  # a view: the band is Fortran-ordered
        flat[pattern.rows[fixed][pattern.valid[fixed]]] = 0.0
        flat[fixed * pattern.band_rows + pattern.kl + pattern.ku] = 1.0
        lu, piv, info = dgbtrf(ab, pattern.kl, pattern.ku, overwrite_ab=1)
        return (lu, piv) if info == 0 else None

    def _solve(self, lu: NDArray[np.float64], piv: NDArray[np.int32], b: NDArray[np.float64]
               ) -> NDArray[np.float64]:
        from scipy.linalg.lapack import dgbtrs

        x, _ = dgbtrs(lu, self.pattern.kl, self.pattern.ku, b, piv)
        return x  # type: ignore[no-any-return]

    def solve(self, fixed: NDArray[np.intp], value: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The solution with the input variables `fixed` (indices) held at `value`; None where it is singular."""
        if self.z0 is None or self.factor is None:
            return None
        if fixed.size == 0:
            return self.z0
        if fixed.size > SCHUR_MAX:
            factor = self._factor(np.concatenate([fixed, self.end_index]))
            if factor is None:
                return None
            b = self.rhs.copy()
            b[fixed] = value
            return self._solve(*factor, b)
        missing = [int(i) for i in fixed if int(i) not in self.columns]
        if missing:
            unit = np.zeros((self.pattern.size, len(missing)))
            unit[missing, np.arange(len(missing))] = 1.0
            for i, column in zip(missing, self._solve(*self.factor, unit).T, strict=True):
                self.columns[i] = column
        C = np.stack([self.columns[int(i)] for i in fixed], axis=1)
        try:
            mu = np.linalg.solve(C[fixed], value - self.z0[fixed])
        except np.linalg.LinAlgError:
            return None
        z = self.z0 + C @ mu
        z[fixed] = value
        return z


def box_lqr(Ad: NDArray[np.float64], Bd: NDArray[np.float64], Q: NDArray[np.float64], R: NDArray[np.float64],
            x0: NDArray[np.float64], steps: int, u_max: NDArray[np.float64], *, max_iter: int = 30,
            tol: float = 1e-9) -> BoxLQRSolution:
    """The bounded QP for P problems, each by a primal-dual active set over its banded KKT system.

    Start from the unbounded optimum; each iteration fixes at its bound every free input that lies outside the
    box, and frees every fixed input whose cost gradient dJ/du_k = R u_k + Bd^T lambda_{k+1} no longer pushes it
    against the bound; a problem is solved when nothing changes (the KKT conditions hold to `tol`, relative to the
    bound and to the largest gradient). Each problem is solved on its own, so one problem gives the same bits alone
    or among others.

    Args:
      Ad (P, nx, nx), Bd (P, nx, nu), Q (P, nx, nx), R (P, nu, nu), x0 (P, nx); u_max: (P, nu), N m.

    Returns:
      The solutions; a problem not solved (its set did not settle, or x_N = 0 is out of its free inputs' reach)
      has `solved` False and its last iterate.
    """
    n_p, nx, nu = Bd.shape
    pattern = _pattern(nx, nu, steps)
    stage = nu + 2 * nx
    U = np.zeros((n_p, steps, nu))
    X = np.zeros((n_p, steps + 1, nx))
    active = np.zeros((n_p, steps, nu), dtype=np.int8)
    solved = np.zeros(n_p, dtype=bool)
    iterations = np.zeros(n_p, dtype=np.int64)
    input_index = (stage * np.arange(steps)[:, None] + nx + np.arange(nu)[None, :]).ravel()
    end_index = stage * (steps - 1) + nx + nu + np.arange(nx)
    for p in range(n_p):
        rhs = np.zeros(pattern.size)
        rhs[:nx] = -Ad[p] @ x0[p]
        kkt = _KKT(pattern, (Ad[p], Bd[p], Q[p], R[p]), rhs, end_index)
        bound = u_max[p][None, :]
        edge = bound * (1 + tol)  # a free input beyond it is out of the box
        scale = max(1.0, float(np.abs(x0[p]).max()))
        a, x, AdT, BdT = active[p], X[p], Ad[p].T, Bd[p].T
        for _ in range(max_iter + 1):
            on = np.flatnonzero(a)
            z = kkt.solve(input_index[on], (a * bound).ravel()[on])
            iterations[p] += 1
            if z is None:
                break
            blocks = z.reshape(steps, stage)
            lam, u = blocks[:, :nx], blocks[:, nx:nx + nu]
            x[0], x[1:] = x0[p], blocks[:, nx + nu:]
            U[p] = u
            residual = np.abs(x[1:] - x[:-1] @ AdT - u @ BdT).max()
            if residual > 1e-6 * scale:  # x_N = 0 is out of the free inputs' reach: the system was singular
                break
            grad = u @ R[p].T + lam @ Bd[p]
            g_tol = tol * max(1.0, float(np.abs(grad).max()))
            free = a == 0
            above, below = free & (u > edge), free & (u < -edge)
            release = ((a == 1) & (grad > g_tol)) | ((a == -1) & (grad < -g_tol))
            if not (above | below | release).any():
                solved[p] = True
                break
            a[above], a[below], a[release] = 1, -1, 0  # disjoint: the first two need a free input, the last a fixed
    U = np.clip(U, -u_max[:, None, :], u_max[:, None, :])  # a free input within tol of its bound is put on it
    return BoxLQRSolution(U=U, X=X, solved=solved, iterations=iterations, active=active)
