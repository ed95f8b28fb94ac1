"""The shipped scenario: its numbers follow their stated rules, and bad files are refused clearly."""

from __future__ import annotations

import pytest

from mjtraj.exceptions import InvalidInputError
from mjtraj.study.scenario import default_scenario_path, load_scenario


def write(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


def paper_text():
    return default_scenario_path().read_text()



def test_paper_settings(scenario):
    assert scenario.task.duration == 2.0 and scenario.task.dt == 0.02 and scenario.task.steps == 100
    assert scenario.loop.substeps == 1



def test_unknown_key(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^config: unknown key 'kq' in \[controller\]; valid: kp, ki, kd, "
                                                r"feedforward, ff_accel, gravity_comp, anti_windup, substeps$"):
        load_scenario(write(tmp_path, paper_text().replace("kp = ", "kq = ")))



def test_unknown_section_and_planner(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^config: unknown planner \[planners.spline\]; valid: cubic, "
                                                r"optimal, quintic, scurve, trapezoidal$"):
        load_scenario(write(tmp_path, paper_text() + "\n[planners.spline]\norder = 3\n"))
    with pytest.raises(InvalidInputError, match=r"^config: unknown key 'extra'; valid: name, model, task, "
                                                r"controller, planners, cost, tuning$"):
        load_scenario(write(tmp_path, "extra = 1\n" + paper_text()))



def test_missing_file_and_bad_toml(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^config: scenario file not found: .*missing\.toml \(shipped "):
        load_scenario(tmp_path / "missing.toml")
    with pytest.raises(InvalidInputError, match=r"^config: .* is not valid TOML: "):
        load_scenario(write(tmp_path, "name = \n"))



def test_bad_task_values(tmp_path, scenario):
    with pytest.raises(InvalidInputError, match=r"^duration: expected a whole number of control periods dt=0.02 s, "
                                                r"got 2.01 s \(100.5 periods\)$"):
        scenario.replace(task={"duration": 2.01})
    with pytest.raises(InvalidInputError, match=r"^q0: expected 3 values, got shape \(2,\)$"):
        scenario.replace(task={"q0": [0.0, 0.0]})
    with pytest.raises(InvalidInputError, match=r"^qg: expected finite values, got \[0.0, nan, 0.0\]$"):
        scenario.replace(task={"qg": [0.0, float("nan"), 0.0]})
    with pytest.raises(InvalidInputError, match=r"^duration: expected a positive number, got -1.0$"):
        scenario.replace(task={"duration": -1.0})



def test_joint_range(model, scenario):
    from mjtraj.core.task import Task

    with pytest.raises(InvalidInputError, match=r"^qg: joint 'elbow_joint' = 3.5 rad is outside its range "
                                                r"\[-3.14159, 3.14159\]$"):
        Task.create(scenario.task.q0, [0.0, 0.0, 3.5], 2.0, 0.02, model=model)

