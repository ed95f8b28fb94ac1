"""Protocol v2's floor cross-checked against an established optimal-control solver: the same problem (J_settle's
weights over the motion and the settle window, the torque box, the at-rest rule at the window's end, on the same
MuJoCo step) posed in CasADi by multiple shooting and solved by IPOPT from a neutral start (the reference as the
states, zero corrective torque), with the step's Jacobians by central differences of MuJoCo's own step: nothing of
the floor's solver (its tree Jacobians, its Gauss-Newton SQP, its starts from the laws' executions) is shared."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjtraj.core.floor import DEFAULT_SETTINGS
from mjtraj.core.model import JointInfo
from mjtraj.core.settle import SETTLE_SPEED, Settle, held
from mjtraj.domain.families import draw_scenario
from mjtraj.domain.floor import floor_of
from mjtraj.domain.pipeline import Job

WINDOW = 25
"""The settle window in periods (0.5 s at 0.02 s)."""
AGREE = 1e-5
"""The two solvers' optima agree to this relative difference: each stops at its own tolerance (the floor's STALL,
1e-6 of the cost; IPOPT's tol 1e-5 on its scaled optimality error, its objective scaled to about 1), on the same
local problem. Measured: 3e-8 (nominal 1) and 1.9e-7 (aggressive 3), IPOPT above the floor in both."""


def _ipopt_floor(model: mujoco.MjModel, job: Job, limit: np.ndarray, scale: float) -> float:
    """J_settle of IPOPT's solution of `job`'s floor problem (the at-rest rule aimed at as the floor aims at it)."""
    import casadi as ca

    n, T = model.nv, job.reference.steps
    data = mujoco.MjData(model)

    def step(x: np.ndarray, u: np.ndarray) -> np.ndarray:
        data.qpos[:], data.qvel[:], data.ctrl[:] = x[:n], x[n:], u
        data.qacc_warmstart[:] = 0.0
        mujoco.mj_step(model, data)
        return np.concatenate([data.qpos, data.qvel])

    def jacobian(x: np.ndarray, u: np.ndarray, eps: float = 1e-6) -> np.ndarray:
        z, out = np.concatenate([x, u]), np.empty((2 * n, 3 * n))
        for i in range(3 * n):
            hi, lo = z.copy(), z.copy()
            hi[i] += eps
            lo[i] -= eps
            out[:, i] = (step(hi[:2 * n], hi[2 * n:]) - step(lo[:2 * n], lo[2 * n:])) / (2 * eps)
        return out

    class Jacobian(ca.Callback):  # type: ignore[misc]
        def __init__(self, name: str, opts: dict) -> None:
            ca.Callback.__init__(self)
            self.construct(name, opts)

        def get_n_in(self) -> int:
            return 3

        def get_n_out(self) -> int:
            return 2

        def get_sparsity_in(self, i: int) -> ca.Sparsity:
            return ca.Sparsity.dense((2 * n, n, 2 * n)[i], 1)

        def get_sparsity_out(self, i: int) -> ca.Sparsity:
            return ca.Sparsity.dense(2 * n, (2 * n, n)[i])

        def eval(self, arg: list) -> list:
            J = jacobian(np.asarray(arg[0]).ravel(), np.asarray(arg[1]).ravel())
            return [J[:, :2 * n], J[:, 2 * n:]]

    class Step(ca.Callback):  # type: ignore[misc]
        def __init__(self, name: str) -> None:
            ca.Callback.__init__(self)
            self.construct(name, {})

        def get_n_in(self) -> int:
            return 2

        def get_n_out(self) -> int:
            return 1

        def get_sparsity_in(self, i: int) -> ca.Sparsity:
            return ca.Sparsity.dense((2 * n, n)[i], 1)

        def get_sparsity_out(self, i: int) -> ca.Sparsity:
            return ca.Sparsity.dense(2 * n, 1)

        def eval(self, arg: list) -> list:
            return [step(np.asarray(arg[0]).ravel(), np.asarray(arg[1]).ravel())]

        def has_jacobian(self) -> bool:
            return True

        def get_jacobian(self, name: str, inames: list, onames: list, opts: dict) -> ca.Callback:
            self._jacobian = Jacobian(name, opts)
            return self._jacobian

    F = Step("mujoco_step")
    q_diag, r_diag = job.weights
    x_ref = np.concatenate([job.reference.q, job.reference.qd], axis=1).T
    opti = ca.Opti()
    X, U = opti.variable(2 * n, T + 1), opti.variable(n, T)
    opti.subject_to(X[:, 0] == x_ref[:, 0])
    cost = 0
    for k in range(T):
        opti.subject_to(X[:, k + 1] == F(X[:, k], U[:, k]))
        d = X[:, k] - x_ref[:, k]
        cost += ca.dot(q_diag * d, d) + ca.dot(r_diag * U[:, k], U[:, k])
    opti.minimize(cost)
    box = np.tile(limit[:, None], (1, T))
    opti.subject_to(opti.bounded(-box, U, box))
    settle = job.settle
    assert settle is not None
    band, speed = DEFAULT_SETTINGS.goal_margin * settle.band, DEFAULT_SETTINGS.goal_margin * SETTLE_SPEED
    opti.subject_to(opti.bounded(settle.goal - band, X[:n, T], settle.goal + band))
    opti.subject_to(opti.bounded(-speed, X[n:, T], speed))
    opti.set_initial(X, x_ref)
    opti.set_initial(U, 0.0)
    opti.solver("ipopt", {"print_time": False},
                {"hessian_approximation": "limited-memory", "tol": 1e-5, "acceptable_tol": 1e-5,
                 "acceptable_iter": 5, "max_iter": 2000, "print_level": 0, "obj_scaling_factor": 1.0 / scale})
    solution = opti.solve()
    assert solution.stats()["return_status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    return float(solution.value(cost))


@pytest.mark.slow
@pytest.mark.parametrize("family, index", [("nominal", 1), ("aggressive", 3)])
def test_protocol_v2s_floor_is_ipopts_optimum_of_the_same_problem(family, index, scenario, model):
    fs = draw_scenario(family, 1, index, model, scenario.task.dt)
    motion = scenario.planner("cubic").plan(fs.task, model)
    job = Job(held(motion, WINDOW, fs.task.qg), scenario.scoring.weights(fs.task, JointInfo.of(model).torque_limit),
              settle=Settle.of(fs.task, motion.steps, WINDOW))
    floor = floor_of(model, scenario.loop, job)
    # IPOPT's objective scaled by the best control law's score of the episode (its size, known before either solve)
    scale = min(cost for cost in floor.controllers.values() if np.isfinite(cost))
    ipopt = _ipopt_floor(model, job, JointInfo.of(model).torque_limit, scale)
    assert ipopt == pytest.approx(floor.cost, rel=AGREE)
