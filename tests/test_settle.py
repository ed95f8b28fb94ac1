"""Protocol v2's settle window (mjtraj.core.settle): the held reference, the score's parts and the at-rest rule
against hand computations, the v1 score of the same motion bit for bit, the env against the sweep's rows, and the
rule as a property of every row."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from mjtraj.core import Rollout, executed_cost, load_model, make
from mjtraj.core.settle import SETTLE_BAND, SETTLE_SPEED, Settle, held, settle_arrays, unsettled, window_steps
from mjtraj.core.task import Task
from mjtraj.exceptions import InvalidInputError
from mjtraj.study.sweep import SweepSettings, run_unit


@pytest.fixture(scope="module")
def model():
    return load_model()


def test_the_held_reference_keeps_the_motion_and_rests_at_the_goal(model):
    task = Task.create([0.0, -1.5, 0.2], [0.4, -1.0, 0.5], 1.0, 0.02, model=model)
    ref = make("optimal").plan(task, model)
    longer = held(ref, 25, task.qg)
    assert longer.steps == ref.steps + 25 and longer.info["motion_steps"] == ref.steps
    assert np.array_equal(longer.q[:ref.steps + 1], ref.q) and np.array_equal(longer.qd[:ref.steps + 1], ref.qd)
    assert np.array_equal(longer.q[ref.steps + 1:], np.tile(task.qg, (25, 1)))
    assert not longer.qd[ref.steps + 1:].any() and not longer.qdd[ref.steps + 1:].any()
    assert np.array_equal(longer.u_plan[:ref.steps], ref.u_plan) and not longer.u_plan[ref.steps:].any()
    assert np.allclose(np.diff(longer.t), 0.02, rtol=0, atol=1e-12)
    assert held(ref, 0) is ref


def test_a_window_is_a_whole_number_of_periods():
    assert window_steps(0.5, 0.02) == 25 and window_steps(0.0, 0.02) == 0
    with pytest.raises(InvalidInputError, match=r"^settle: expected a whole number of control periods of 0.02 s, "
                                                r"got 0.51 s$"):
        window_steps(0.51, 0.02)
    with pytest.raises(InvalidInputError, match=r"^settle: expected a window >= 0 s, got -1.0$"):
        window_steps(-1.0, 0.02)


def _rollout(rng, B, steps, n):
    e, ed, dtau = (rng.standard_normal((B, steps, n)) for _ in range(3))
    q = rng.standard_normal((B, steps, n))
    q_final, qd_final = rng.standard_normal((B, n)), rng.standard_normal((B, n))
    return Rollout(q=q, qd=np.zeros_like(q), e=e, ed=ed, tau_ff=np.zeros_like(q), tau_fb=np.zeros_like(q), dtau=dtau,
                   saturated=np.zeros_like(q, dtype=bool), q_final=q_final, qd_final=qd_final, e_final=q_final,
                   diverged_step=np.full(B, -1), dt=0.02)


def test_the_parts_sum_to_the_episodes_score_and_the_motion_is_j_exec():
    """Oracles: J_exec over every period and over the motion's (`executed_cost`, the score's one definition); the end
    error and speed as the largest joint's."""
    rng = np.random.default_rng(0)
    B, N, S, n = 3, 7, 4, 2
    r = _rollout(rng, B, N + S, n)
    q_diag, r_diag = rng.uniform(0.1, 2, (B, 2 * n)), rng.uniform(0.1, 2, (B, n))
    goal = rng.standard_normal((B, n))
    arrays = settle_arrays(r, q_diag, r_diag, [Settle(N, S, goal[b], 1.0) for b in range(B)])
    total = executed_cost(r.e, r.ed, r.dtau, q_diag, r_diag)
    parts = arrays["cost_position"] + arrays["cost_velocity"] + arrays["cost_torque"]
    assert np.allclose(parts, total, rtol=1e-13)
    assert np.array_equal(arrays["cost_motion"], executed_cost(np.ascontiguousarray(r.e[:, :N]),
                                                               np.ascontiguousarray(r.ed[:, :N]),
                                                               np.ascontiguousarray(r.dtau[:, :N]), q_diag, r_diag))
    assert np.allclose(arrays["cost_torque"], [np.sum(r.dtau[b] ** 2 * r_diag[b]) for b in range(B)], rtol=1e-13)
    assert np.array_equal(arrays["end_err"], np.max(np.abs(goal - r.q_final), axis=1))
    assert np.array_equal(arrays["end_speed"], np.max(np.abs(r.qd_final), axis=1))


def test_the_settling_time_is_when_the_last_joint_entered_the_band_for_good():
    """A hand-made path of one joint: out of the band until sample 9 of 12 (motion 6 periods + window 6): 3 periods
    after the motion's end; entering and leaving again counts the last entry; inside from the motion's end: 0; outside
    at the end: NaN."""
    N, S = 6, 6
    band_ok = 0.001

    def settle_time(path, final):
        q = np.array(path, dtype=np.float64)[None, :, None]
        r = Rollout(q=q, qd=np.zeros_like(q), e=np.zeros_like(q), ed=np.zeros_like(q), tau_ff=np.zeros_like(q),
                    tau_fb=np.zeros_like(q), dtau=np.zeros_like(q), saturated=np.zeros_like(q, dtype=bool),
                    q_final=np.array([[final]]), qd_final=np.zeros((1, 1)), e_final=np.zeros((1, 1)),
                    diverged_step=np.array([-1]), dt=0.1)
        return settle_arrays(r, np.ones(2), np.ones(1), [Settle(N, S, np.zeros(1), band_ok / SETTLE_BAND)])[
            "settle_time"][0]

    out, inside = 0.5, 0.0
    assert settle_time([out] * 9 + [inside] * 3, inside) == pytest.approx(0.3)
    assert settle_time([inside] * 4 + [out] * 3 + [inside] * 5, inside) == pytest.approx(0.1)
    assert settle_time([out] * 3 + [inside] * 9, inside) == 0.0
    assert np.isnan(settle_time([inside] * 12, out))


def test_the_at_rest_rule_names_what_it_missed():
    settle = Settle(10, 25, np.zeros(3), 0.5)
    assert unsettled(0.0099, 0.049, settle) == ""
    assert unsettled(0.011, 0.01, settle) == "end error 0.011 rad > 0.02 x the move (0.01 rad)"
    assert unsettled(0.0, 0.06, settle) == f"end speed 0.06 rad/s > {SETTLE_SPEED:g} rad/s"
    assert unsettled(float("nan"), 0.0, settle).startswith("end error nan")


def test_a_window_leaves_the_motions_j_exec_bit_for_bit_under_pid():
    """PID reads only the current sample: the first N periods of a v2 episode are v1's execution, so its J_exec of
    the motion (cost_motion) is v1's cost, bit for bit, on every family; the window only adds."""
    for family in ("nominal", "aggressive", "mismatch"):
        v1 = run_unit(SweepSettings(families=(family,), scenarios=4, seed=5, planners=("cubic", "quintic")),
                      (family, 0)).rows
        v2 = run_unit(SweepSettings(families=(family,), scenarios=4, seed=5, planners=("cubic", "quintic"),
                                    settle=0.5), (family, 0)).rows
        assert [r["cost"] for r in v1] == [r["cost_motion"] for r in v2]
        assert all(b["cost"] > a["cost"] for a, b in zip(v1, v2, strict=True))
        assert "settle" not in v1[0] and v2[0]["settle"] == 0.5 and "end_speed" not in v1[0]


@pytest.mark.parametrize("config", [None, "paper_adaptive"])
def test_every_row_is_ok_exactly_when_at_rest_at_the_goal(config):
    """The property of protocol v2's success rule over rows of every family: ok rows end within the band and below
    the speed limit; not_settled rows do not, and say why (every law: the slow tier)."""
    _check_at_rest_rule(config, scenarios=3)


@pytest.mark.slow
@pytest.mark.parametrize("law", ["pid", "computed_torque", "adaptive_computed_torque", "mpc", "adaptive_mpc"])
def test_every_laws_rows_are_ok_exactly_when_at_rest_at_the_goal(tmp_path, law):
    from pathlib import Path

    from mjtraj.rl.evaluate import _law_config

    _check_at_rest_rule(_law_config(law, Path(tmp_path)), scenarios=12)


def _check_at_rest_rule(config, scenarios):
    seen = set()
    for family in ("nominal", "aggressive", "mismatch"):
        for noise in (0.0, 1e-3) if family == "mismatch" else (0.0,):
            rows = run_unit(SweepSettings(families=(family,), scenarios=scenarios, seed=11, planners=("cubic",),
                                          config=config, settle=0.5, sensor_noise=noise), (family, 0)).rows
            for r in rows:
                band = SETTLE_BAND * r["max_displacement"]
                at_rest = r["end_err"] <= band and r["end_speed"] <= SETTLE_SPEED
                assert r["status"] in ("ok", "not_settled"), r["reason"]
                assert (r["status"] == "ok") == at_rest, (family, r["end_err"], band, r["end_speed"])
                assert (r["reason"] == "") == at_rest
                seen.add(r["status"])
    assert "ok" in seen


@pytest.mark.slow
def test_the_noisy_env_declares_its_sensor_to_the_law_as_the_sweep_does(tmp_path):
    """UR5TrackNoisy-v2 under `adaptive_mpc`, whose filter is designed for the sensor the loop declares, replays the
    sweep's noisy row (1 mrad declared there too) bit for bit."""
    from mjtraj.rl.evaluate import _law_config

    row = run_unit(SweepSettings(families=("mismatch",), scenarios=1, seed=4, planners=("cubic",),
                                 config=_law_config("adaptive_mpc", tmp_path),
                                 settle=0.5, sensor_noise=1e-3), ("mismatch", 0)).rows[0]
    env = gym.make("UR5TrackNoisy-v2", controller="adaptive_mpc")
    env.reset(options={"scenario": {"family": "mismatch", "seed": 4, "index": row["scenario"]}})
    done = False
    while not done:
        _, _, done, _, info = env.step(np.zeros(3))
    assert info["metrics"]["cost"] == row["cost"] and info["metrics"]["end_speed"] == row["end_speed"]


def test_the_v2_env_replays_the_sweeps_v2_rows_bit_for_bit():
    """UR5TrackAggressive-v2 and UR5TrackMismatch-v2 with a zero residual are the sweep's cubic+PID rows under a
    0.5 s window: the same score, parts, end speed and at-rest verdict; the return is minus J_settle."""
    for env_id, family in (("UR5TrackAggressive-v2", "aggressive"), ("UR5TrackMismatch-v2", "mismatch")):
        rows = run_unit(SweepSettings(families=(family,), scenarios=2, seed=4, planners=("cubic",), settle=0.5),
                        (family, 0)).rows
        env = gym.make(env_id)
        for row in rows:
            obs, info = env.reset(options={"scenario": {"family": family, "seed": 4, "index": row["scenario"]}})
            assert obs.shape == (21,)
            total, steps, done = 0.0, 0, False
            while not done:
                obs, reward, done, _, info = env.step(np.zeros(3))
                total += reward
                steps += 1
            assert steps == round(row["duration"] / 0.02) + 25
            metrics = info["metrics"]
            for name in ("cost", "cost_position", "cost_velocity", "cost_torque", "cost_motion", "end_err",
                         "end_speed", "settle_time"):
                assert metrics[name] == row[name] or (np.isnan(metrics[name]) and np.isnan(row[name])), name
            assert info["settled"] == (row["status"] == "ok") and info["settle_reason"] == row["reason"]
            assert total == pytest.approx(-metrics["cost"], rel=1e-12)
        env.close()


def test_the_v2_observation_is_the_measured_state_and_names_the_task():
    """With measurement noise the v2 observation's q, qd, e, ed are what the law measures (the true state plus that
    period's noise); v1's observation keeps the true state. The last two entries are the move and the time to the
    motion's end."""
    noisy = gym.make("UR5TrackNoisy-v2").unwrapped
    obs, info = noisy.reset(seed=2)
    loop = noisy.loop
    q, qd = loop.measured()
    assert not np.array_equal(q, loop.positions)
    assert np.array_equal(obs[:3], q[0]) and np.array_equal(obs[3:6], qd[0])
    assert np.array_equal(obs[12:15], obs[6:9] - q[0])
    move = float(np.max(np.abs(info["task"]["qg"] - info["task"]["q0"])))
    assert obs[19] == move and obs[20] == pytest.approx(info["task"]["duration"])
    for _ in range(3):
        obs, *_ = noisy.step(np.zeros(3))
    assert obs[20] == pytest.approx(info["task"]["duration"] - 3 * 0.02)
    v1 = gym.make("UR5TrackMismatch-v1", measurement_noise=1e-3).unwrapped
    obs, _ = v1.reset(seed=2)
    assert obs.shape == (19,) and np.array_equal(obs[:3], v1.loop.positions[0])


@pytest.mark.parametrize("settle", [0.5, 0.7])
def test_the_v2_observation_stays_in_its_space_through_the_window(settle):
    """The time to the motion's end runs down to minus the window, computed in periods (0.7 s is 35 periods, whose
    product with dt rounds below -0.7): every observation of an episode lies in the observation space."""
    env = gym.make("UR5TrackAggressive-v2", settle=settle).unwrapped
    obs, _ = env.reset(seed=1)
    done = False
    while not done:
        assert env.observation_space.contains(obs)
        obs, _, done, _, _ = env.step(np.zeros(3))
    assert env.observation_space.contains(obs) and obs[20] < 0


def test_a_noise_free_scenario_is_not_replayed_under_noise():
    env = gym.make("UR5TrackNoisy-v2")
    with pytest.raises(InvalidInputError, match=r"^options: a nominal scenario is measured without noise \(sweeps "
                                                r"draw noise for mismatched plants only\); make the env with "
                                                r"measurement_noise=0 to replay it, got measurement_noise=0.001$"):
        env.reset(options={"scenario": {"family": "nominal", "seed": 1, "index": 0}})


def test_mpc_plans_to_rest_through_the_window(tmp_path):
    """With a settle window the MPC's terminal rows are the at-rest rule's: held-out aggressive motions end at rest
    at the goal (an aggressive scenario it had left still moving under v1's terminal box)."""
    rows = run_unit(SweepSettings(families=("aggressive",), scenarios=3, seed=777, planners=("cubic",),
                                  config=_mpc_config(tmp_path), settle=0.5), ("aggressive", 0)).rows
    assert [r["status"] for r in rows] == ["ok"] * 3
    assert max(r["end_speed"] for r in rows) <= SETTLE_SPEED


def _mpc_config(folder):
    from mjtraj.rl.evaluate import _law_config

    return _law_config("mpc", folder)
