"""Metrics on hand-made arrays with hand-computed answers."""

from __future__ import annotations

import numpy as np
import pytest

from mjtraj.core.metrics import METRIC_NAMES, executed_cost, integral_abs, metrics, reduction, rms
from mjtraj.core.rollout import Rollout


def hand_rollout() -> Rollout:
    e = np.array([[[1.0, -1.0], [2.0, 0.0]]])          # (B=1, N=2, n=2)
    ed = np.array([[[0.0, 1.0], [0.0, 0.0]]])
    dtau = np.array([[[3.0, -4.0], [0.0, 60.0]]])
    fb = np.array([[[1.0, 1.0], [1.0, 1.0]]])
    sat = np.array([[[False, False], [False, True]]])
    z = np.zeros((1, 2, 2))
    return Rollout(q=z, qd=z, e=e, ed=ed, tau_ff=dtau - fb, tau_fb=fb, dtau=dtau, saturated=sat,
                   q_final=np.zeros((1, 2)), qd_final=np.zeros((1, 2)), e_final=np.array([[3.0, 4.0]]),
                   diverged_step=np.array([-1]), dt=0.5)



def test_by_hand():
    m = metrics(hand_rollout(), np.diag([1.0, 2.0, 3.0, 4.0]), np.diag([0.5, 0.25]))[0]
    assert m.rms_err == pytest.approx(np.sqrt(6 / 4))
    assert m.rms_dtau == pytest.approx(np.sqrt((9 + 16 + 3600) / 4))
    assert m.int_dtau == pytest.approx((3 + 4 + 60) * 0.5)
    # k=0: x=[1,-1,0,1]: 1 + 2 + 0 + 4 = 7; u: 0.5*9 + 0.25*16 = 8.5 -> 15.5
    # k=1: x=[2,0,0,0]: 4; u: 0.25*3600 = 900 -> 904
    assert m.cost == pytest.approx(919.5)
    assert m.rms_fb == pytest.approx(1.0)
    assert m.peak_dtau == 60.0 and m.saturated_frac == 0.25 and m.max_err == 2.0 and m.terminal_err == 5.0



def test_pure_functions_broadcast():
    x = np.arange(24.0).reshape(2, 3, 4)
    np.testing.assert_allclose(rms(x), [np.sqrt(np.mean(x[0] ** 2)), np.sqrt(np.mean(x[1] ** 2))])
    np.testing.assert_allclose(integral_abs(-x, 0.1), [x[0].sum() * 0.1, x[1].sum() * 0.1])
    e = np.ones((2, 3, 2))
    np.testing.assert_allclose(executed_cost(e, 0 * e, 0 * e, np.ones(4), np.ones(2)), [6.0, 6.0])
    weights = np.array([[1.0, 1, 0, 0], [0, 0, 2, 2]])  # one diagonal per execution
    np.testing.assert_allclose(executed_cost(e, e, 0 * e, weights, np.ones((2, 2))), [6.0, 12.0])



def test_reduction_matches_the_papers_columns():
    # Table I: Int. dtau 6.329 (cubic) vs 4.535 (optimal) -> 28.35 %; cost 6.983 vs 3.622 -> 48.13 %
    assert reduction(6.329, 4.535) == pytest.approx(28.35, abs=0.005)
    assert reduction(6.983, 3.622) == pytest.approx(48.13, abs=0.005)



def test_diverged_scenario_gives_nan():
    r = hand_rollout()
    bad = Rollout(**{**{k: getattr(r, k) for k in r.__dataclass_fields__}, "diverged_step": np.array([1])})
    m = metrics(bad, np.eye(4), np.eye(2))[0]
    assert all(np.isnan(getattr(m, name)) for name in METRIC_NAMES)



def test_norm_and_total_torque_definitions(model, scenario):
    """rms_dtau_norm = sqrt(n) rms_dtau; rms_tau_total uses G(q_k) by mj_forward at the recorded poses."""
    import mujoco

    from mjtraj.core.closed_loop import ClosedLoop
    from mjtraj.core.metrics import gravity_along, metrics_arrays
    from mjtraj.core.planners import make

    rollout = ClosedLoop(model, scenario.loop).run([make("cubic").plan(scenario.task, model)])
    arrays = metrics_arrays(rollout, scenario.Q_exec, scenario.R_exec, gravity=gravity_along(model, rollout))
    assert arrays["rms_dtau_norm"][0] == pytest.approx(np.sqrt(3) * arrays["rms_dtau"][0], rel=1e-12)
    data = mujoco.MjData(model)
    gravity = []
    for q in rollout.q[0]:
        data.qpos[:], data.qvel[:] = q, 0.0
        mujoco.mj_forward(model, data)
        gravity.append(data.qfrc_bias.copy())
    total = np.sqrt(np.mean(np.square(np.array(gravity) + rollout.dtau[0])))
    assert arrays["rms_tau_total"][0] == pytest.approx(total, rel=1e-12)
    assert np.isnan(metrics_arrays(rollout, scenario.Q_exec, scenario.R_exec)["rms_tau_total"][0])
