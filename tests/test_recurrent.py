"""Recurrent policies (sb3-contrib's RecurrentPPO): memory is cleared where an episode starts and never leaks
between the rows of a batch; rl eval and validation tell the policy where episodes start."""

from __future__ import annotations

import numpy as np
import pytest
from sb3_contrib import RecurrentPPO

from mjtraj.rl.adapters import from_zip_policy
from mjtraj.rl.episodes import run_episodes
from mjtraj.rl.policy import Normalization, Policy
from mjtraj.rl.sb3_env import SB3TrackVecEnv
from mjtraj.rl.train import TrainSettings


@pytest.fixture(scope="module")
def policy() -> Policy:
    """An untrained LSTM policy (random weights: its actions depend on its memory) behind an identity transform."""
    settings = TrainSettings(algo="recurrent_ppo", task="random")
    env = SB3TrackVecEnv(1, **settings.env_kwargs())
    model = RecurrentPPO("MlpLstmPolicy", env, seed=0, device="cpu", n_steps=8, batch_size=8)
    d = env.observation_space.shape[0]
    record = {"settings": {"algo": "recurrent_ppo", "seed": 0}, "env": {**settings.env_kwargs(), "duration": 0.4}}
    return Policy(model, record, Normalization(np.zeros(d), np.full(d, 1e4), 0.0, 10.0), 0)


def _observations(count: int) -> np.ndarray:
    return np.random.default_rng(0).normal(0, 1, (count, 19))


def test_memory_matters_and_a_start_clears_it(policy):
    o = _observations(3)
    policy.start(np.ones(1, dtype=bool))
    first = policy.act(o[:1])
    policy.act(o[1:2])
    carried = policy.act(o[:1])
    policy.start(np.ones(1, dtype=bool))
    again = policy.act(o[:1])
    np.testing.assert_array_equal(again, first)
    assert not np.array_equal(carried, first)  # without the start, the memory of o[1] changes the action


def test_rows_of_a_batch_do_not_share_memory(policy):
    o = _observations(4)
    policy.start(np.ones(2, dtype=bool))
    together = [policy.act(o[0:2]), policy.act(o[2:4])]
    alone = []
    for row in range(2):
        policy.start(np.ones(1, dtype=bool))
        alone.append([policy.act(o[row:row + 1]), policy.act(o[2 + row:3 + row])])
    for step in range(2):
        np.testing.assert_allclose(together[step], np.vstack([alone[r][step] for r in range(2)]), atol=1e-6)


def test_the_evaluation_path_starts_every_episode_afresh(policy):
    """Two validation-style runs in a row on the same references give the same costs: the second does not inherit
    the first's memory (the path calls the policy's start at every batch)."""
    settings = policy.settings()
    rng = np.random.default_rng(1)
    tasks = [settings.sample_task(rng) for _ in range(2)]
    refs = [settings.planner.plan(t, settings.model) for t in tasks]
    weights = [settings.weights(t) for t in tasks]
    scored = from_zip_policy(policy, source="test")
    one = [o.metrics["cost"] for o in run_episodes(scored, settings, refs, weights)]
    two = [o.metrics["cost"] for o in run_episodes(scored, settings, refs, weights)]
    assert one == two
