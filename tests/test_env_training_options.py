"""What the env offers training: plant randomisation and measurement noise (the sweeps' mismatch rules, drawn per
episode), the reward relative to PID alone, and the env pickled or copied after reset."""

from __future__ import annotations

import copy
import pickle
import re

import gymnasium as gym
import numpy as np
import pytest
from mjtraj.envs.ur5_track import UR5TrackEnv
from mjtraj.envs.vector import UR5TrackVectorEnv

from mjtraj.core import random_task
from mjtraj.core.model import JointInfo
from mjtraj.core.planners import make
from mjtraj.core.scoring import Scoring
from mjtraj.domain.families import (
    DAMPING,
    FRICTION,
    LINK_SCALE,
    PAYLOAD_MASS,
    draw_perturbation,
    noise_scale,
    perturbed_plant,
)
from mjtraj.domain.pipeline import Job, execute
from mjtraj.exceptions import InvalidInputError

SIGMA = 2e-4
"""rad, the measurement noise of the noisy cases."""


def run(env, seed, action=None):
    """One episode from reset(seed); (reset info, rewards, final info)."""
    _, first = env.reset(seed=seed)
    rewards = []
    while True:
        a = np.zeros(env.action_space.shape) if action is None else action
        _, reward, terminated, truncated, info = env.step(a)
        rewards.append(reward)
        if terminated or truncated:
            return first, np.array(rewards), info


@pytest.mark.parametrize("sigma", [0.0, SIGMA])
def test_a_randomised_episode_is_the_sweep_pipelines_execution_of_the_same_draws(model, sigma):
    """Oracle: the draws made by hand from reset's generator (task, then plant, then noise, by the sweeps' rules)
    executed by the sweeps' pipeline on the perturbed plant give the env's episode metrics exactly."""
    env = UR5TrackEnv(task="random", plant_randomization="mismatch", measurement_noise=sigma)
    seed = 11
    first, _, info = run(env, seed)
    rng = np.random.default_rng(seed)  # gymnasium's np_random(seed) is this generator
    task = random_task(rng, model, max_displacement=1.5, duration=2.0, dt=0.02)
    perturbation = draw_perturbation(rng, 3)
    noise = rng.standard_normal((task.steps, 6)) * noise_scale(3, sigma, 0.02) if sigma else None
    assert first["plant"] == perturbation.as_dict()
    weights = Scoring().weights(task, JointInfo.of(model).torque_limit)
    job = Job(make("cubic").plan(task, model), weights, perturbation, noise)
    (expected,) = execute(model, env.settings.loop, [job], plant=perturbed_plant(model))
    assert expected.status == "ok"
    np.testing.assert_equal(info["metrics"], expected.metrics)  # NaN equals NaN here (rms_tau_total)


def test_the_plant_changes_every_episode_within_the_mismatch_rules():
    env = UR5TrackEnv(plant_randomization="mismatch")
    env.reset(seed=0)
    plants = [env.reset()[1]["plant"] for _ in range(200)]
    columns = {name: np.array([p[name] for p in plants]) for name in plants[0]}
    bounds = {"payload_kg": PAYLOAD_MASS, "mass_scale": LINK_SCALE, "inertia_scale": LINK_SCALE,
              "damping": DAMPING, "friction": FRICTION}
    for name, values in columns.items():
        low, high = bounds[name.rsplit("_", 1)[0] if name != "payload_kg" else name]
        assert low <= values.min() and values.max() <= high, name
        assert values.max() - values.min() > 0.8 * (high - low), name  # spread over the range, not fixed
    assert "plant" not in UR5TrackEnv().reset(seed=0)[1]  # no randomisation: the nominal plant, nothing reported


def test_randomisation_changes_the_execution_and_the_same_seed_repeats_it():
    nominal = run(UR5TrackEnv(), 5)[2]["metrics"]
    a = run(UR5TrackEnv(plant_randomization="mismatch"), 5)
    b = run(UR5TrackEnv(plant_randomization="mismatch"), 5)
    c = run(UR5TrackEnv(plant_randomization="mismatch"), 6)
    np.testing.assert_equal(a[2]["metrics"], b[2]["metrics"])
    np.testing.assert_equal(a[0], b[0])
    assert a[2]["metrics"]["rms_err"] > 10 * nominal["rms_err"]  # a 0..5 kg payload the feedforward ignores
    assert c[2]["metrics"]["rms_err"] != a[2]["metrics"]["rms_err"]


@pytest.mark.slow
def test_vector_env_sub_env_i_is_the_single_env_seeded_s_plus_i_under_randomisation():
    kwargs = {"task": "random", "action_mode": "residual", "plant_randomization": "mismatch",
              "measurement_noise": SIGMA}
    venv = UR5TrackVectorEnv(3, autoreset_mode="SameStep", **kwargs)
    _, info = venv.reset(seed=20)
    assert info["_plant"].tolist() == [True] * 3
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (260, 3, 3))  # two episodes and a bit: the autoreset draws new plants
    rewards, restarted = [], []
    for a in actions:
        _, reward, _, _, info = venv.step(a)
        rewards.append(reward)
        if "plant" in info:
            restarted.append(info["_plant"].copy())
    assert len(restarted) == 2 and all(mask.all() for mask in restarted)
    for i in range(3):
        env = UR5TrackEnv(**kwargs)
        env.reset(seed=20 + i)
        single = []
        for a in actions:
            _, reward, terminated, _, _ = env.step(a[i])
            single.append(reward)
            if terminated:
                env.reset()
        assert np.array_equal(np.array(rewards)[:, i], single)


@pytest.mark.parametrize("kwargs", [{}, {"task": "random", "action_mode": "residual",
                                         "plant_randomization": "mismatch", "measurement_noise": SIGMA}])
def test_the_env_pickles_and_deep_copies_after_reset_and_goes_on_bit_for_bit(kwargs):
    env = gym.make("UR5Track-v0", **kwargs)
    env.reset(seed=3)
    for _ in range(30):
        env.step(np.full(3, 0.2))
    clones = [pickle.loads(pickle.dumps(env)), copy.deepcopy(env)]
    action = np.array([0.3, -0.5, 0.1])
    expected = run_on(env, action)
    for clone in clones:
        np.testing.assert_equal(run_on(clone, action), expected)
    assert copy.deepcopy(env).reset(seed=9)[0].tolist() == env.reset(seed=9)[0].tolist()


def run_on(env, action):
    """Rewards and final metrics of the rest of the running episode, then of one more (no new seed)."""
    out = []
    for _ in range(2):
        while True:
            _, reward, terminated, _, info = env.step(action)
            out.append(reward)
            if terminated:
                out.append(info["metrics"])
                env.reset()
                break
    return out


def test_the_vector_env_pickles_after_reset():
    venv = UR5TrackVectorEnv(2, task="random", plant_randomization="mismatch")
    venv.reset(seed=1)
    venv.step(np.zeros((2, 3)))
    clone = pickle.loads(pickle.dumps(venv))
    a = np.full((2, 3), 0.4)
    assert np.array_equal(venv.step(a)[0], clone.step(a)[0])


@pytest.mark.parametrize(("extra", "name"), [({}, "controller"), ({}, "pid"),
                                             ({"plant_randomization": "mismatch", "measurement_noise": SIGMA}, "pid"),
                                             ({"controller": "computed_torque"}, "controller")])
def test_the_baseline_reward_is_the_plain_reward_minus_the_laws_alone_on_the_same_episode(extra, name):
    """Oracle: the plain env with the same actions, and the same episode in pid mode (the configured law alone,
    PID or computed torque); 'pid' is the earlier name of 'controller' and means the same."""
    kwargs = {"task": "random", **extra}
    advantage = UR5TrackEnv(action_mode="residual", reward_baseline=name, **kwargs)
    plain = UR5TrackEnv(action_mode="residual", **kwargs)
    alone = UR5TrackEnv(action_mode="pid", **kwargs)
    actions = np.random.default_rng(1).uniform(-1, 1, (100, 3))
    runs = [run_actions(env, actions, seed=8) for env in (advantage, plain, alone)]
    (r_adv, m_adv), (r_plain, m_plain), (r_pid, m_pid) = runs
    np.testing.assert_array_equal(r_adv, r_plain - r_pid)
    np.testing.assert_equal(m_adv, m_plain)  # the metrics still score J_exec
    np.testing.assert_allclose(r_adv.sum(), m_pid["cost"] - m_plain["cost"], rtol=1e-12)
    assert m_plain["cost"] != m_pid["cost"]


def run_actions(env, actions, seed):
    """Rewards of one episode from reset(seed) under `actions`, and its final metrics."""
    env.reset(seed=seed)
    rewards = []
    for a in actions:
        _, reward, terminated, _, info = env.step(a)
        rewards.append(reward)
        if terminated:
            return np.array(rewards), info["metrics"]
    raise AssertionError("the episode did not end")


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"reward_baseline": "zero"}, "reward_baseline: unknown value 'zero'; valid: none, controller, pid"),
    ({"plant_randomization": "payload"}, "plant_randomization: unknown value 'payload'; valid: none, mismatch"),
    ({"measurement_noise": -1e-3}, "measurement_noise: expected a value >= 0, got -0.001"),
    ({"measurement_noise": float("nan")}, "measurement_noise: expected a finite number, got nan"),
    ({"plant_randomization": True}, "plant_randomization: expected a string, got True"),
])
def test_bad_randomisation_arguments_are_one_line_errors(kwargs, message):
    with pytest.raises(InvalidInputError, match=f"^{re.escape(message)}$"):
        UR5TrackEnv(**kwargs)
