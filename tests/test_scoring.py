"""Scoring: Bryson's rule, J_exec by hand, and the env's per-step terms summing to J_exec."""


from __future__ import annotations

import numpy as np

from mjtraj.core.model import JointInfo
from mjtraj.core.planners.optimal import bryson_weights
from mjtraj.study.scenario import default_scenario_path


def write(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


def paper_text():
    return default_scenario_path().read_text()



def test_weights_follow_brysons_rule(model, scenario):
    Q, R = bryson_weights(scenario.task, JointInfo.of(model).torque_limit)
    options = scenario.planner_options["optimal"]
    np.testing.assert_allclose(options["state_weight"], Q, rtol=1e-15)
    np.testing.assert_allclose(options["input_weight"], R, rtol=1e-15)
    np.testing.assert_array_equal(scenario.Q_exec, Q)
    np.testing.assert_array_equal(scenario.R_exec, R)

