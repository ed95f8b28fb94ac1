"""The plan policy's tracker (mjtraj.rl.plan_tracker) against oracles: the finite-horizon LQ problem solved as one
least-squares problem over the whole control sequence, scipy's discrete algebraic Riccati equation, finite
differences of the taper."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.linalg

from mjtraj.core import ComputedTorque
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.plan_tracker import Tracker, lqr_gains, taper, tapered

DT = 0.02


def _double_integrator() -> tuple[np.ndarray, np.ndarray]:
    return np.array([[1.0, DT], [0.0, 1.0]]), np.array([[DT * DT / 2.0], [DT]])


def _stage_scales(motion, window, boost, end_boost=None, end_periods=0):
    """Each period's stage weight over the motion's, as the module docstring states it: 1 in the motion, `boost` in
    the window, `end_boost` over its last `end_periods`."""
    return [end_boost if k >= motion + window - end_periods else boost if k >= motion else 1.0
            for k in range(motion + window)]


def _batch_optimal_controls(x0, qp, qv, r, scales, terminal, position_scales=None):
    """The controls u_0..u_{K-1} minimising sum_k scales[k] x_k^T diag(position_scales[k] qp, qv) x_k + r u_k^2 +
    x_K^T (terminal Q) x_K from x0 for x' = A x + B u, as one linear least-squares problem over the stacked controls
    (no Riccati recursion)."""
    position_scales = [1.0] * len(scales) if position_scales is None else position_scales
    A, B = _double_integrator()
    steps = len(scales)
    Phi = np.zeros((2 * (steps + 1), 2))
    Gamma = np.zeros((2 * (steps + 1), steps))
    for k in range(steps + 1):
        Phi[2 * k:2 * k + 2] = np.linalg.matrix_power(A, k)
        for j in range(k):
            Gamma[2 * k:2 * k + 2, j] = (np.linalg.matrix_power(A, k - 1 - j) @ B)[:, 0]
    weights = []
    for k in range(steps + 1):
        scale = terminal if k == steps else scales[k]
        weights += [scale * (1.0 if k == steps else position_scales[k]) * qp, scale * qv]
    W = np.diag(weights)
    H = Gamma.T @ W @ Gamma + r * np.eye(steps)
    return np.linalg.solve(H, -Gamma.T @ W @ Phi @ x0)


def test_the_lqr_gains_give_the_controls_of_the_whole_horizons_least_squares_solution():
    """From any start, the closed loop u_k = -(kp_k e_k + kd_k ed_k) (e = q - q_p here) under lqr_gains plays the
    controls that minimise the finite-horizon cost, found without a Riccati recursion (to 1e-7 relative)."""
    A, B = _double_integrator()
    qp, qv, r = np.array([40.0, 3.0]), np.array([2.0, 0.5]), np.array([0.02, 0.3])
    scales = _stage_scales(20, 8, 3.0, 30.0, 3)
    kp, kd = lqr_gains(qp, qv, r, DT, np.array(scales), 1000.0)
    assert kp.shape == kd.shape == (29, 2)
    for j, x0 in ((0, np.array([0.1, -0.3])), (1, np.array([-0.02, 0.5]))):
        _assert_plays_the_best_controls(kp[:, j], kd[:, j], _batch_optimal_controls(x0, qp[j], qv[j], r[j], scales,
                                                                                     1000.0), x0)


def _assert_plays_the_best_controls(kp, kd, best, x0):
    """The loop u_k = -(kp_k e_k + kd_k ed_k) from x0 plays `best` (to 1e-7 relative)."""
    A, B = _double_integrator()
    x, played = x0.copy(), []
    for k in range(len(best)):
        u = -(kp[k] * x[0] + kd[k] * x[1])
        played.append(u)
        x = A @ x + B[:, 0] * u
    np.testing.assert_allclose(played, best, rtol=1e-7, atol=1e-9 * np.abs(best).max())


def test_far_from_the_end_the_lqr_gains_are_the_infinite_horizons():
    """Long before the end the recursion's gains equal those of scipy's discrete algebraic Riccati solution for the
    motion's weights (to 1e-9 relative)."""
    A, B = _double_integrator()
    qp, qv, r = np.array([55.0, 12.0, 3.0]), np.array([4.0, 1.0, 0.2]), np.array([0.05, 0.01, 0.002])
    kp, kd = lqr_gains(qp, qv, r, DT, np.array(_stage_scales(400, 25, 3.0, 30.0, 8)), 1000.0)
    for j in range(3):
        P = scipy.linalg.solve_discrete_are(A, B, np.diag([qp[j], qv[j]]), np.array([[r[j]]]))
        K = np.linalg.solve(B.T @ P @ B + r[j], B.T @ P @ A)[0]
        np.testing.assert_allclose([kp[0, j], kd[0, j]], K, rtol=1e-9)


def test_the_computed_torque_rule_keeps_ct_rules_gains_at_every_sample():
    law = ComputedTorque.for_period(DT, 3)
    weights = (np.ones(6), np.ones(3))
    kp, kd = Tracker.of_rule("computed_torque").gains(weights, np.eye(3), 10, 5, DT)
    assert kp.shape == (16, 3)
    np.testing.assert_array_equal(kp, np.tile(law.kp, (16, 1)))
    np.testing.assert_array_equal(kd, np.tile(law.kd, (16, 1)))
    assert not Tracker.of_rule("computed_torque").taper and Tracker.of_rule("lqr") == Tracker()


def test_the_lqr_rule_weighs_an_acceleration_by_the_torque_it_costs_and_each_period_by_its_part():
    """Tracker.gains play, for joint j, the controls that minimise the episode's cost with control weight
    R_j M_jj^2 and the stage weights of the module docstring (motion, window, the window's end with its position
    weight, terminal)."""
    Q, R = np.array([30.0, 20.0, 10.0, 3.0, 2.0, 1.0]), np.array([0.01, 0.02, 0.03])
    mass = np.array([[2.0, 0.3, 0.1], [0.3, 1.5, 0.2], [0.1, 0.2, 0.5]])
    tracker = Tracker(window_boost=3.0, end_boost=30.0, end_periods=4, end_position=7.0, terminal=100.0)
    kp, kd = tracker.gains((Q, R), mass, 12, 10, DT)
    assert kp.shape == kd.shape == (23, 3)
    scales = _stage_scales(12, 10, 3.0, 30.0, 4)
    position = _stage_scales(12, 10, 1.0, 7.0, 4)  # 1 but over the end segment
    for j in range(3):
        x0 = np.array([0.05 * (j + 1), -0.2])
        best = _batch_optimal_controls(x0, Q[j], Q[3 + j], R[j] * mass[j, j] ** 2, scales, 100.0, position)
        _assert_plays_the_best_controls(kp[:, j], kd[:, j], best, x0)
    without = Tracker(window_boost=3.0, end_periods=0, terminal=100.0).gains((Q, R), mass, 12, 10, DT)
    assert not np.allclose(without[0], kp)  # the end segment moves the gains
    alike = dataclasses.replace(tracker, end_position=1.0).gains((Q, R), mass, 12, 10, DT)
    assert not np.allclose(alike[0], kp)  # and so does its position weight


def test_the_taper_falls_from_one_to_zero_smoothly_with_its_derivatives():
    """g = 1 before the start and 0 after the end; g' and g'' match central differences of g and g' (step 1e-7 s;
    first order at the two joins, where g'' has a kink) to 1e-6 of their scale, and vanish at both ends (C2)."""
    t, h = np.linspace(0.0, 2.0, 2001), 1e-7
    g, g1, g2 = taper(t, 1.0, 1.5)
    (above, above1, _), (below, below1, _) = taper(t + h, 1.0, 1.5), taper(t - h, 1.0, 1.5)
    assert np.all(g[t <= 1.0] == 1.0) and np.all(g[t >= 1.5] == 0.0)
    np.testing.assert_allclose(g1, (above - below) / (2 * h), rtol=0, atol=1e-6 * np.abs(g1).max())
    np.testing.assert_allclose(g2, (above1 - below1) / (2 * h), rtol=0, atol=1e-6 * np.abs(g2).max())
    assert g1[t == 1.0] == 0.0 and g1[t == 1.5] == 0.0 and g2[t == 1.0] == 0.0 and g2[t == 1.5] == 0.0


def _sine_motion(t: np.ndarray) -> np.ndarray:
    """(K, 6): a two-joint motion's position sin(w t), velocity and acceleration in closed form."""
    w = np.array([3.0, 5.0])
    return np.concatenate([np.sin(np.outer(t, w)), w * np.cos(np.outer(t, w)), -w * w * np.sin(np.outer(t, w))],
                          axis=1)


def test_tapered_offsets_of_a_motion_are_a_motion_ending_at_rest():
    """Offsets that are a motion's position, velocity and acceleration stay one after tapering (central
    differences, step 1e-7 s, of the tapered position and velocity give the tapered velocity and acceleration to
    1e-6 of their scale), equal the offsets before the start, and end at zero with zero rates."""
    t, h = np.linspace(0.0, 1.0, 1001), 1e-7
    out = tapered(_sine_motion(t), t, 0.4, 0.9)
    above, below = tapered(_sine_motion(t + h), t + h, 0.4, 0.9), tapered(_sine_motion(t - h), t - h, 0.4, 0.9)
    np.testing.assert_allclose(out[:, 2:4], (above[:, :2] - below[:, :2]) / (2 * h), rtol=0, atol=1e-6 * 5)
    np.testing.assert_allclose(out[:, 4:], (above[:, 2:4] - below[:, 2:4]) / (2 * h), rtol=0,
                               atol=1e-6 * np.abs(out[:, 4:]).max())
    np.testing.assert_array_equal(out[t <= 0.4], _sine_motion(t)[t <= 0.4])
    assert np.all(out[t >= 0.9] == 0.0)


def test_a_tracker_refuses_bad_settings_by_name():
    """Each bad field is refused with one message naming it, what was expected and what arrived."""
    import re

    for kwargs, message in (
            ({"rule": "pid"}, "tracker: unknown value 'pid'; valid: lqr, computed_torque"),
            ({"window_boost": 0.0}, "window_boost: expected a positive number, got 0.0"),
            ({"terminal": -1.0}, "terminal: expected a positive number, got -1.0"),
            ({"anchor": "kalman"}, "anchor: unknown value 'kalman'; valid: nominal, mpc_filter"),
            ({"anchor_gain": 1.5}, "anchor_gain: expected a number in (0, 1], got 1.5"),
            ({"end_boost": 0.0}, "end_boost: expected a positive number, got 0.0"),
            ({"end_position": -2.0}, "end_position: expected a positive number, got -2.0"),
            ({"end_periods": -1}, "end_periods: expected a whole number >= 0, got -1"),
            ({"end_periods": 2.5}, "end_periods: expected a whole number >= 0, got 2.5")):
        with pytest.raises(InvalidInputError, match=f"^{re.escape(message)}$"):
            Tracker(**kwargs)
    with pytest.raises(InvalidInputError,
                       match=r"^end_periods: expected at most the settle window's 5 periods, got 8$"):
        Tracker(end_periods=8).gains((np.ones(6), np.ones(3)), np.eye(3), 10, 5, DT)
    Tracker.of_rule("computed_torque").check_window(0)  # fixed gains need no window
    with pytest.raises(InvalidInputError, match=r"^position_boosts: expected one factor per period, shape \(4,\), "
                       r"got shape \(3,\)$"):
        lqr_gains(np.ones(1), np.ones(1), np.ones(1), DT, np.ones(4), 10.0, np.ones(3))


def test_a_record_written_before_a_field_existed_keeps_the_tracker_it_was_tracked_with():
    """Tracker.of_record: a record without the end segment's fields tracks with no end segment, one without its
    position weight with the end segment's position weighed as its velocity, whatever today's defaults; a record
    that names them keeps them."""
    old = {"rule": "lqr", "window_boost": 3.0, "terminal": 1000.0, "taper": True, "anchor": "nominal",
           "anchor_gain": 1.0}
    assert Tracker.of_record(old).end_periods == 0
    assert Tracker.of_record(Tracker().as_dict()) == Tracker()
    # bit for bit the gains of the rules such records were tracked with: the window's weight to the window's end
    Q, R, mass = np.array([30.0, 20.0, 10.0, 3.0, 2.0, 1.0]), np.array([0.01, 0.02, 0.03]), np.diag([2.0, 1.5, 0.5])
    kp, kd = Tracker.of_record(old).gains((Q, R), mass, 30, 25, DT)
    want = lqr_gains(Q[:3], Q[3:], R * np.diag(mass) ** 2, DT, np.array([1.0] * 30 + [3.0] * 25), 1000.0)
    np.testing.assert_array_equal(kp, want[0])
    np.testing.assert_array_equal(kd, want[1])
    # and an end segment of 30 over the last 8 periods on the position as on the velocity
    ended = {**old, "end_boost": 30.0, "end_periods": 8}
    assert Tracker.of_record(ended).end_position == 1.0
    kp, kd = Tracker.of_record(ended).gains((Q, R), mass, 30, 25, DT)
    want = lqr_gains(Q[:3], Q[3:], R * np.diag(mass) ** 2, DT, np.array([1.0] * 30 + [3.0] * 17 + [30.0] * 8),
                     1000.0)
    np.testing.assert_array_equal(kp, want[0])
    np.testing.assert_array_equal(kd, want[1])


def test_a_trackers_departures_name_only_the_fields_that_act():
    """departures: the lqr default has none; no end segment names end_periods but not its idle weight; the
    computed_torque rule, whose fixed gains read no weight, names none of the LQR's fields."""
    assert Tracker().departures() == []
    assert Tracker(end_periods=0, end_boost=10.0, end_position=2.0).departures() == ["end_periods 0"]
    assert Tracker(end_position=1.0).departures() == ["end_position 1.0"]
    assert Tracker(window_boost=5.0, anchor_gain=0.5).departures() == ["window_boost 5.0", "anchor_gain 0.5"]
    ct = Tracker.of_rule("computed_torque")
    assert dataclasses.replace(ct, end_periods=8, terminal=5.0).departures() == []
    assert dataclasses.replace(ct, taper=True).departures() == ["taper True"]


def test_the_nominal_anchor_is_zero_on_the_nominal_plant_and_finds_a_plants_damping():
    """DisturbanceObserver: on the nominal plant (stepped as the env steps it) the estimate is exactly 0; on a
    plant that differs by joint damping b alone it is the damping torque -b qd over the period (the mean of its
    two ends, to 5 % of its size: the velocity is not linear over the period nor the mass matrix constant), one
    period after the first measurement (0 before it)."""
    import copy

    from mjtraj.core import DynamicsProbe
    from mjtraj.core.plant import BatchPlant
    from mjtraj.rl.plan_tracker import DisturbanceObserver
    from mjtraj.rl.plan_train import env_settings

    settings = env_settings(0.5)
    model = settings.model
    damped = copy.copy(model)
    damped.dof_damping[:] = [3.0, 2.0, 1.0]
    q0, qd0, u = np.array([[0.2, -1.1, 1.4]]), np.array([[0.8, -0.6, 1.1]]), np.array([[5.0, -8.0, 2.0]])
    mass = DynamicsProbe(model).mass_and_bias(q0, qd0)[0]
    for plant_model, nominal in ((model, True), (damped, False)):
        observer = DisturbanceObserver(model, settings.loop.gravity_comp, settings.loop.substeps, 1.0)
        observer.reset(np.ones(1, dtype=bool))
        assert np.all(observer.estimate(q0, qd0) == 0.0)
        observer.remember(q0, qd0, u, mass)
        plant = BatchPlant(plant_model, 1, gravity_comp=settings.loop.gravity_comp, substeps=settings.loop.substeps)
        plant.reset(q0, qd0)
        plant.step(u)
        q1, qd1 = plant.state()
        d = observer.estimate(q1, qd1)
        if nominal:
            assert np.all(d == 0.0)
        else:
            expected = -damped.dof_damping * (qd0 + qd1) / 2.0
            np.testing.assert_allclose(d, expected, rtol=0, atol=0.05 * np.abs(expected).max())
