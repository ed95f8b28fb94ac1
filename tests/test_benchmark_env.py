"""The benchmark envs (UR5Track-v1 and its variants) and the replay of held-out sweep scenarios in the env."""

import gymnasium as gym
import mjtraj.envs  # noqa: F401 - registers the envs
import numpy as np
import pytest
from mjtraj.envs import BENCHMARK_VARIANTS, UR5TrackEnv, UR5TrackVectorEnv

from mjtraj.exceptions import InvalidInputError
from mjtraj.study import SweepSettings, run_unit


def episode(env, action, **reset):
    """Run one episode with a constant action; (reset info, return, final info)."""
    _, first = env.reset(**reset)
    total, done = 0.0, False
    while not done:
        _, reward, terminated, truncated, info = env.step(action)
        total += reward
        done = terminated or truncated
    return first, total, info


@pytest.mark.parametrize("family", ["nominal", "aggressive", "mismatch"])
def test_a_replayed_scenario_costs_what_its_sweep_row_says_bit_for_bit(family):
    settings = SweepSettings(families=(family,), scenarios=3, seed=7, planners=("cubic",), batch=3)
    rows = run_unit(settings, (family, 0)).rows
    env = UR5TrackEnv(task="random", family=family)  # pid mode: the controller alone, as the sweep's rows
    for row in rows:
        first, total, info = episode(env, np.zeros(3), options={"scenario": {"family": family, "seed": 7,
                                                                             "index": int(row["scenario"])}})
        assert row["status"] == "ok"
        assert info["metrics"]["cost"] == float(row["cost"]) and -total == pytest.approx(float(row["cost"]))
        assert first["task"]["duration"] == float(row["duration"])
        if family == "mismatch":
            assert first["plant"]["payload_kg"] == float(row["payload_kg"])


def test_the_vector_env_replays_one_scenario_per_sub_env():
    single = UR5TrackEnv(task="random", family="mismatch")
    vector = UR5TrackVectorEnv(2, task="random", family="mismatch")
    specs = [{"family": "mismatch", "seed": 3, "index": i} for i in (4, 9)]
    obs, info = vector.reset(options={"scenario": specs})
    for i, spec in enumerate(specs):
        o, first = single.reset(options={"scenario": spec})
        np.testing.assert_array_equal(o, obs[i])
        assert first["plant"]["payload_kg"] == info["plant"]["payload_kg"][i]
    with pytest.raises(InvalidInputError, match=r"^options: 'scenario' expects a list of 2 scenarios"):
        vector.reset(options={"scenario": specs[0]})


def test_bad_scenarios_are_refused_with_what_to_do():
    env = UR5TrackEnv(task="random")
    with pytest.raises(InvalidInputError, match=r"make the env with family='mismatch' \(UR5TrackMismatch-v1\)"):
        env.reset(options={"scenario": {"family": "mismatch", "seed": 0, "index": 0}})
    with pytest.raises(InvalidInputError, match=r"^options: 'scenario' expects a dict with the keys family, seed"):
        env.reset(options={"scenario": {"family": "nominal", "seed": 0}})
    with pytest.raises(InvalidInputError, match=r"scenario family 'hard' is unknown"):
        env.reset(options={"scenario": {"family": "hard", "seed": 0, "index": 0}})
    with pytest.raises(InvalidInputError, match=r"^options: 'scenario' sets the task, duration and plant; give it"):
        env.reset(options={"scenario": {"family": "nominal", "seed": 0, "index": 0}, "duration": 1.0})
    with pytest.raises(InvalidInputError, match=r"^family: 'nominal' draws every episode's task; use task='random'"):
        UR5TrackEnv(family="nominal")


def test_v1_acts_by_default_and_each_seed_draws_a_new_task():
    env = gym.make("UR5Track-v1")
    assert env.unwrapped.settings.action_mode == "residual" and env.unwrapped.settings.residual_scale == 6.0
    returns = {a: episode(env, np.full(3, a), seed=0)[1] for a in (-1.0, 0.0, 1.0)}
    assert len(set(returns.values())) == 3  # the action changes the return (v0's default ignores it)
    tasks = [episode(env, np.zeros(3), seed=s)[0]["task"]["qg"] for s in (0, 1)]
    assert not np.array_equal(*tasks)
    env.close()


def test_the_variants_draw_their_family():
    aggressive = gym.make("UR5TrackAggressive-v1")
    durations = {aggressive.reset(seed=s)[1]["task"]["duration"] for s in range(6)}
    assert len(durations) > 1 and all(0.5 <= d <= 1.0 for d in durations)
    mismatch = gym.make("UR5TrackMismatch-v1")
    assert mismatch.reset(seed=0)[1]["plant"]["payload_kg"] > 0
    assert set(BENCHMARK_VARIANTS) == {"UR5Track-v1", "UR5TrackAggressive-v1", "UR5TrackMismatch-v1", "UR5Track-v2",
                                       "UR5TrackAggressive-v2", "UR5TrackMismatch-v2", "UR5TrackNoisy-v2"}
    vec = gym.make_vec("UR5TrackMismatch-v1", num_envs=2, vectorization_mode="vector_entry_point")
    assert vec.unwrapped.settings.family == "mismatch"
    for env in (aggressive, mismatch, vec):
        env.close()
