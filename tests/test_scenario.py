"""The shipped scenario: its numbers follow their stated rules, and bad files are refused clearly."""

from __future__ import annotations

import numpy as np
import pytest

from mjtraj.domain.scenario import default_scenario_path, load_scenario
from mjtraj.exceptions import InvalidInputError


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
                                                r"controller, feedforward, ff_accel, gravity_comp, anti_windup, "
                                                r"adaptation_rate, substeps$"):
        load_scenario(write(tmp_path, paper_text().replace("kp = ", "kq = ")))



def test_unknown_section_and_planner(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^config: unknown planner \[planners.spline\]; valid: cubic, "
                                                r"optimal, nonlinear_optimal, nonlinear_min_effort, quintic, scurve, "
                                                r"trapezoidal$"):
        load_scenario(write(tmp_path, paper_text() + "\n[planners.spline]\norder = 3\n"))
    with pytest.raises(InvalidInputError, match=r"^config: unknown key 'extra'; valid: name, model, torque_limit, "
                                                r"task, controller, planners, cost, tuning$"):
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
                                                r"\[-3.141592653589793, 3.141592653589793\]$"):
        Task.create(scenario.task.q0, [0.0, 0.0, 3.5], 2.0, 0.02, model=model)
    # the message shows every digit: a limit just outside is not printed as equal to the range
    with pytest.raises(InvalidInputError, match=r"= -3.1415926535897936 rad is outside its range "
                                                r"\[-3.141592653589793,"):
        Task.create(scenario.task.q0, [0.0, 0.0, np.nextafter(-np.pi, -4)], 2.0, 0.02, model=model)



@pytest.mark.parametrize(("edit", "message"), [
    (lambda t: t.replace('name = "paper"', 'name = "../escaped"'),
     r"^config: name: expected a name of letters, digits, '_', '-' and '.' \(not a path\), got '\.\./escaped'$"),
    (lambda t: t.replace('name = "paper"', 'name = "/abs/path"'), r"^config: name: expected a name"),
    (lambda t: t + "\n[planners]\ncubic = 5\n", r"^config: \[planners.cubic\] must be a table of options, got 5$"),
    (lambda t: t.replace("q0 = [0.0, -1.5707963267948966, 0.0]", "q0 = true"),
     r"^config: q0 in \[task\]: expected a list of numbers, got True$"),
    (lambda t: t.replace("qg = [1.0, -0.5707963267948966, 1.0]", "qg = 1.0"),
     r"^config: qg in \[task\]: expected a list of numbers, got 1.0$"),
    (lambda t: t.replace("duration = 2.0", "duration = true"),
     r"^config: duration in \[task\]: expected a number, got True$"),
    (lambda t: t.replace('linearization = "midpoint"', 'linearization = "midpoint"\ntorque_bound = -1'),
     r"^torque_bound: expected positive values, got -1$"),
])
def test_malformed_files_name_the_key(tmp_path, edit, message):
    with pytest.raises(InvalidInputError, match=message):
        load_scenario(write(tmp_path, edit(paper_text())))


def test_a_binary_file_is_not_a_scenario(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\xff")
    with pytest.raises(InvalidInputError, match=r"^config: .*s\.toml is not a text file \(not UTF-8 at byte 0\)$"):
        load_scenario(path)


def test_shipped_scenarios_load_by_name():
    from mjtraj.domain.scenario import shipped_scenarios

    assert shipped_scenarios() == ("paper", "paper_adaptive", "paper_computed_torque", "paper_oracle", "paper_tuned")
    assert load_scenario("paper_tuned").tuning["mode"] == "held out"
    assert load_scenario("paper_oracle").name == "paper_oracle"
