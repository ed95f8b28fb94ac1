"""Protocol v2's Kalman filter (`mjtraj.core.estimator`): the same estimates as an independent filter (filterpy's)
on the same linear model, a constant disturbance and payload found on a linear plant, the parameters kept within
their bounds; and in the predictive laws: a residual is not taken for a disturbance."""

from __future__ import annotations

import re

import gymnasium as gym
import mjtraj.envs  # noqa: F401
import numpy as np
import pytest

from mjtraj.core.estimator import DisturbanceKalman, KalmanSettings


def _model(rng, n):
    """A stable discrete double integrator per joint, coupled a little: A (2n, 2n), B (2n, n)."""
    dt = 0.02
    A = np.block([[np.eye(n), dt * np.eye(n)], [-0.05 * np.eye(n), 0.98 * np.eye(n)]]) + 1e-3 * rng.normal(size=(2 * n,
                                                                                                             2 * n))
    B = np.vstack([0.5 * dt**2 * np.eye(n), dt * np.eye(n)]) * rng.uniform(0.5, 2.0, n)
    return dt, A, B


@pytest.mark.parametrize("parameters", [0, 2])
def test_the_filter_is_filterpys_on_the_augmented_model(parameters):
    """Twenty periods of a time-varying regressor: the estimate and covariance of `DisturbanceKalman` equal
    filterpy's KalmanFilter (predict, then update, on z = [x; d; theta] with F = [[A, B, B Y], [0, I, 0], [0, 0,
    I]]), filterpy's parameters projected onto the bounds as ours are (the one step a Kalman filter does not take)."""
    from filterpy.kalman import KalmanFilter

    rng = np.random.default_rng(3)
    n = 3
    dt, A, B = _model(rng, n)
    bounds = np.full(parameters, 10.0)
    ours = DisturbanceKalman(n, dt, KalmanSettings(), bounds=bounds)
    m = ours.size
    theirs = KalmanFilter(dim_x=m, dim_z=2 * n)
    theirs.H = np.hstack([np.eye(2 * n), np.zeros((2 * n, m - 2 * n))])
    theirs.R = np.diag(ours.measurement)
    theirs.Q = np.diag(ours.process)
    theirs.P = ours.initial(1)[0]
    theirs.x = np.zeros(m)
    P = ours.initial(1)
    z = np.zeros((1, m - 2 * n))
    x = np.zeros((1, 2 * n))
    for _ in range(20):
        Y = rng.normal(size=(1, n, parameters))
        u = rng.normal(size=n)
        F = np.eye(m)
        F[:2 * n, :2 * n], F[:2 * n, 2 * n:3 * n] = A, B
        F[:2 * n, 3 * n:] = B @ Y[0]
        theirs.F = F
        theirs.predict(u=None)
        theirs.x = theirs.x + np.concatenate([B @ u, np.zeros(m - 2 * n)])
        predicted = (A @ x[0] + B @ (u + z[0, :n] + Y[0] @ z[0, n:]))[None]
        P = ours.predict(P, A[None], B[None], Y if parameters else None)
        y = rng.normal(size=2 * n) * 0.01
        theirs.update(y)
        theirs.x[3 * n:] = np.clip(theirs.x[3 * n:], 0.0, bounds)
        x, z, P = ours.correct(predicted, z, P, y[None])
        np.testing.assert_allclose(np.concatenate([x[0], z[0]]), theirs.x, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(P[0], theirs.P, rtol=1e-8, atol=1e-14)


def test_a_constant_torque_and_payload_on_a_linear_plant_are_found():
    """The plant receives 2 N m on joint 0 and a 'payload' of 1.5 whose torque is a known, varying regressor; with
    the sensor's noise, after 400 periods the filter's torque disturbance and parameter are within a few percent (a
    prior of 0.15 of the bound, so that 1.5 lies within two of its standard deviations)."""
    rng = np.random.default_rng(5)
    n = 2
    dt, A, B = _model(rng, n)
    filt = DisturbanceKalman(n, dt, KalmanSettings(initial_parameter=0.15), bounds=[10.0])
    x_true = np.zeros(2 * n)
    d_true, theta_true = np.array([2.0, 0.0]), 1.5
    P, x, z = filt.initial(1), x_true[None].copy(), np.zeros((1, n + 1))
    sigma = np.sqrt(filt.measurement)
    for k in range(400):
        Y = np.array([[0.0], [5.0 * np.sin(0.05 * k)]])[None]
        u = -2.0 * x_true[:n] - 0.5 * x_true[n:]
        x_true = A @ x_true + B @ (u + d_true + Y[0, :, 0] * theta_true)
        predicted = (A @ x[0] + B @ (u + z[0, :n] + Y[0] @ z[0, n:]))[None]
        P = filt.predict(P, A[None], B[None], Y)
        x, z, P = filt.correct(predicted, z, P, (x_true + sigma * rng.standard_normal(2 * n))[None])
    assert z[0, 0] == pytest.approx(2.0, abs=0.15)
    assert z[0, 2] == pytest.approx(1.5, rel=0.05)


def test_the_parameters_stay_within_their_bounds():
    filt = DisturbanceKalman(1, 0.02, KalmanSettings(initial_parameter=0.15), bounds=[1.0])
    P = filt.predict(filt.initial(1), np.eye(2)[None], np.array([[[0.0], [0.02]]]), np.ones((1, 1, 1)))
    _, z, _ = filt.correct(np.zeros((1, 2)), np.zeros((1, 2)), P, np.array([[10.0, 500.0]]))
    _, w, _ = filt.correct(np.zeros((1, 2)), np.zeros((1, 2)), P, np.array([[-10.0, -500.0]]))
    assert 0.0 <= z[0, 1] <= 1.0 and 0.0 <= w[0, 1] <= 1.0
    assert {z[0, 1], w[0, 1]} == {0.0, 1.0}  # the unprojected estimates leave the bounds on both sides


def test_the_settings_refuse_what_is_not_a_noise_level():
    from mjtraj.exceptions import InvalidInputError

    with pytest.raises(InvalidInputError, match="torque_noise"):
        KalmanSettings(torque_noise=0.0)
    with pytest.raises(InvalidInputError, match="state_noise"):
        KalmanSettings(state_noise=(1e-4,))  # type: ignore[arg-type]


@pytest.mark.slow
@pytest.mark.parametrize("law", ["mpc", "adaptive_mpc"])
def test_a_residual_enters_the_prediction_so_the_filter_does_not_cancel_it(law):
    """On the nominal plant without noise (v2), a constant residual of 3 N m on joint 0: the filter's torque
    disturbance stays near zero (it predicts the residual), and the residual moves the execution."""
    def run(action):
        env = gym.make("UR5Track-v2", controller=law, residual_scale=6.0)
        env.reset(seed=4)
        loop = env.unwrapped.loop
        n = 3
        seen = []
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            seen.append(loop.law_state()[0, 1 + 4 * n:1 + 5 * n].copy())
        return np.array(seen), info["metrics"]["cost"]

    quiet, cost = run(np.zeros(3))
    pushed, pushed_cost = run(np.array([0.5, 0.0, 0.0]))
    assert np.max(np.abs(pushed[5:, 0] - quiet[5:, 0])) < 0.3  # 3 N m of residual: not in the estimate
    assert pushed_cost > cost


def test_the_filter_assumes_the_declared_sensor_times_its_margin_at_least_its_least():
    """`sensor_margin` 2, `sensor` 1 mrad: simulations declared exact, 1 mrad and 3 mrad are filtered as three
    filters that assume a fixed 1, 2 and 6 mrad (the covariance before the first measurement and every correction)."""
    rng = np.random.default_rng(8)
    n = 3
    dt, A, B = _model(rng, n)
    declared = np.array([0.0, 1e-3, 3e-3])
    ours = DisturbanceKalman(n, dt, KalmanSettings(sensor_margin=2.0), bounds=[5.0])
    fixed = [DisturbanceKalman(n, dt, KalmanSettings(sensor=s), bounds=[5.0]) for s in (1e-3, 2e-3, 6e-3)]
    P = ours.initial(3, declared)
    for b, f in enumerate(fixed):
        np.testing.assert_array_equal(P[b], f.initial(1)[0])
    x, z = np.zeros((3, 2 * n)), np.zeros((3, n + 1))
    for _ in range(5):
        Y = rng.normal(size=(3, n, 1))
        P = ours.predict(P, np.broadcast_to(A, (3, *A.shape)), np.broadcast_to(B, (3, *B.shape)), Y)
        y = rng.normal(size=(3, 2 * n)) * 0.01
        theirs = [f.correct(x[b:b + 1], z[b:b + 1], P[b:b + 1], y[b:b + 1]) for b, f in enumerate(fixed)]
        x, z, P = ours.correct(x, z, P, y, declared)
        for b, (xb, zb, Pb) in enumerate(theirs):
            np.testing.assert_array_equal(x[b], xb[0])
            np.testing.assert_array_equal(z[b], zb[0])
            np.testing.assert_array_equal(P[b], Pb[0])
    assert not np.array_equal(P[0], P[1])
    from mjtraj.exceptions import InvalidInputError

    with pytest.raises(InvalidInputError, match="^sensor_margin: "):
        KalmanSettings(sensor_margin=0.0)


@pytest.mark.slow
def test_the_loop_declares_its_sensor_to_the_predictive_laws_filter(monkeypatch, scenario, model):
    """A noisy mismatch episode of protocol v2 under `adaptive_mpc` (margin 2) with 1 mrad declared is, bit for bit,
    the episode of a law whose filter assumes a fixed 2 mrad with nothing declared; declaring nothing to the shipped
    law (so that it assumes 1 mrad) changes the execution."""
    import dataclasses

    import mjtraj.core.laws as laws
    from mjtraj.core.model import JointInfo
    from mjtraj.core.mpc import ADAPTIVE_SETTINGS, AdaptiveModelPredictive
    from mjtraj.core.settle import Settle, held
    from mjtraj.domain.families import draw_scenario, measurement_noise, perturbed_plant
    from mjtraj.domain.pipeline import Job, execute_batch
    from mjtraj.study.sweep import SCORING

    drawn = draw_scenario("mismatch", 777, 1, model, 0.02)
    reference = held(scenario.planner("cubic").plan(drawn.task, model), 25, drawn.task.qg)
    noise = measurement_noise([drawn], reference.steps, 3, 1e-3, 0.02)[:, 0]
    weights = SCORING.weights(drawn.task, JointInfo.of(model).torque_limit)
    settle = Settle.of(drawn.task, reference.steps - 25, 25)
    config, plant = dataclasses.replace(scenario.loop, controller="adaptive_mpc"), perturbed_plant(model)

    def run(sensor):
        job = Job(reference, weights, drawn.perturbation, noise, settle, sensor)
        return execute_batch(model, config, [job], plant=plant)[0].dtau

    declared, silent = run(1e-3), run(0.0)
    fixed = dataclasses.replace(ADAPTIVE_SETTINGS, kalman=dataclasses.replace(ADAPTIVE_SETTINGS.kalman, sensor=2e-3,
                                                                               sensor_margin=1.0))
    monkeypatch.setitem(laws._BUILT_IN, "adaptive_mpc", lambda config, dt, n, nsim, m: AdaptiveModelPredictive(
        m, dt, nsim, rate=config.adaptation_rate, settings=fixed))
    np.testing.assert_array_equal(run(0.0), declared)
    assert not np.array_equal(silent, declared)


def test_a_declared_sensor_that_is_not_a_standard_deviation_per_simulation_is_refused(scenario, model):
    from mjtraj.core.closed_loop import ClosedLoop
    from mjtraj.exceptions import InvalidInputError

    loop = ClosedLoop(model, scenario.loop, nsim=2)
    references = [scenario.planner("cubic").plan(scenario.task, model)] * 2
    for bad, message in ((-1e-3, "expected standard deviations >= 0 (rad), got [-0.001, -0.001]"),
                         ([1e-3, 0.0, 0.0], "expected 2 values, got shape (3,)"),
                         ("noisy", "expected 2 numbers, got 'noisy'"),
                         (np.nan, "expected finite values, got [nan, nan]")):
        with pytest.raises(InvalidInputError, match="^sensor: " + re.escape(message) + "$"):
            loop.start(references, sensor=bad)
    loop.start(references, sensor=[0.0, 1e-3])  # one each is accepted


def test_a_law_whose_track_does_not_take_sensors_is_not_given_them():
    """A plug-in law written before sensors were declared (its `track` without `sensors`) still runs on noisy
    episodes: the loop passes it the settle window alone; a `track` that takes `sensors`, or any keyword, gets them."""
    from mjtraj.core.closed_loop import _accepted

    def before(rows, q_ref, qd_ref, tau_ff, *, windows=None):
        return None

    def after(rows, q_ref, qd_ref, tau_ff, *, windows=None, sensors=None):
        return None

    def anything(rows, q_ref, qd_ref, tau_ff, **given):
        return None

    extra = {"windows": np.ones(2), "sensors": np.ones(2)}
    assert set(_accepted(before, extra)) == {"windows"}
    assert set(_accepted(after, extra)) == set(_accepted(anything, extra)) == {"windows", "sensors"}
    assert _accepted(before, {"windows": extra["windows"]}) == {"windows": extra["windows"]}
