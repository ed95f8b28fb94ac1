"""The condensed finite-horizon QP of the paper (§IV): built by one function, solved by another (OSQP)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from numpy.typing import NDArray

from mjtraj.checks import frozen
from mjtraj.exceptions import InfeasibleError, InvalidInputError, SolverError


@dataclass(frozen=True)
class CondensedQP:
    """min_U 1/2 U^T H U + f^T U  s.t.  A_eq U = b_eq,  lb <= U <= ub  (U stacks u_0..u_{N-1}).

    With X = A_bar x0 + B_bar U the stacked predicted states x_1..x_N (paper eq. 17):
    H = B_bar^T Q_bar B_bar + R_bar, f = B_bar^T Q_bar A_bar x0 (= F x0), A_eq = B_N, b_eq = -A_N x0.
    `constant` is the U-independent part of J, 1/2 x0^T Q x0 + 1/2 (A_bar x0)^T Q_bar (A_bar x0).
    """

    H: NDArray[np.float64]
    f: NDArray[np.float64]
    A_eq: NDArray[np.float64]
    b_eq: NDArray[np.float64]
    lb: NDArray[np.float64]
    ub: NDArray[np.float64]
    A_bar: NDArray[np.float64]
    B_bar: NDArray[np.float64]
    x0: NDArray[np.float64]
    constant: float
    nu: int

    def objective(self, U: npt.ArrayLike) -> float:
        """The paper's J(x0, U), constant included."""
        U = np.asarray(U, dtype=np.float64)
        return float(0.5 * U @ self.H @ U + self.f @ U + self.constant)

    def predict(self, U: npt.ArrayLike) -> NDArray[np.float64]:
        """States x_0..x_N of the linear model under U; shape (N+1, nx)."""
        X = self.A_bar @ self.x0 + self.B_bar @ np.asarray(U, dtype=np.float64)
        return np.vstack([self.x0, X.reshape(-1, self.x0.size)])


def build_qp(Ad: npt.ArrayLike, Bd: npt.ArrayLike, x0: npt.ArrayLike, steps: int, Q: npt.ArrayLike,
             R: npt.ArrayLike, u_min: npt.ArrayLike, u_max: npt.ArrayLike) -> CondensedQP:
    """Condense x_{k+1} = Ad x_k + Bd u_k over `steps` periods into the paper's QP.

    Args:
      Ad: shape (nx, nx). Bd: shape (nx, nu). x0: initial regulation state, shape (nx,).
      Q: state weight, shape (nx, nx). R: input weight, shape (nu, nu).
      u_min, u_max: input bounds, shape (nu,), N m.
    """
    Ad = np.asarray(Ad, dtype=np.float64)
    Bd = np.asarray(Bd, dtype=np.float64)
    x0 = np.asarray(x0, dtype=np.float64)
    Q = np.asarray(Q, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    nx, nu = Bd.shape
    N = steps
    if Ad.shape != (nx, nx) or x0.shape != (nx,) or Q.shape != (nx, nx) or R.shape != (nu, nu):
        raise InvalidInputError(f"build_qp: expected Ad ({nx},{nx}), x0 ({nx},), Q ({nx},{nx}), R ({nu},{nu}); "
                                f"got {Ad.shape}, {x0.shape}, {Q.shape}, {R.shape}")
    powers = [np.eye(nx)]
    for _ in range(N):
        powers.append(Ad @ powers[-1])
    A_bar = np.vstack(powers[1:])                                   # rows: A^1 .. A^N
    AkB = np.stack([p @ Bd for p in powers[:N]])                    # A^k B, k = 0..N-1
    i, j = np.tril_indices(N)                                       # block (i, j) = A^(i-j) B for j <= i
    B_bar4 = np.zeros((N, N, nx, nu))
    B_bar4[i, j] = AkB[i - j]
    B_bar = B_bar4.transpose(0, 2, 1, 3).reshape(N * nx, N * nu)
    QB = np.einsum("ab,kbc->kac", Q, B_bar.reshape(N, nx, N * nu)).reshape(N * nx, N * nu)
    H = B_bar.T @ QB + np.kron(np.eye(N), R)
    H = 0.5 * (H + H.T)
    free = A_bar @ x0
    f = QB.T @ free
    constant = 0.5 * float(x0 @ Q @ x0) + 0.5 * float(free @ np.kron(np.eye(N), Q) @ free)
    lb = np.tile(np.asarray(u_min, dtype=np.float64), N)
    ub = np.tile(np.asarray(u_max, dtype=np.float64), N)
    return CondensedQP(H=frozen(H), f=frozen(f), A_eq=frozen(B_bar[-nx:].copy()), b_eq=frozen(-powers[N] @ x0),
                       lb=frozen(lb), ub=frozen(ub), A_bar=frozen(A_bar), B_bar=frozen(B_bar), x0=frozen(x0.copy()),
                       constant=constant, nu=nu)


@dataclass(frozen=True)
class QPSolution:
    """An OSQP answer with what is needed to trust it (qpsolvers' Solution is the model)."""

    U: NDArray[np.float64]
    status: str
    polished: bool
    iterations: int
    solve_time: float
    """Wall time of setup + solve, s."""
    objective: float
    equality_residual: float
    """max |A_eq U - b_eq|."""
    bound_violation: float
    """max(lb - U, U - ub, 0)."""
    extra: dict[str, Any] = field(default_factory=dict)

    def is_optimal(self, tol: float = 1e-8) -> bool:
        """Solved, and the constraints hold to `tol`."""
        return self.status == "solved" and self.equality_residual <= tol and self.bound_violation <= tol


DEFAULT_SETTINGS: dict[str, Any] = {
    "eps_abs": 1e-9, "eps_rel": 1e-9, "max_iter": 200_000, "polishing": True, "polish_refine_iter": 10,
    "verbose": False,
}


def solve_qp(qp: CondensedQP, *, settings: dict[str, Any] | None = None) -> QPSolution:
    """Solve `qp` with OSQP (tight tolerances, polishing) and check the answer.

    Raises:
      InfeasibleError: OSQP reports the problem primal infeasible.
      SolverError: any other status than solved, or a solution violating the constraints by > 1e-6.
    """
    import osqp

    options = {**DEFAULT_SETTINGS, **(settings or {})}
    n_u = qp.H.shape[0]
    n_eq = qp.A_eq.shape[0]
    A = sp.vstack([sp.csc_matrix(qp.A_eq), sp.identity(n_u, format="csc")], format="csc")
    lower = np.concatenate([qp.b_eq, qp.lb])
    upper = np.concatenate([qp.b_eq, qp.ub])
    start = time.perf_counter()
    solver = osqp.OSQP()
    try:
        solver.setup(sp.triu(sp.csc_matrix(qp.H), format="csc"), qp.f.copy(), A, lower, upper, **options)
        result = solver.solve(raise_error=False)
    except (ValueError, RuntimeError, osqp.OSQPException) as e:
        raise SolverError(f"OSQP failed during setup or solve: {e!r}") from e
    elapsed = time.perf_counter() - start
    status = str(result.info.status)
    if "infeasible" in status and "dual" not in status:
        raise InfeasibleError(f"QP is infeasible (OSQP status {status!r})")
    if status != "solved":
        raise SolverError(f"OSQP did not solve the QP: status {status!r} after {result.info.iter} iterations")
    U = np.array(result.x, dtype=np.float64)
    eq_res = float(np.max(np.abs(qp.A_eq @ U - qp.b_eq))) if n_eq else 0.0
    bound = float(max(0.0, np.max(qp.lb - U), np.max(U - qp.ub)))
    solution = QPSolution(U=frozen(U), status=status, polished=int(result.info.status_polish) == 1,
                          iterations=int(result.info.iter), solve_time=elapsed, objective=qp.objective(U),
                          equality_residual=eq_res, bound_violation=bound)
    if eq_res > 1e-6 or bound > 1e-6:
        raise SolverError(f"OSQP returned status 'solved' but the solution violates the constraints: "
                          f"equality residual {eq_res:.3g}, bound violation {bound:.3g}")
    return solution
