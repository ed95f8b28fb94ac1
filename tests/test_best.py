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
    monkeypatch.setattr(best, "score_baselines", lambda deployable, **_: {n: scores[n] for n in deployable})
    record = best.choose_best(tmp_path, names, scenarios=3, command="test")
    assert record["best"] == names[1]  # worst ratios 1.5, 1.2, inf
    written = json.loads((tmp_path / BEST_FILE).read_text())
    assert written["best"] == names[1] and written["scores"][names[2]]["nominal"] == "inf"
    assert best_name(tmp_path) == names[1]


def test_best_name_without_a_choice(tmp_path):
    with pytest.raises(InvalidInputError, match="baseline:best has not been chosen yet; run mjtraj rl best"):
        best_name(tmp_path)


def test_scores_are_ratios_to_cubic_pid_on_the_same_scenarios():
    """One baseline, two scenarios per family: each ratio is its mean J_exec over cubic+PID's, the two computed
    independently here through the evaluation path."""
    from mjtraj.envs import resolve

    from mjtraj.rl.adapters import load_any

    name = baseline_names()[0]
    got = best.score_baselines([name], scenarios=2)[name]
    policy = load_any(f"baseline:{name}")
    pid = resolve(task="random")
    for family in FAMILIES:
        draws = best.validation_scenarios(family, 2, pid.model, pid.dt)
        mine = best._costs(policy, policy.settings(), draws)
        ref = best._costs(None, pid, draws)
        expected = mine.mean() / ref.mean() if np.all(np.isfinite(mine)) else np.inf
        assert got[family] == expected
