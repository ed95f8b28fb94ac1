"""The shipped scenario: its numbers follow their stated rules, and bad files are refused clearly."""

from __future__ import annotations

import numpy as np
import pytest

from mjtraj.exceptions import InvalidInputError
from mjtraj.gains import gain_rule, spectral_radius_along
from mjtraj.model import JointInfo
from mjtraj.planners import available, make
from mjtraj.planners.optimal import bryson_weights
from mjtraj.scenario import default_scenario_path, load_scenario


def test_paper_settings(scenario):
    assert scenario.task.duration == 2.0 and scenario.task.dt == 0.02 and scenario.task.steps == 100
    assert scenario.loop.substeps == 1


def test_gains_follow_the_rule(model, scenario):
    rule = gain_rule(model, scenario.task.q0, scenario.task.qg, scenario.task.dt)
    for name in ("kp", "ki", "kd"):
        np.testing.assert_allclose(getattr(scenario.loop.gains, name), getattr(rule, name), rtol=1e-12)


def test_weights_follow_brysons_rule(model, scenario):
    Q, R = bryson_weights(scenario.task, JointInfo.of(model).torque_limit)
    options = scenario.planner_options["optimal"]
    np.testing.assert_allclose(options["state_weight"], Q, rtol=1e-15)
    np.testing.assert_allclose(options["input_weight"], R, rtol=1e-15)
    np.testing.assert_array_equal(scenario.Q_exec, Q)
    np.testing.assert_array_equal(scenario.R_exec, R)


def test_default_gains_are_stable_along_every_reference(model, scenario):
    refs = [scenario.planner(name).plan(scenario.task, model) for name in available()]
    assert spectral_radius_along(model, scenario.loop.gains, refs, moving=False) < 1.0
    assert spectral_radius_along(model, scenario.loop.gains, refs, moving=True) < 1.0


def test_naive_diagonal_gains_are_unstable(model, scenario):
    """ur5_params.md's pitfall, reproduced: kp = D_ii(q_bar) w^2 at the same bandwidth is unstable at 0.02 s."""
    from mjtraj.controller import PIDGains
    from mjtraj.gains import mass_matrix

    w = 2 * np.pi / (20 * 0.02)
    inertia = np.diag(mass_matrix(model, (scenario.task.q0 + scenario.task.qg) / 2))
    naive = PIDGains.create(inertia * w**2, inertia * w**3 / 10, 2 * inertia * w, 3)
    refs = [make("cubic").plan(scenario.task, model)]
    assert spectral_radius_along(model, naive, refs, moving=False) > 1.5


def write(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


def paper_text():
    return default_scenario_path().read_text()


def test_unknown_key(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^config: unknown key 'kq' in \[controller\]; valid: kp, ki, kd, "
                                                r"feedforward, ff_accel, gravity_comp, anti_windup, substeps$"):
        load_scenario(write(tmp_path, paper_text().replace("kp = ", "kq = ")))


def test_unknown_section_and_planner(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^config: unknown planner \[planners.spline\]; valid: cubic, "
                                                r"optimal, quintic, trapezoidal$"):
        load_scenario(write(tmp_path, paper_text() + "\n[planners.spline]\norder = 3\n"))
    with pytest.raises(InvalidInputError, match=r"^config: unknown key 'extra'; valid: name, task, controller, "
                                                r"planners, cost$"):
        load_scenario(write(tmp_path, "extra = 1\n" + paper_text()))


def test_missing_file_and_bad_toml(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^config: scenario file not found: .*missing\.toml$"):
        load_scenario(tmp_path / "missing.toml")
    with pytest.raises(InvalidInputError, match=r"^config: .* is not valid TOML: "):
        load_scenario(write(tmp_path, "name = \n"))


def test_bad_task_values(tmp_path, scenario):
    with pytest.raises(InvalidInputError, match=r"^duration: expected a whole number of control periods dt=0.02 s, "
                                                r"got 2.01 s \(100.5 periods\)$"):
        scenario.replace(task_changes={"duration": 2.01})
    with pytest.raises(InvalidInputError, match=r"^q0: expected 3 values, got shape \(2,\)$"):
        scenario.replace(task_changes={"q0": [0.0, 0.0]})
    with pytest.raises(InvalidInputError, match=r"^qg: expected finite values, got \[0.0, nan, 0.0\]$"):
        scenario.replace(task_changes={"qg": [0.0, float("nan"), 0.0]})
    with pytest.raises(InvalidInputError, match=r"^duration: expected a positive number, got -1.0$"):
        scenario.replace(task_changes={"duration": -1.0})


def test_joint_range(model, scenario):
    from mjtraj.task import Task

    with pytest.raises(InvalidInputError, match=r"^qg: joint 'elbow_joint' = 3.5 rad is outside its range "
                                                r"\[-3.14159, 3.14159\]$"):
        Task.create(scenario.task.q0, [0.0, 0.0, 3.5], 2.0, 0.02, model=model)
