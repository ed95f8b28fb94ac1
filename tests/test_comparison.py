"""compare: the pipeline's numbers, planners named once, the stability check computed once per scenario."""

from __future__ import annotations

import pytest

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.metrics import metrics
from mjtraj.exceptions import InvalidInputError
from mjtraj.study.comparison import compare


def test_metrics_are_the_loops(scenario, model):
    result = compare(scenario, ("cubic", "optimal"))
    refs = [result.references[name] for name in result.planners]
    rollout = ClosedLoop(model, scenario.loop, nsim=2).run(refs)
    expected = metrics(rollout, scenario.Q_exec, scenario.R_exec, model=model)
    assert [result.metrics[n] for n in result.planners] == expected
    assert result.reduction("cubic", "cost") == pytest.approx(
        100 * (expected[0].cost - expected[1].cost) / expected[0].cost, rel=1e-12)


def test_stability_is_computed_once_per_scenario(scenario):
    fresh = scenario.replace(name="fresh")
    first = compare(fresh, ("cubic",))
    key = ("stability", ("cubic",))
    assert fresh.memo[key] == first.stability
    fresh.memo[key] = {"at_rest": -1.0, "moving": -1.0}  # a second compare reads the memo
    assert compare(fresh, ("cubic",)).stability == {"at_rest": -1.0, "moving": -1.0}
    assert "stability" not in str(fresh.replace(name="other").memo)  # a replaced scenario starts afresh


@pytest.mark.parametrize(("planners", "message"), [
    ((), r"^planners: expected at least one planner, got none$"),
    (("cubic", "spline"), r"^planners: unknown planner 'spline'; valid: cubic, optimal, nonlinear_optimal, "
                          r"nonlinear_min_effort, quintic, scurve, trapezoidal$"),
    (("cubic", "cubic"), r"^planners: expected distinct planners, got cubic more than once$"),
])
def test_bad_planner_lists(scenario, planners, message):
    with pytest.raises(InvalidInputError, match=message):
        compare(scenario, planners)


def test_compare_says_which_planner_missed_its_goal_in_the_table_the_report_and_the_json(scenario):
    """Gains a hundred times too soft and no feedforward: the arm stays far short of the 1 rad move, and compare says
    so (it was silent)."""
    from mjtraj.core.controller import PIDGains
    from mjtraj.study.comparison import compare, comparison_record
    from mjtraj.study.report import format_report

    g = scenario.loop.gains
    soft = PIDGains.create(g.kp * 0.01, 0.0 * g.ki, g.kd * 0.01, 3)
    weak = scenario.replace(loop={"feedforward": "none", "gains": soft})
    result = compare(weak, ["cubic", "quintic"])
    record = comparison_record(result)
    assert {name: p["status"] for name, p in record["planners"].items()} == {"cubic": "missed_goal",
                                                                             "quintic": "missed_goal"}
    assert record["planners"]["cubic"]["reason"].startswith("terminal error ")
    text = format_report(result)
    assert "MISSED THE GOAL (2 of 2: terminal error above 0.2 x the move of 1 rad, a failure by the goal rule)" in text
    assert text.count("MISSED") == 3  # the line and both rows' Goal column
    assert result.metrics["cubic"].terminal_err > 0.2
