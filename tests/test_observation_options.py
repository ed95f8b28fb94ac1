"""The env's memory and plant options against oracles: the history is the env's own earlier observations, the
plant entries are reset info's plant (or the loop's estimate) over the stated bounds, the evaluation path observes
the same sequence, and a deployable policy's observation carries no privileged input."""

from __future__ import annotations

import gymnasium as gym
import mjtraj.envs  # noqa: F401
import numpy as np
import pytest
from mjtraj.envs.ur5_track import UR5TrackEnv
from mjtraj.envs.vector import UR5TrackVectorEnv

from mjtraj.core import parameter_bounds
from mjtraj.domain.pipeline import Job, execute


def _rollout(env, actions):
    obs, info = env.reset(seed=3)
    out = [obs]
    for a in actions:
        obs, *_ = env.step(a)
        out.append(obs)
    return np.array(out), info


def test_history_is_the_envs_own_earlier_observations():
    actions = np.random.default_rng(0).uniform(-1, 1, (12, 3)).astype(np.float32)
    plain, _ = _rollout(UR5TrackEnv(action_mode="residual", task="random"), actions)
    stacked, _ = _rollout(UR5TrackEnv(action_mode="residual", task="random", history=3), actions)
    d = plain.shape[1]
    assert stacked.shape[1] == 4 * d
    for k in range(len(plain)):
        for j in range(4):
            np.testing.assert_array_equal(stacked[k, j * d:(j + 1) * d], plain[max(k - j, 0)])


def test_vector_env_history_restarts_with_each_episode():
    """Across an autoreset the history is refilled with the new episode's first observation; within an episode it
    is the previous observations (oracle: the same vector env without history)."""
    env = UR5TrackVectorEnv(2, action_mode="residual", task="random", history=2)
    plain = UR5TrackVectorEnv(2, action_mode="residual", task="random")
    obs, _ = env.reset(seed=5)
    ref, _ = plain.reset(seed=5)
    d = ref.shape[1]
    seen, start, restarts, ended = [ref], 0, 0, False
    actions = np.random.default_rng(1).uniform(-1, 1, (230, 2, 3)).astype(np.float32)
    for k, a in enumerate(actions, start=1):
        obs, *_ = env.step(a)
        ref, _, done, cut, _ = plain.step(a)
        seen.append(ref)
        if ended:  # this step reset both sub-envs (same N, none diverged)
            start, restarts = k, restarts + 1
        assert np.all(done | cut) or not np.any(done | cut)
        ended = bool(np.any(done | cut))
        for j in range(3):
            np.testing.assert_array_equal(obs[:, j * d:(j + 1) * d], seen[max(k - j, start)])
    assert restarts == 2
    env.close()
    plain.close()


def test_observe_plant_true_is_reset_infos_plant_over_its_bounds():
    env = UR5TrackEnv(action_mode="residual", task="random", family="mismatch", observe_plant="true")
    obs, info = env.reset(seed=1)
    plant = info["plant"]
    theta = np.array([plant["payload_kg"], *(plant[f"damping_{j}"] for j in range(3)),
                      *(plant[f"friction_{j}"] for j in range(3))]).reshape(-1)
    bounds = parameter_bounds(env.settings.model)
    np.testing.assert_allclose(obs[-7:], theta / bounds, rtol=0, atol=0)
    obs, *_ = env.step(np.zeros(3, np.float32))
    np.testing.assert_allclose(obs[-7:], theta / bounds, rtol=0, atol=0)
    assert env.observation_space.contains(obs)
    env.close()


def test_observe_plant_estimate_is_the_adaptive_laws_estimate_and_starts_at_zero():
    env = UR5TrackEnv(action_mode="residual", task="random", family="mismatch", observe_plant="estimate",
                      controller="adaptive_computed_torque")
    obs, _ = env.reset(seed=2)
    np.testing.assert_array_equal(obs[-7:], 0.0)  # nothing is known before the first period
    for _ in range(30):
        obs, *_ = env.step(np.zeros(3, np.float32))
    state = env.unwrapped.loop.law_state()[0]
    np.testing.assert_array_equal(obs[-7:], state / parameter_bounds(env.settings.model))
    assert obs[-7] > 0.0  # it has begun to estimate the payload
    env.close()


@pytest.mark.parametrize("kwargs", [{"history": 2, "observe_control": True},
                                    {"observe_plant": "estimate", "controller": "adaptive_computed_torque",
                                     "history": 1},
                                    {"observe_plant": "true", "family": "mismatch", "task": "random"}])
def test_the_evaluation_path_observes_as_the_env(kwargs):
    """A policy that acts on every entry of its observation gives, through the evaluation path (rl eval and
    validation), the env's own episode, cost bit for bit."""
    from mjtraj.rl.episodes import PolicyActor

    weights = None

    def policy(obs):
        nonlocal weights
        if weights is None:
            weights = np.random.default_rng(7).normal(0, 1e-3, (obs.shape[1], 3))
        return np.clip(np.tanh(obs @ weights), -1, 1).astype(np.float32)

    env = UR5TrackEnv(action_mode="residual", **kwargs)
    obs, info = env.reset(seed=4)
    done = False
    while not done:
        obs, _, done, _, last = env.step(policy(obs[None])[0])
    core = env.unwrapped._core
    s = env.settings
    task = core.tasks[0]
    plant = core.plants[0]
    job = Job(s.planner.plan(task, s.model), s.weights(task), plant)
    out = execute(s.model, s.loop, [job], actor=PolicyActor(policy, s), plant=core.plant)
    assert out[0].metrics["cost"] == last["metrics"]["cost"]
    env.close()


def test_a_deployable_policy_sees_no_privileged_input():
    """The student's observation (observe_plant='estimate') is a function of what the controller measures: two
    plants that differ only in a parameter the law has not yet felt give identical first observations, while the
    teacher's (observe_plant='true') differ. And rl eval labels only the teacher privileged."""
    from mjtraj.rl.adapters import ScoredPolicy

    light = {"family": "mismatch", "seed": 0, "index": 0}
    heavy = {"family": "mismatch", "seed": 0, "index": 1}
    student = UR5TrackEnv(action_mode="residual", task="random", family="mismatch", observe_plant="estimate",
                          controller="adaptive_computed_torque")
    teacher = UR5TrackEnv(action_mode="residual", task="random", family="mismatch", observe_plant="true",
                          controller="adaptive_computed_torque")
    s_light, _ = student.reset(options={"scenario": light})
    s_heavy, info = student.reset(options={"scenario": heavy})
    t_light, _ = teacher.reset(options={"scenario": light})
    t_heavy, _ = teacher.reset(options={"scenario": heavy})
    np.testing.assert_array_equal(s_light[-7:], s_heavy[-7:])
    assert not np.array_equal(t_light[-7:], t_heavy[-7:])

    def act(obs):
        return np.zeros((len(obs), 3))

    def scored(env):
        return ScoredPolicy("p", "p", "callable", {"observe_plant": env}, act)

    assert not scored("estimate").sees_plant and scored("true").sees_plant
    student.close()
    teacher.close()


def test_a_time_limit_truncation_carries_the_metrics_of_the_periods_run():
    """gym.make's TimeLimit cuts the episode at k < N: episode_metrics() then gives the metrics of the k periods,
    whose J_exec is minus the return (the reward sums the same step costs); the vector env's truncating step carries
    them in its info."""
    import gymnasium as gym

    env = gym.make("UR5Track-v0", action_mode="residual", max_episode_steps=30)
    env.reset(seed=0)
    total, truncated, info = 0.0, False, {}
    steps = 0
    while not truncated:
        _, reward, terminated, truncated, info = env.step(np.full(3, 0.2, np.float32))
        total += reward
        steps += 1
        assert not terminated
    assert steps == 30
    metrics = env.unwrapped.episode_metrics()
    assert metrics["cost"] == pytest.approx(-total, rel=1e-12)
    assert np.isfinite(metrics["terminal_err"]) and metrics["terminal_err"] > 0
    env.close()
    vec = UR5TrackVectorEnv(2, action_mode="residual", max_episode_steps=30)
    vec.reset(seed=0)
    returns = np.zeros(2)
    for _ in range(30):
        _, reward, _, cut, vinfo = vec.step(np.full((2, 3), 0.2, np.float32))
        returns += reward
    assert cut.all()
    np.testing.assert_allclose(vinfo["metrics"]["cost"], -returns, rtol=1e-12)
    vec.close()


@pytest.mark.parametrize("law, mode, integrates", [("pid", "residual", True), ("pid", "torque", True),
                                                   ("adaptive_computed_torque", "residual", False),
                                                   ("mpc", "torque", False)])
def test_observe_controls_integral_is_what_the_env_card_says(law, mode, integrates):
    """The integral entries: pid integrates e (in torque mode too), the other laws leave them 0 (the env card)."""
    env = gym.make("UR5Track-v2", controller=law, action_mode=mode, observe_control=True)
    obs, _ = env.reset(seed=1)
    for _ in range(10):
        obs, *_ = env.step(np.zeros(3))
    integral = obs[19:22]
    assert np.any(integral != 0.0) if integrates else np.all(integral == 0.0)
