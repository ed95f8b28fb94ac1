"""baseline:best: chosen on validation scenarios by the stated rule, never on evaluation ones."""

from __future__ import annotations

import json

import numpy as np
import pytest

import mjtraj.rl.best as best
from mjtraj.core import load_model
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.baselines import BEST_FILE, baseline_names, best_name
from mjtraj.study import FAMILIES, draw_scenario


def test_validation_scenarios_are_not_evaluation_scenarios():
    model = load_model()
    for family in FAMILIES:
        mine = best.validation_scenarios(family, 20, model, 0.02)
        for seed in range(3):
            for i in range(20):
                theirs = draw_scenario(family, seed, i, model, 0.02).task
                assert not any(np.array_equal(m.task.q0, theirs.q0) for m in mine)


def test_the_rule_takes_the_lowest_worst_family_ratio(tmp_path, monkeypatch):
    names = baseline_names()[:3]
    scores = {names[0]: {"nominal": 1.01, "aggressive": 1.5, "mismatch": 0.3},
              names[1]: {"nominal": 1.2, "aggressive": 1.1, "mismatch": 0.9},
              names[2]: {"nominal": float("inf"), "aggressive": 1.0, "mismatch": 0.2}}
    asked = []

    def scored(deployable, *, scenarios, protocol, progress):
        asked.append((scenarios, protocol))
        return {n: scores[n] for n in deployable}

    monkeypatch.setattr(best, "score_baselines", scored)
    record = best.choose_best(tmp_path, names, scenarios=3, command="test")
    assert record["best"] == names[1]  # worst ratios 1.5, 1.2, inf
    assert record["protocol"] == "v2" and record["rule"] == best.BEST_RULES["v2"] and asked == [(3, "v2")]
    written = json.loads((tmp_path / BEST_FILE).read_text())
    assert written["best"] == names[1] and written["scores"][names[2]]["nominal"] == "inf"
    assert best_name(tmp_path) == names[1]
    # protocol v1's rule is recorded apart: baseline:best stays v2's choice
    scores[names[0]]["aggressive"] = 1.0
    record = best.choose_best(tmp_path, names, scenarios=3, protocol="v1", command="test")
    assert record["best"] == names[0] and record["protocol"] == "v1" and record["rule"] == best.BEST_RULES["v1"]
    assert asked[-1] == (3, "v1")
    assert json.loads((tmp_path / best.BEST_FILES["v1"]).read_text())["best"] == names[0]
    assert best_name(tmp_path) == names[1]


def test_a_family_ratio_is_rl_evals_ratio_of_means():
    """Over the scenarios the reference did not fail; +inf once the policy failed one of those (oracle: rl eval's
    own `ratio_of_means`, NaN marking a failure there)."""
    from mjtraj.rl.protocol_stats import ratio_of_means

    inf = np.inf
    for mine, theirs in (([1.0, 2.0, 3.0], [2.0, 2.0, 2.0]), ([1.0, 2.0, 9.0], [2.0, 2.0, inf]),
                         ([1.0, 2.0, inf], [2.0, 2.0, inf]), ([inf, 2.0, 3.0], [2.0, 2.0, inf])):
        mine, theirs = np.array(mine), np.array(theirs)
        want = ratio_of_means(np.where(np.isfinite(mine), mine, np.nan)[None],
                              np.where(np.isfinite(theirs), theirs, np.nan)[None])[0]
        assert best.family_ratio(mine, theirs) == want
    assert best.family_ratio(np.array([1.0, 2.0, inf]), np.array([2.0, 2.0, inf])) == 0.75
    assert best.family_ratio(np.array([1.0]), np.array([inf])) == inf  # rl eval: NaN, no scenario to read


def test_best_name_without_a_choice(tmp_path):
    with pytest.raises(InvalidInputError, match="baseline:best has not been chosen yet; run mjtraj rl best"):
        best_name(tmp_path)


def test_an_unknown_protocol_is_refused(tmp_path):
    with pytest.raises(InvalidInputError, match="protocol: expected one of v1, v2, got 'v3'"):
        best.choose_best(tmp_path, baseline_names()[:1], scenarios=1, protocol="v3")
    assert not (tmp_path / BEST_FILE).exists()


def _env_costs(env, scenarios, act, monkeypatch, start=None) -> np.ndarray:
    """Each scenario's score, replayed in `env` (reset to it, `act(obs)` each step, the cost from the last step's
    info): +inf where the episode diverged, or, with a settle window, did not end at rest at the goal, or without
    one, on the nominal family, ended short of the goal. `start()` is called before each episode (a policy with
    episode state starts afresh)."""
    from mjtraj.envs.settings import TrackSettings

    costs = []
    for scenario in scenarios:
        monkeypatch.setattr(TrackSettings, "scenario", lambda self, spec, scenario=scenario: scenario)
        obs, _ = env.reset(options={"scenario": {"family": scenario.family, "seed": 0, "index": scenario.index}})
        if start is not None:
            start()
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(act(obs))
            done = terminated or truncated
        failed = info["diverged"] or (not info["settled"] if "settled" in info else
                                      scenario.family == "nominal" and info["missed_goal"])
        costs.append(np.inf if failed else info["metrics"]["cost"])
    return np.array(costs)


@pytest.mark.slow
@pytest.mark.parametrize("protocol", ["v1", "v2"])
@pytest.mark.parametrize("name", ["ppo_batched_s1", "plan_lqr_s1"])
def test_scores_are_ratios_to_the_reference_on_the_same_scenarios(monkeypatch, protocol, name):
    """One baseline, two scenarios per family. Oracle: the validation scenarios drawn here from the stated stream
    [VALIDATION_SEED, VALIDATION_STREAM, family id, i] and replayed in UR5TrackEnv, stepped by hand: the policy acting
    on the env's observations in the env it declares, and the controller alone (a zero action) in the random-task env
    of the protocol's reference (v1: the default env, cubic+PID; v2: the adaptive law's shipped scenario, every
    episode with the settle window, the policy observing the measured state); each ratio is the mean of the policy's
    episode costs over the reference's (over the scenarios the reference did not fail). A torch policy's float32
    kernels batch differently in the two paths: 1e-9 relative. One baseline of each kind: a batched run's torch
    module and a plan (NumPy, with episode state)."""
    from mjtraj.envs import UR5TrackEnv

    from mjtraj.core import SETTLE_WINDOW
    from mjtraj.rl.adapters import load_any
    from mjtraj.rl.streams import VALIDATION_STREAM
    from mjtraj.study import FAMILY_ID, FamilyScenario, draw_family, load_scenario

    policy = load_any(f"baseline:{name}")
    assert not policy.sees_plant  # a deployable one: acts on observations alone
    got = best.score_baselines([name], scenarios=2, protocol=protocol)[name]
    assert list(got) == list(FAMILIES)
    v2 = {"settle": SETTLE_WINDOW} if protocol == "v2" else {}
    law = {"scenario": load_scenario("paper_adaptive")} if protocol == "v2" else {}
    for family in FAMILIES:
        plants = {"plant_randomization": "mismatch"} if family == "mismatch" else {}
        acting = UR5TrackEnv(**{**policy.env, "task": "random", **plants, **v2,
                                **({"observe_measured": True} if v2 else {})})
        alone = UR5TrackEnv(task="random", **plants, **v2, **law)
        scenarios = []
        for i in range(2):
            rng = np.random.default_rng([best.VALIDATION_SEED, VALIDATION_STREAM, FAMILY_ID[family], i])
            scenarios.append(FamilyScenario(family, i, *draw_family(rng, family, alone.settings.model,
                                                                    alone.settings.dt), 0))
        mine = _env_costs(acting, scenarios, lambda obs: policy.act(obs[None])[0], monkeypatch,
                          start=lambda: policy.start(np.ones(1, dtype=bool)))
        reference = _env_costs(alone, scenarios, lambda obs: np.zeros(3), monkeypatch)
        keep = np.isfinite(reference)  # the scenarios the reference came to rest on
        assert keep.any(), family
        expected = mine[keep].mean() / reference[keep].mean() if np.all(np.isfinite(mine[keep])) else np.inf
        assert got[family] == pytest.approx(expected, rel=1e-9), family
