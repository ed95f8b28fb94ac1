"""Fixed observation scales (`--observation-scaling fixed`): the PID-torque oracle, training through them, refusals."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from mjtraj.envs.settings import resolve
from mjtraj.envs.ur5_track import UR5TrackEnv

from mjtraj.cli import main
from mjtraj.core.controller import PIDGains
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.policy import load_policy
from mjtraj.rl.sb3_env import SB3TrackVecEnv
from mjtraj.rl.scaling import fixed_normalization, fixed_scales
from mjtraj.rl.train import TrainSettings


@pytest.mark.parametrize("scale", [1.0, 6.0])
def test_fixed_scales_observe_the_errors_as_pid_torque_in_units_of_the_residual(scale):
    """Oracle: the env's own tau_fb. The scaled P, D and I entries of the observation after period k, summed and
    times s, are the PID torque of period k+1, its integral first advanced by e dt (float32 rounding aside)."""
    env = UR5TrackEnv(action_mode="residual", residual_scale=scale, observe_control=True, task="random",
                      plant_randomization="mismatch")
    s, gains = env.settings, env.settings.loop.gains
    scaled = fixed_normalization(s, np.inf)
    n = s.n
    obs, _ = env.reset(seed=3)
    done, steps = False, 0
    while not done:
        z = scaled(obs[None])[0].astype(np.float64)
        np.testing.assert_allclose(z[:n] * np.pi, obs[:n], rtol=1e-6)  # positions in half turns
        e = obs[4 * n:5 * n]
        obs, _, terminated, truncated, info = env.step(np.zeros(n, np.float32))
        done = terminated or truncated
        m = 6 * n + 1
        predicted = (z[4 * n:5 * n] + z[5 * n:6 * n] + z[m:m + n]) * scale + gains.ki * e * s.dt
        np.testing.assert_allclose(predicted, info["tau_fb"], rtol=1e-5, atol=1e-5 * scale)
        steps += 1
    assert steps == s.steps
    assert np.all(fixed_scales(s)[m + n:] == s.torque_limit)  # the feedforward in units of the saturation


def test_fixed_scales_cover_the_preview_and_any_layout():
    s = resolve(action_mode="residual", preview=2, residual_scale=2.0)
    scales = fixed_scales(s)
    assert scales.shape == (s.obs_size,) == (19 + 12,)
    assert np.all(scales[19:] == np.pi) and scales[18] == 1.0  # previewed references; phase
    np.testing.assert_array_equal(scales[12:15], 2.0 / s.loop.gains.kp)


def test_fixed_scales_refuse_a_controller_without_pid_gains():
    with pytest.raises(InvalidInputError, match=r"^observation_scaling: fixed scales the errors by the PID gains; "
                                                r"expected the pid controller, got 'computed_torque'$"):
        fixed_scales(resolve(controller="computed_torque"))
    s = resolve()
    no_integral = dataclasses.replace(s, loop=dataclasses.replace(s.loop, gains=PIDGains.create(
        s.loop.gains.kp, [0.0, 1.0, 1.0], s.loop.gains.kd, 3)))
    with pytest.raises(InvalidInputError, match=r"^observation_scaling: fixed needs positive PID gains; ki is "
                                                r"\[0.0, 1.0, 1.0\]$"):
        fixed_scales(no_integral)


def test_an_unknown_observation_scaling_is_refused(capsys, tmp_path):
    assert main(["rl", "train", "--observation-scaling", "minmax", "--out", str(tmp_path / "x")]) == 2
    expected = "mjtraj: error: observation_scaling: unknown value 'minmax'; valid: running, fixed\n"
    assert capsys.readouterr().err == expected
    assert not (tmp_path / "x").exists()
    with pytest.raises(InvalidInputError,
                       match="^observation_scaling: unknown value 'none'; valid: running, fixed$"):
        TrainSettings(observation_scaling="none")


def test_the_sb3_env_shows_the_agent_the_scaled_observations():
    """Same seeds: the SB3 env's observations (the final ones in the infos too) are the vector env's, scaled."""
    kwargs = {"action_mode": "residual", "observe_control": True, "task": "random", "duration": 0.1}
    s = resolve(**kwargs)
    scaled = fixed_normalization(s, 10.0)
    agent = SB3TrackVecEnv(2, observe=scaled, **kwargs)
    raw = SB3TrackVecEnv(2, **kwargs)
    agent.seed(5), raw.seed(5)
    np.testing.assert_array_equal(agent.reset(), scaled(raw.reset()))
    actions = np.full((2, 3), 0.3, np.float32)
    for _ in range(s.steps):
        agent.step_async(actions), raw.step_async(actions)
        (obs, reward, dones, infos), (obs_raw, reward_raw, _, infos_raw) = agent.step_wait(), raw.step_wait()
        np.testing.assert_array_equal(obs, scaled(obs_raw))
        np.testing.assert_array_equal(reward, reward_raw)
    assert dones.all()
    for info, info_raw in zip(infos, infos_raw, strict=True):
        np.testing.assert_array_equal(info["terminal_observation"], scaled(info_raw["terminal_observation"]))
    agent.close(), raw.close()


@pytest.mark.slow
def test_a_run_with_fixed_scales_records_them_and_its_policy_acts_through_them(tmp_path):
    out = tmp_path / "fixed"
    assert main(["rl", "train", "--steps", "240", "--seed", "2", "--evaluations", "2", "--checkpoints", "2",
                 "--validation", "4", "--observe-control", "--observation-scaling", "fixed", "--out", str(out),
                 "--no-progress"]) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["settings"]["observation_scaling"] == "fixed" and run["normalization"]["norm_obs"] is False
    policy = load_policy(out / "policy.zip")
    expected = fixed_normalization(policy.settings(), 10.0)
    for got, want in ((policy.normalization.mean, expected.mean), (policy.normalization.var, expected.var)):
        np.testing.assert_array_equal(got, want)
    assert policy.normalization.epsilon == 0.0 and policy.label.endswith("sees PID, fixed scales)")
    obs = np.random.default_rng(0).normal(size=(16, policy.settings().obs_size))
    actions, _ = policy.model.predict(expected(obs), deterministic=True)
    np.testing.assert_array_equal(policy.act(obs), actions)
