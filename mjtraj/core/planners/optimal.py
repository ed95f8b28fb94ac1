"""Control-aware optimal planner (paper §III-IV): linearise, discretise by ZOH, solve the condensed QP."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import choice, positive, vector
from mjtraj.core.linearize import discretize_zoh, linearize, linearize_many
from mjtraj.core.lqr import box_lqr
from mjtraj.core.model import JointInfo
from mjtraj.core.planners.base import Planner, register
from mjtraj.core.qp import CondensedQP, build_qp, solve_qp
from mjtraj.core.reference import Reference
from mjtraj.core.scoring import bryson_weights
from mjtraj.core.task import Task
from mjtraj.exceptions import InfeasibleError, InvalidInputError, MjtrajError

LINEARIZATION_POINTS = ("midpoint", "start", "goal")
SOLVERS = ("auto", "osqp")


def planner_weights(task: Task, bound: NDArray[np.float64], state_weight: tuple[float, ...] | None,
                    input_weight: tuple[float, ...] | None, alpha: float, split: float
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """An optimal-type planner's (Q, R), full matrices (2n, 2n) and (n, n): the given diagonals, else Bryson's rule
    for the task with the state weight scaled by alpha and shared by split (see Optimal)."""
    q_default, r_default = bryson_weights(task, bound)
    if state_weight is None:
        n = task.n
        share = np.repeat([2.0 * split, 2.0 * (1.0 - split)], n)
        q_diag = float(alpha) * (share * q_default)
    else:
        q_diag = vector("state_weight", state_weight, 2 * task.n)
    r_diag = r_default if input_weight is None else vector("input_weight", input_weight, task.n)
    if (q_diag < 0).any() or (r_diag <= 0).any():
        raise InvalidInputError(f"state_weight, input_weight: expected Q >= 0 and R > 0, got "
                                f"{q_diag.tolist()} and {r_diag.tolist()}")
    return np.diag(q_diag), np.diag(r_diag)


def check_weight_options(planner: Any) -> None:
    """Validate alpha and split of an optimal-type planner, and that they are not given with state_weight."""
    for name, low, high in (("alpha", 0.0, np.inf), ("split", 0.0, 1.0)):
        value = getattr(planner, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
            raise InvalidInputError(f"{name}: expected a number in [{low:g}, {high:g}], got {value!r}")
    if planner.state_weight is not None and (planner.alpha != 1.0 or planner.split != 0.5):
        raise InvalidInputError("alpha, split: they scale Bryson's state weight; give them or state_weight, not both")


@register("optimal")
@dataclass(frozen=True)
class Optimal(Planner):
    """Finite-horizon, effort-aware planner of the paper, with terminal constraint x_N = 0.

    Linearises the gravity-compensated plant at (x_bar, u_bar) = ([q_bar; 0], 0) by central finite
    differences through MuJoCo, discretises by zero-order hold, and minimises
    1/2 sum_{k=1..N} x_k^T Q x_k + 1/2 sum_{k=0..N-1} u_k^T R u_k over x_k = [q_k - qg; qd_k], subject to
    x_N = 0 and |u_k| <= torque_bound (see `solver`). The reference is the linear model's predicted state;
    qdd is the ZOH acceleration per step (qd_{k+1} - qd_k) / dt, and 0 at the final sample; u_plan = U*.

    Attributes:
      linearization: 'midpoint' (q_bar = (q0+qg)/2), 'start' or 'goal'; ignored when q_bar is given.
      q_bar: a user linearisation pose, shape (n,), rad.
      state_weight: diag(Q), shape (2n,); None for Bryson's rule (`bryson_weights`) scaled by `alpha` and `split`.
      input_weight: diag(R), shape (n,); None for Bryson's rule.
      alpha: scale of Bryson's state weight, >= 0 (its weight frontier: 0 is the minimum-effort plan of the linear
        model, 1 Bryson's rule); with state_weight None only.
      split: share of the state weight on positions, in [0, 1]: Q = alpha diag(2 split Q_pos, 2 (1 - split) Q_vel)
        with Bryson's Q_pos, Q_vel (0.5: Bryson's own balance); with state_weight None only.
      torque_bound: |u_k| bound, shape (n,) or scalar, N m; None for the model's ctrlrange.
      fd_eps: finite-difference step of the linearisation.
      solver: 'auto' = the exact active-set solver on the banded KKT system (`mjtraj.core.lqr.box_lqr`: the same
        optimum, verified by its KKT conditions), OSQP where its active set does not settle; 'osqp' = OSQP always.
      osqp_settings: overrides of `mjtraj.core.qp.DEFAULT_SETTINGS`.
    """

    linearization: str = "midpoint"
    q_bar: tuple[float, ...] | None = None
    state_weight: tuple[float, ...] | None = None
    input_weight: tuple[float, ...] | None = None
    alpha: float = 1.0
    split: float = 0.5
    torque_bound: float | tuple[float, ...] | None = None
    fd_eps: float = 1e-6
    solver: str = "auto"
    osqp_settings: dict[str, Any] | None = None
    name: ClassVar[str] = "optimal"

    def __post_init__(self) -> None:
        choice("linearization", self.linearization, LINEARIZATION_POINTS)
        choice("solver", self.solver, SOLVERS)
        positive("fd_eps", self.fd_eps)
        check_weight_options(self)
        for name in ("q_bar", "torque_bound"):
            value = getattr(self, name)
            if value is None:
                continue
            array = np.asarray(value, dtype=object).ravel()
            if array.size == 0 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
                                          for v in array):
                raise InvalidInputError(f"{name}: expected finite numbers (one per joint), got {value!r}")
            if name == "torque_bound" and np.any(array.astype(float) <= 0):
                raise InvalidInputError(f"torque_bound: expected positive values, got {value!r}")

    def operating_point(self, task: Task) -> NDArray[np.float64]:
        """q_bar for `task`; shape (n,), rad."""
        if self.q_bar is not None:
            return vector("q_bar", self.q_bar, task.n)
        return {"midpoint": 0.5 * (task.q0 + task.qg), "start": task.q0, "goal": task.qg}[self.linearization]

    def weights(self, task: Task, bound: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(Q, R) as full matrices, shapes (2n, 2n) and (n, n) (`planner_weights`)."""
        return planner_weights(task, bound, self.state_weight, self.input_weight, self.alpha, self.split)

    def bounds(self, task: Task, model: mujoco.MjModel, joints: JointInfo | None = None) -> NDArray[np.float64]:
        """|u| bound per joint; shape (n,), N m (`joints`: those of `model`, when already read)."""
        if self.torque_bound is None:
            return (JointInfo.of(model) if joints is None else joints).torque_limit.copy()
        bound = vector("torque_bound", self.torque_bound, task.n)
        if np.any(bound <= 0):
            raise InvalidInputError(f"torque_bound: expected positive values, got {bound.tolist()}")
        return bound

    def build(self, task: Task, model: mujoco.MjModel) -> tuple[CondensedQP, dict[str, Any]]:
        """The QP for `task` and the facts of its construction (operating point, A_d, B_d)."""
        task.check_limits(model)
        q_bar = self.operating_point(task)
        bound = self.bounds(task, model)
        A, B = linearize(model, q_bar, eps=self.fd_eps)
        Ad, Bd = discretize_zoh(A, B, task.dt)
        Q, R = self.weights(task, bound)
        x0 = np.concatenate([task.q0 - task.qg, np.zeros(task.n)])
        qp = build_qp(Ad, Bd, x0, task.steps, Q, R, -bound, bound)
        return qp, {"q_bar": q_bar, "A_c": A, "B_c": B, "A_d": Ad, "B_d": Bd, "bound": bound}

    def plan(self, task: Task, model: mujoco.MjModel) -> Reference:
        """Plan `task` on the nominal `model` (`plan_many` of one task).

        Raises:
          InfeasibleError: x_N = 0 cannot be reached within the torque bounds in T (names the bound).
          SolverError: OSQP failed.
        """
        result = self.plan_many([task], model)[0]
        if isinstance(result, MjtrajError):
            raise result
        return result

    def plan_many(self, tasks: Sequence[Task], model: mujoco.MjModel) -> list[Reference | MjtrajError]:
        """Plan every task; the entry of a task that cannot be planned is its error (InfeasibleError,
        SolverError, InvalidInputError), so that one bad task does not stop the others.

        Tasks of one grid (N, dt) are linearised in one batched call and solved by the exact active-set solver on
        each one's banded KKT system (`mjtraj.core.lqr.box_lqr`); with solver 'osqp', or where the active set does
        not settle, OSQP solves the condensed QP.
        """
        results: list[Reference | MjtrajError | None] = [None] * len(tasks)
        prepared: dict[tuple[int, float], list[tuple[int, Task, NDArray[np.float64], NDArray[np.float64]]]] = {}
        joints = JointInfo.of(model)
        for i, task in enumerate(tasks):
            try:
                task.check_limits(model, joints)
                entry = (i, task, self.operating_point(task), self.bounds(task, model, joints))
            except MjtrajError as e:
                results[i] = e
                continue
            prepared.setdefault((task.steps, task.dt), []).append(entry)
        for (steps, dt), group in prepared.items():
            self._plan_group(group, steps, dt, model, results)
        return [r for r in results if r is not None]

    def _plan_group(self, group: list[tuple[int, Task, NDArray[np.float64], NDArray[np.float64]]], steps: int,
                    dt: float, model: mujoco.MjModel, results: list[Reference | MjtrajError | None]) -> None:
        start = time.perf_counter()
        tasks = [task for _, task, _, _ in group]
        A, B = linearize_many(model, np.array([q_bar for _, _, q_bar, _ in group]), eps=self.fd_eps)
        Ad, Bd = discretize_zoh(A, B, dt)
        bounds = np.array([bound for _, _, _, bound in group])
        weights = [self.weights(task, bound) for task, bound in zip(tasks, bounds, strict=True)]
        Q = np.array([w[0] for w in weights])
        R = np.array([w[1] for w in weights])
        x0 = np.array([np.concatenate([task.q0 - task.qg, np.zeros(task.n)]) for task in tasks])
        built = time.perf_counter()
        if self.solver == "auto":
            solution = box_lqr(Ad, Bd, Q, R, x0, steps, bounds)
            solved, U, X = solution.solved, solution.U, solution.X
        else:
            solved = np.zeros(len(group), dtype=bool)
        share = (time.perf_counter() - built) / len(group)
        for j, (i, task, q_bar, bound) in enumerate(group):
            facts = {"linearization": self.linearization if self.q_bar is None else "user", "q_bar": q_bar.tolist(),
                     "build_time": (built - start) / len(group)}
            if solved[j]:
                info = {"solver": "kkt-active-set", "status": "solved", "polished": False,
                        "iterations": int(solution.iterations[j]),
                        "active_bounds": int(np.sum(solution.active[j] != 0)), "solve_time": share}
                results[i] = self._reference(task, U[j], X[j], Q[j], R[j], bound, facts, info)
                continue
            try:
                results[i] = self._plan_osqp(task, model, Ad[j], Bd[j], Q[j], R[j], bound, facts)
            except MjtrajError as e:
                results[i] = e

    def _plan_osqp(self, task: Task, model: mujoco.MjModel, Ad: NDArray[np.float64], Bd: NDArray[np.float64],
                   Q: NDArray[np.float64], R: NDArray[np.float64], bound: NDArray[np.float64],
                   facts: dict[str, Any]) -> Reference:
        x0 = np.concatenate([task.q0 - task.qg, np.zeros(task.n)])
        qp = build_qp(Ad, Bd, x0, task.steps, Q, R, -bound, bound)
        try:
            solution = solve_qp(qp, settings=self.osqp_settings)
        except InfeasibleError as e:
            raise InfeasibleError(_infeasibility_message(qp, bound, task, model)) from e
        info = {"solver": "osqp", "status": solution.status, "polished": solution.polished,
                "iterations": solution.iterations, "solve_time": solution.solve_time}
        U = solution.U.reshape(task.steps, task.n)
        return self._reference(task, U, qp.predict(solution.U), Q, R, bound, facts, info)

    def _reference(self, task: Task, U: NDArray[np.float64], X: NDArray[np.float64], Q: NDArray[np.float64],
                   R: NDArray[np.float64], bound: NDArray[np.float64], facts: dict[str, Any],
                   info: dict[str, Any]) -> Reference:
        """The reference of the predicted states X (N+1, 2n) under U (N, n), with the solution's checks."""
        n = task.n
        qd = X[:, n:]
        qdd = np.zeros_like(qd)
        qdd[:-1] = (qd[1:] - qd[:-1]) / task.dt
        objective = 0.5 * float(np.einsum("ki,ki->", X @ Q, X) + np.einsum("ki,ki->", U @ R, U))
        info = {**info, "objective": objective, "terminal_residual": float(np.abs(X[-1]).max()),
                "bound_violation": float(max(0.0, (np.abs(U) - bound).max())), **facts}
        info["plan_time"] = info["build_time"] + info["solve_time"]
        q = X[:, :n] + task.qg
        q[0] = task.q0  # exactly where the task starts ((q0 - qg) + qg may differ from q0 in the last bit)
        return Reference(planner=self.name, t=task.times, q=q, qd=qd, qdd=qdd, u_plan=U, info=info)


def _infeasibility_message(qp: CondensedQP, bound: NDArray[np.float64], task: Task, model: mujoco.MjModel) -> str:
    """Explain an infeasible QP: the smallest bound scaling t with which x_N = 0 is reachable (an LP)."""
    from scipy.optimize import linprog

    n_u = qp.H.shape[0]
    scale = np.tile(bound, n_u // bound.size)
    # min t  s.t.  A_eq U = b_eq,  -t*scale <= U <= t*scale
    c = np.zeros(n_u + 1)
    c[-1] = 1.0
    eye = np.eye(n_u)
    A_ub = np.block([[eye, -scale[:, None]], [-eye, -scale[:, None]]])
    result = linprog(c, A_ub=A_ub, b_ub=np.zeros(2 * n_u), A_eq=np.hstack([qp.A_eq, np.zeros((qp.A_eq.shape[0], 1))]),
                     b_eq=qp.b_eq, bounds=[(None, None)] * n_u + [(0, None)], method="highs")
    names = JointInfo.of(model).names
    bounds_text = ", ".join(f"{name} +-{b:.4g} N m" for name, b in zip(names, bound, strict=True))
    head = (f"optimal: x_N = 0 cannot be reached within the torque bounds u_min/u_max ({bounds_text}) "
            f"in T = {task.duration:.4g} s")
    if not result.success:
        return head
    t = float(result.x[-1])
    U = result.x[:-1].reshape(-1, bound.size)
    joint = int(np.argmax(np.max(np.abs(U), axis=0) / bound))
    return (f"{head}: the linear model needs at least {t:.3g} times those bounds; the binding bound is "
            f"joint '{names[joint]}' (needs {t * bound[joint]:.4g} N m); lengthen the duration or raise "
            f"torque_bound")
