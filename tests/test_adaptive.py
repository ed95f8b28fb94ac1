"""Adaptive computed torque against oracles: the MjSpec-built payload plant and mj_inverse for the regressor, the
polarisation identity's symmetric Coriolis term, and convergence of the estimate to a known payload."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from mjtraj.core.adaptive import AdaptiveComputedTorque, parameter_bounds
from mjtraj.core.closed_loop import ClosedLoop, LoopConfig
from mjtraj.core.controller import ComputedTorque, PIDGains
from mjtraj.core.dynamics import DynamicsProbe
from mjtraj.core.model import load_model
from mjtraj.core.payload import with_point_mass
from mjtraj.core.reference import Reference
from mjtraj.domain.families import Perturbation, no_perturbation, perturbed_plant, plant_fields
from mjtraj.exceptions import InvalidInputError


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return load_model()


def _inverse(model: mujoco.MjModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, *, fields=None) -> np.ndarray:
    """mj_inverse's qfrc_inverse per state (`fields`, one row each, set on `model` first)."""
    data = mujoco.MjData(model)
    if fields is not None:
        for name, value in fields.items():
            getattr(model, name)[:] = value[0]
    out = np.empty_like(q)
    for i in range(q.shape[0]):
        data.qpos[:], data.qvel[:], data.qacc[:] = q[i], qd[i], qdd[i]
        mujoco.mj_inverse(model, data)
        out[i] = data.qfrc_inverse
    return out


def _states(rows: int, seed: int = 0) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    return tuple(rng.uniform(-1.5, 1.5, (rows, 3)) for _ in range(3))


def test_point_mass_model_equals_the_welded_payload_body(model):
    """with_point_mass (parallel-axis algebra on one body) against perturbed_plant (MjSpec adds a welded body)."""
    welded = perturbed_plant(model)
    welded_fields = plant_fields(welded, [Perturbation(2.5, np.ones(3), np.ones(3), np.zeros(3), np.zeros(3))])
    for name, value in welded_fields.items():
        getattr(welded, name)[:] = value[0]
    merged = with_point_mass(model, 2.5)
    q, qd, qdd = _states(20)
    np.testing.assert_allclose(_inverse(merged, q, qd, qdd), _inverse(welded, q, qd, qdd), rtol=1e-10, atol=1e-10)


def test_regressor_times_true_parameters_is_the_plants_extra_torque(model):
    """With qd_r = qd and qdd_r = qdd, Y theta equals what mj_inverse says the perturbed plant needs beyond the
    nominal model (payload and damping; friction, a constraint, is not in mj_inverse)."""
    law = AdaptiveComputedTorque(model, 0.02, 20)
    q, qd, qdd = _states(20, 1)
    payload, damping = 3.2, np.array([0.4, 0.9, 0.2])
    plant = perturbed_plant(model)
    perturbation = Perturbation(payload, np.ones(3), np.ones(3), damping, np.zeros(3))
    fields = plant_fields(plant, [perturbation])
    extra = _inverse(plant, q, qd, qdd, fields=fields) - _inverse(model, q, qd, qdd)
    _, _, Y = law.regressor(q, qd, qd, qdd)
    theta = np.concatenate([[payload], damping, np.zeros(3)])
    np.testing.assert_allclose(np.einsum("bip,p->bi", Y, theta), extra, rtol=1e-9, atol=1e-9)


def test_nominal_torque_uses_the_symmetric_coriolis_term(model):
    """The nominal part at qd_r = qd is computed torque's feedforward D qdd + h; C(q, a) b is bilinear and
    symmetric (polarisation), so swapping the velocities leaves it unchanged."""
    law = AdaptiveComputedTorque(model, 0.02, 20)
    q, qd, qdd = _states(20, 2)
    nominal, D, _ = law.regressor(q, qd, qd, qdd)
    D0, h = DynamicsProbe(model, size=20).mass_and_bias(q, qd)
    np.testing.assert_allclose(D, D0, rtol=1e-12)
    np.testing.assert_allclose(nominal, np.einsum("bij,bj->bi", D0, qdd) + h, rtol=1e-9, atol=1e-9)
    other = _states(20, 3)[1]
    one, _, _ = law.regressor(q, qd, other, np.zeros_like(qdd))
    two, _, _ = law.regressor(q, other, qd, np.zeros_like(qdd))
    passive = DynamicsProbe(model, size=20).terms(q, qd)[2] - DynamicsProbe(model, size=20).terms(q, other)[2]
    np.testing.assert_allclose(one - two, -passive, atol=1e-9)


def _exciting_reference(steps: int, dt: float) -> Reference:
    """Sums of sinusoids of incommensurate frequencies on every joint about the upright pose: persistently
    exciting for the payload's gravity and inertia."""
    t = np.arange(steps + 1) * dt
    home = np.array([0.0, -np.pi / 2, 0.0])
    w = np.array([[1.1, 2.3], [0.7, 1.9], [1.3, 2.9]])
    a = np.array([[0.6, 0.3], [0.5, 0.2], [0.7, 0.3]])
    q = home + np.stack([sum(a[j, i] * np.sin(w[j, i] * t) for i in range(2)) for j in range(3)], axis=1)
    qd = np.stack([sum(a[j, i] * w[j, i] * np.cos(w[j, i] * t) for i in range(2)) for j in range(3)], axis=1)
    qdd = np.stack([sum(-a[j, i] * w[j, i] ** 2 * np.sin(w[j, i] * t) for i in range(2)) for j in range(3)], axis=1)
    return Reference("exciting", t, q - q[0] + home, qd, qdd)


@pytest.mark.parametrize("payload", [1.5, 4.0])
def test_estimate_converges_to_a_known_payload(model, payload):
    """On a plant whose only difference from the nominal model is a payload, a persistently exciting 20 s motion
    drives the estimate to it; the damping and friction estimates stay near their true zero."""
    plant = perturbed_plant(model)
    truth = Perturbation(payload, np.ones(3), np.ones(3), np.zeros(3), np.zeros(3))
    config = LoopConfig(PIDGains.create([1, 1, 1], [0, 0, 0], [0, 0, 0], 3), controller="adaptive_computed_torque")
    loop = ClosedLoop(model, config, nsim=1, plant=plant, plant_fields=plant_fields(plant, [truth]))
    loop.run([_exciting_reference(1000, float(model.opt.timestep))])
    estimate = loop.law_state()
    assert estimate is not None
    assert estimate[0, 0] == pytest.approx(payload, rel=0.02)
    bounds = parameter_bounds(model)
    assert np.all(estimate[0, 1:] <= 0.02 * bounds[1:])


def test_nominal_plant_keeps_the_estimate_near_zero_and_tracks_like_computed_torque(model):
    """No payload: the estimate stays small and the tracking error is computed torque's to within 10 % (both are
    the zero-order hold's, a few mrad on this fast motion)."""
    ref = _exciting_reference(200, float(model.opt.timestep))
    gains = PIDGains.create([1, 1, 1], [0, 0, 0], [0, 0, 0], 3)
    adaptive = ClosedLoop(model, LoopConfig(gains, controller="adaptive_computed_torque"))
    out = adaptive.run([ref])
    ct = ClosedLoop(model, LoopConfig(gains, controller="computed_torque")).run([ref])
    assert np.abs(out.e).max() <= 1.1 * np.abs(ct.e).max() < 5e-3
    assert adaptive.law_state()[0, 0] < 0.05


def test_state_resets_on_restart_and_can_be_set(model):
    plant = perturbed_plant(model)
    config = LoopConfig(PIDGains.create([1, 1, 1], [0, 0, 0], [0, 0, 0], 3), controller="adaptive_computed_torque")
    loaded = Perturbation(4.0, np.ones(3), np.ones(3), np.zeros(3), np.zeros(3))
    loop = ClosedLoop(model, config, nsim=2, plant=plant,
                      plant_fields=plant_fields(plant, [loaded, no_perturbation(3)]))
    ref = _exciting_reference(100, float(model.opt.timestep))
    loop.run([ref, ref])
    assert loop.law_state()[0, 0] > 1.0
    loop.restart([0], [ref])
    np.testing.assert_array_equal(loop.law_state()[0], 0.0)
    loop.set_law_state([[4.0, 0, 0, 0, 0, 0, 0]], [1])
    assert loop.law_state()[1, 0] == 4.0
    with pytest.raises(InvalidInputError, match="state: expected finite values of shape"):
        loop.set_law_state([[1.0, 2.0]], [0])
    pid = ClosedLoop(model, LoopConfig(PIDGains.create([1, 1, 1], [0, 0, 0], [0, 0, 0], 3)))
    pid.start([ref])
    assert pid.law_state() is None
    with pytest.raises(InvalidInputError, match="has no state"):
        pid.set_law_state([[0.0]])


def test_zero_rate_freezes_the_estimate(model):
    plant = perturbed_plant(model)
    config = LoopConfig(PIDGains.create([1, 1, 1], [0, 0, 0], [0, 0, 0], 3), controller="adaptive_computed_torque",
                        adaptation_rate=0.0)
    loaded = Perturbation(4.0, np.ones(3), np.ones(3), np.full(3, 0.5), np.full(3, 1.0))
    loop = ClosedLoop(model, config, plant=plant, plant_fields=plant_fields(plant, [loaded]))
    loop.run([_exciting_reference(50, float(model.opt.timestep))])
    np.testing.assert_array_equal(loop.law_state(), 0.0)
    with pytest.raises(InvalidInputError, match="adaptation_rate"):
        LoopConfig(PIDGains.create([1, 1, 1], [0, 0, 0], [0, 0, 0], 3), adaptation_rate=-1.0)


def test_is_computed_torques_gains_at_zero_estimate(model):
    """theta_hat = 0, qd_r's Coriolis aside: lam = k = w gives computed torque's kp = w^2, kd = 2 w."""
    law = AdaptiveComputedTorque(model, 0.02, 1)
    ct = ComputedTorque.for_period(0.02, 3)
    assert law.w**2 == pytest.approx(ct.kp[0]) and 2 * law.w == pytest.approx(ct.kd[0])


def test_oracle_actor_starts_the_estimate_at_each_plants_truth(model):
    from mjtraj.domain.oracle import TrueParameters, true_parameters

    plant = perturbed_plant(model)
    plants = [Perturbation(2.0, np.ones(3), np.ones(3), np.array([0.1, 0.2, 0.3]), np.array([1.0, 2.0, 3.0])),
              no_perturbation(3)]
    config = LoopConfig(PIDGains.create([1, 1, 1], [0, 0, 0], [0, 0, 0], 3), controller="adaptive_computed_torque")
    loop = ClosedLoop(model, config, nsim=2, plant=plant, plant_fields=plant_fields(plant, plants))
    ref = _exciting_reference(10, float(model.opt.timestep))
    loop.start([ref, ref])
    actor = TrueParameters()
    actor.begin(loop, [ref, ref], plants)
    np.testing.assert_array_equal(loop.law_state(), [[2.0, 0.1, 0.2, 0.3, 1.0, 2.0, 3.0], np.zeros(7)])
    np.testing.assert_array_equal(true_parameters(plants, 3), loop.law_state())
    np.testing.assert_array_equal(actor.act(loop), np.zeros((2, 3)))
