"""Control-aware optimal planner (paper §III-IV): linearise, discretise by ZOH, solve the condensed QP."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj._validate import choice, positive, vector
from mjtraj.exceptions import InfeasibleError, InvalidInputError
from mjtraj.linearize import discretize_zoh, linearize
from mjtraj.model import JointInfo
from mjtraj.planners.base import register
from mjtraj.qp import CondensedQP, build_qp, solve_qp
from mjtraj.reference import Reference
from mjtraj.task import Task

LINEARIZATION_POINTS = ("midpoint", "start", "goal")
JOINT_SPEED_LIMIT = np.pi
"""UR5 joint speed limit, rad/s (180 deg/s on every joint; shared/ur5_params.md)."""


def bryson_weights(task: Task, torque_bound: NDArray[np.float64]
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Bryson's rule: each weight is 1 / (largest acceptable value)^2 of its variable.

    Scales: position deviation max_i |dq_i| (the move itself; 1 rad if there is no move), velocity the
    joint speed limit pi rad/s, torque the corrective saturation. Returns diag(Q), shape (2n,), and
    diag(R), shape (n,).
    """
    move = float(np.max(np.abs(task.displacement))) or 1.0
    n = task.n
    q_diag = np.concatenate([np.full(n, 1.0 / move**2), np.full(n, 1.0 / JOINT_SPEED_LIMIT**2)])
    return q_diag, 1.0 / np.asarray(torque_bound, dtype=np.float64) ** 2


@register("optimal")
@dataclass(frozen=True)
class Optimal:
    """Finite-horizon, effort-aware planner of the paper, with terminal constraint x_N = 0.

    Linearises the gravity-compensated plant at (x_bar, u_bar) = ([q_bar; 0], 0) by central finite
    differences through MuJoCo, discretises by zero-order hold, and minimises
    1/2 sum_{k=1..N} x_k^T Q x_k + 1/2 sum_{k=0..N-1} u_k^T R u_k over x_k = [q_k - qg; qd_k], subject to
    x_N = 0 and |u_k| <= torque_bound, with OSQP. The reference is the linear model's predicted state;
    qdd is the ZOH acceleration per step (qd_{k+1} - qd_k) / dt, and 0 at the final sample; u_plan = U*.

    Attributes:
      linearization: 'midpoint' (q_bar = (q0+qg)/2), 'start' or 'goal'; ignored when q_bar is given.
      q_bar: a user linearisation pose, shape (n,), rad.
      state_weight: diag(Q), shape (2n,); None for Bryson's rule (`bryson_weights`).
      input_weight: diag(R), shape (n,); None for Bryson's rule.
      torque_bound: |u_k| bound, shape (n,) or scalar, N m; None for the model's ctrlrange.
      fd_eps: finite-difference step of the linearisation.
      osqp_settings: overrides of `mjtraj.qp.DEFAULT_SETTINGS`.
    """

    linearization: str = "midpoint"
    q_bar: tuple[float, ...] | None = None
    state_weight: tuple[float, ...] | None = None
    input_weight: tuple[float, ...] | None = None
    torque_bound: float | tuple[float, ...] | None = None
    fd_eps: float = 1e-6
    osqp_settings: dict[str, Any] | None = None
    name: ClassVar[str] = "optimal"

    def __post_init__(self) -> None:
        choice("linearization", self.linearization, LINEARIZATION_POINTS)
        positive("fd_eps", self.fd_eps)

    def operating_point(self, task: Task) -> NDArray[np.float64]:
        """q_bar for `task`; shape (n,), rad."""
        if self.q_bar is not None:
            return vector("q_bar", self.q_bar, task.n)
        return {"midpoint": 0.5 * (task.q0 + task.qg), "start": task.q0, "goal": task.qg}[self.linearization]

    def weights(self, task: Task, bound: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(Q, R) as full matrices, shapes (2n, 2n) and (n, n)."""
        q_default, r_default = bryson_weights(task, bound)
        q_diag = q_default if self.state_weight is None else vector("state_weight", self.state_weight, 2 * task.n)
        r_diag = r_default if self.input_weight is None else vector("input_weight", self.input_weight, task.n)
        if np.any(q_diag < 0) or np.any(r_diag <= 0):
            raise InvalidInputError(f"state_weight, input_weight: expected Q >= 0 and R > 0, got "
                                    f"{q_diag.tolist()} and {r_diag.tolist()}")
        return np.diag(q_diag), np.diag(r_diag)

    def bounds(self, task: Task, model: mujoco.MjModel) -> NDArray[np.float64]:
        """|u| bound per joint; shape (n,), N m."""
        if self.torque_bound is None:
            return JointInfo.of(model).torque_limit.copy()
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
        """Plan `task` on the nominal `model`.

        Raises:
          InfeasibleError: x_N = 0 cannot be reached within the torque bounds in T (names the bound).
          SolverError: OSQP failed.
        """
        start = time.perf_counter()
        qp, facts = self.build(task, model)
        built = time.perf_counter()
        try:
            solution = solve_qp(qp, settings=self.osqp_settings)
        except InfeasibleError as e:
            raise InfeasibleError(_infeasibility_message(qp, facts["bound"], task, model)) from e
        X = qp.predict(solution.U)
        n = task.n
        q = X[:, :n] + task.qg
        qd = X[:, n:]
        qdd = np.zeros_like(qd)
        qdd[:-1] = np.diff(qd, axis=0) / task.dt
        info = {"status": solution.status, "polished": solution.polished, "iterations": solution.iterations,
                "objective": solution.objective, "terminal_residual": float(np.max(np.abs(X[-1]))),
                "equality_residual": solution.equality_residual, "bound_violation": solution.bound_violation,
                "solve_time": solution.solve_time, "build_time": built - start,
                "plan_time": time.perf_counter() - start, "linearization": self.linearization
                if self.q_bar is None else "user", "q_bar": facts["q_bar"].tolist()}
        return Reference(planner=self.name, t=task.times, q=q, qd=qd, qdd=qdd,
                         u_plan=solution.U.reshape(task.steps, n), info=info)


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
    bounds_text = ", ".join(f"{name} +-{b:.4g} N m" for name, b in zip(names, bound))
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
