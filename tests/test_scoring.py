"""Scoring: Bryson's rule, J_exec by hand, the per-step terms summing to J_exec, and the score's independence from a
planner's weights."""

from __future__ import annotations

import numpy as np
import pytest

from mjtraj.core.model import JointInfo
from mjtraj.core.scoring import JOINT_SPEED_LIMIT, Scoring, bryson_weights, executed_cost, step_cost
from mjtraj.core.task import Task
from mjtraj.exceptions import InvalidInputError


def test_weights_follow_brysons_rule(model, scenario):
    Q, R = bryson_weights(scenario.task, JointInfo.of(model).torque_limit)
    options = scenario.planner_options["optimal"]
    np.testing.assert_allclose(options["state_weight"], Q, rtol=1e-15)
    np.testing.assert_allclose(options["input_weight"], R, rtol=1e-15)
    np.testing.assert_array_equal(scenario.Q_exec, Q)
    np.testing.assert_array_equal(scenario.R_exec, R)


def test_brysons_rule_by_hand():
    task = Task.create([0.0, 0.0], [0.5, -2.0], 1.0, 0.1)
    q, r = bryson_weights(task, [60.0, 30.0])
    np.testing.assert_array_equal(q, [1 / 4, 1 / 4, 1 / np.pi**2, 1 / np.pi**2])
    np.testing.assert_array_equal(r, [1 / 3600, 1 / 900])
    still = Task.create([0.3, 0.3], [0.3, 0.3], 1.0, 0.1)  # no move: the position scale is 1 rad
    assert bryson_weights(still, [60.0, 60.0])[0][0] == 1.0
    assert JOINT_SPEED_LIMIT == np.pi


def test_executed_cost_by_hand_and_as_the_sum_of_its_steps(rng):
    e, ed, dtau = rng.normal(size=(3, 2, 5, 2))
    q, r = np.array([2.0, 3.0, 0.5, 0.25]), np.array([0.1, 0.2])
    by_hand = [sum(2 * e[b, k, 0] ** 2 + 3 * e[b, k, 1] ** 2 + 0.5 * ed[b, k, 0] ** 2 + 0.25 * ed[b, k, 1] ** 2
                   + 0.1 * dtau[b, k, 0] ** 2 + 0.2 * dtau[b, k, 1] ** 2 for k in range(5)) for b in range(2)]
    np.testing.assert_allclose(executed_cost(e, ed, dtau, q, r), by_hand, rtol=1e-14)
    tracking, effort = step_cost(e, ed, dtau, q, r)
    assert tracking.shape == effort.shape == (2, 5)
    np.testing.assert_allclose((tracking + effort).sum(axis=1), by_hand, rtol=1e-14)


def test_the_score_is_the_scenarios_not_the_planners(scenario):
    """Retuning the optimal planner's own weights leaves the scenario's score unchanged."""
    retuned = scenario.replace(planner_options={"optimal": {"state_weight": (0.0,) * 6}})
    np.testing.assert_array_equal(retuned.Q_exec, scenario.Q_exec)
    np.testing.assert_array_equal(retuned.R_exec, scenario.R_exec)
    assert Scoring().weights(scenario.task, scenario.torque_limit)[0].tolist() == scenario.Q_exec.tolist()


def test_scoring_arguments():
    assert Scoring().rule == "bryson" and Scoring.fixed([1] * 6, [1] * 3, 3).rule == "fixed"
    with pytest.raises(InvalidInputError, match=r"^Q_exec, R_exec: give both fixed weights, or neither"):
        Scoring(Q_exec=np.ones(6))
    with pytest.raises(InvalidInputError, match=r"^R_exec: expected finite weights >= 0 \(a diagonal\), got"):
        Scoring(np.ones(6), -np.ones(3))
    with pytest.raises(InvalidInputError, match=r"^Q_exec, R_exec: expected 4 and 2 weights for a task of 2 joints"):
        Scoring.fixed([1] * 6, [1] * 3, 3).weights(Task.create([0, 0], [1, 1], 1.0, 0.1), [60, 60])
