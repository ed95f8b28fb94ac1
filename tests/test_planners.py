"""Planner contract over the registry, golden values, and the optimal planner against independent oracles."""

from __future__ import annotations

import numpy as np
import pytest
from oracles import WEIGHTS, kkt_solve, unit_task

from mjtraj.core.planners import default_names, make
from mjtraj.core.task import Task
from mjtraj.exceptions import InfeasibleError, InvalidInputError


@pytest.mark.parametrize("name", default_names())
def test_contract(name, model, task):
    ref = make(name).plan(task, model)
    assert ref.planner == name
    assert ref.q.shape == ref.qd.shape == ref.qdd.shape == (task.steps + 1, task.n)
    np.testing.assert_allclose(ref.t, np.arange(task.steps + 1) * task.dt, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(ref.q[0], task.q0)
    tol = 1e-8 if name == "optimal" else 1e-12
    np.testing.assert_allclose(ref.q[-1], task.qg, atol=tol)
    np.testing.assert_allclose(ref.qd[0], 0.0, atol=tol)
    np.testing.assert_allclose(ref.qd[-1], 0.0, atol=tol)
    for a in (ref.q, ref.qd, ref.qdd):
        assert np.all(np.isfinite(a)) and not a.flags.writeable
    again = make(name).plan(task, model)
    np.testing.assert_array_equal(again.q, ref.q)  # deterministic, bit for bit


@pytest.mark.parametrize("name", ["cubic", "quintic", "trapezoidal"])
def test_kinematic_velocity_and_acceleration_are_derivatives(name, model, task):
    ref = make(name).plan(task, model)
    dt = task.dt
    # central differences of the samples (trapezoid: away from its acceleration jumps)
    qd_fd = (ref.q[2:] - ref.q[:-2]) / (2 * dt)
    np.testing.assert_allclose(qd_fd, ref.qd[1:-1], atol=2e-3 if name != "trapezoidal" else 1e-2)


def test_golden_unit_move(model):
    q0 = np.zeros(3) + np.array([0.0, -1.5, 0.0])
    task = Task.create(q0, q0 + 1.0, 2.0, 0.02, model=model)
    k = 25  # t = 0.5 s
    assert make("cubic").plan(task, model).q[k, 0] - q0[0] == pytest.approx(0.15625, abs=1e-15)
    assert make("quintic").plan(task, model).q[k, 0] - q0[0] == pytest.approx(0.103515625, abs=1e-15)
    trap = make("trapezoidal").plan(task, model)
    assert trap.q[k, 0] - q0[0] == pytest.approx(0.140625, abs=1e-15)
    assert np.max(np.abs(trap.qdd)) == pytest.approx(1.125, abs=1e-15)
    assert trap.info["blend_time"] == pytest.approx(2.0 / 3.0, abs=1e-15)


@pytest.mark.parametrize("factor", [1.0, 2.5, float("nan")])
def test_trapezoid_factor_out_of_range(factor):
    with pytest.raises(InvalidInputError, match=r"^cruise_factor: expected a value in \(1, 2\] \(cruise velocity "
                       r"V = cruise_factor\*\|dq\|/T must lie in \(\|dq\|/T, 2\|dq\|/T\]\), got "):
        make("trapezoidal", cruise_factor=factor)


def test_trapezoid_zero_move_is_constant(model):
    task = Task.create([0.1, -1.0, 0.2], [0.1, -1.0, 0.2], 1.0, 0.02, model=model)
    ref = make("trapezoidal").plan(task, model)
    np.testing.assert_array_equal(ref.q, np.tile(task.q0, (task.steps + 1, 1)))


def test_unknown_planner_and_option():
    with pytest.raises(InvalidInputError, match=r"^planner: unknown planner 'spline'; valid: cubic, optimal, "
                                                r"nonlinear_optimal, nonlinear_min_effort, quintic, scurve, "
                                                r"trapezoidal$"):
        make("spline")
    with pytest.raises(InvalidInputError, match=r"^planner 'cubic': unknown option 'order'; valid: \(none\)$"):
        make("cubic", order=3)
    with pytest.raises(InvalidInputError, match=r"^linearization: unknown value 'end'; valid: midpoint, start, goal$"):
        make("optimal", linearization="end")


def test_optimal_with_tight_bounds(model):
    task = unit_task(model)
    loose = make("optimal", torque_bound=1e4, **WEIGHTS)
    bound = 0.7 * np.max(np.abs(loose.plan(task, model).u_plan))
    tight = make("optimal", torque_bound=bound, **WEIGHTS)
    qp_tight, _ = tight.build(task, model)
    ref = tight.plan(task, model)
    assert np.max(np.abs(ref.u_plan)) <= bound + 1e-8
    assert np.max(np.abs(ref.u_plan)) >= bound - 1e-6          # the bound is active
    unconstrained = qp_tight.objective(kkt_solve(qp_tight))
    assert ref.info["objective"] >= unconstrained - 1e-9
    assert ref.info["objective"] > loose.plan(task, model).info["objective"] - 1e-9
    assert ref.info["terminal_residual"] <= 1e-8


def test_optimal_solution_satisfies_kkt_conditions(model, task):
    """Independent optimality check with bounds active: projected gradient stationarity on the free set."""
    planner = make("optimal")
    qp, _ = planner.build(task, model)
    U = planner.plan(task, model).u_plan.ravel()
    grad = qp.H @ U + qp.f
    free = (U > qp.lb + 1e-7) & (U < qp.ub - 1e-7)
    # grad = -A_eq^T nu - mu with mu = 0 on free components: solve for nu there, then check the rest
    nu = np.linalg.lstsq(-qp.A_eq.T[free], grad[free], rcond=None)[0]
    residual = grad + qp.A_eq.T @ nu
    assert np.max(np.abs(residual[free])) < 1e-6 * max(1.0, np.max(np.abs(grad)))
    at_upper, at_lower = U >= qp.ub - 1e-7, U <= qp.lb + 1e-7
    assert np.all(residual[at_upper] <= 1e-6) and np.all(residual[at_lower] >= -1e-6)


@pytest.mark.parametrize("point", ["start", "goal", "midpoint"])
def test_linearization_points(model, task, point):
    planner = make("optimal", linearization=point)
    expected = {"start": task.q0, "goal": task.qg, "midpoint": (task.q0 + task.qg) / 2}[point]
    np.testing.assert_array_equal(planner.operating_point(task), expected)


def test_optimal_infeasible_names_the_bound(model):
    q0 = np.array([0.0, -1.5, 0.5])
    task = Task.create(q0, q0 + 1.0, 0.1, 0.02, model=model)
    with pytest.raises(InfeasibleError) as info:
        make("optimal").plan(task, model)
    message = str(info.value)
    assert message.startswith("optimal: x_N = 0 cannot be reached within the torque bounds u_min/u_max "
                              "(shoulder_pan_joint +-60 N m, shoulder_lift_joint +-60 N m, elbow_joint +-60 N m) "
                              "in T = 0.1 s: the linear model needs at least ")
    assert "the binding bound is joint '" in message and message.endswith("lengthen the duration or raise torque_bound")


def test_alpha_and_split_scale_brysons_state_weight(model, task):
    """Q = alpha diag(2 split Q_pos, 2 (1 - split) Q_vel); alpha 1 and split 0.5 are Bryson's rule itself."""
    from mjtraj.core.planners.optimal import planner_weights
    from mjtraj.core.scoring import bryson_weights

    bound = np.full(3, 60.0)
    q_pos_vel, _ = bryson_weights(task, bound)
    Q, R = planner_weights(task, bound, None, None, 0.3, 0.8)
    np.testing.assert_allclose(np.diag(Q), 0.3 * np.concatenate([1.6 * q_pos_vel[:3], 0.4 * q_pos_vel[3:]]),
                               rtol=1e-15)
    np.testing.assert_array_equal(np.diag(planner_weights(task, bound, None, None, 1.0, 0.5)[0]), q_pos_vel)
    with pytest.raises(InvalidInputError, match=r"^alpha: expected a number in \[0, inf\], got -1$"):
        make("optimal", alpha=-1)
    with pytest.raises(InvalidInputError, match=r"^split: expected a number in \[0, 1\], got 2$"):
        make("optimal", split=2)
    with pytest.raises(InvalidInputError, match=r"^alpha, split: they scale Bryson's state weight; give them or "
                                                r"state_weight, not both$"):
        make("optimal", alpha=0.5, state_weight=(1.0,) * 6)


def test_bad_options_fail_at_construction_and_never_spoil_other_tasks(model, task):
    with pytest.raises(InvalidInputError, match=r"^torque_bound: expected positive values, got -1$"):
        make("optimal", torque_bound=-1)
    with pytest.raises(InvalidInputError, match=r"^q_bar: expected finite numbers \(one per joint\), got \(\)$"):
        make("optimal", q_bar=())
    wrong = make("optimal", q_bar=(0.0, 0.0))  # two values for three joints: a per-task error
    results = wrong.plan_many([task, task], model)
    assert [str(r) for r in results] == ["q_bar: expected 3 values, got shape (2,)"] * 2
