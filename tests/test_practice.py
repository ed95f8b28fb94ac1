"""What a practitioner reads (mjtraj.rl.practice): the execution table and the ranking under a second weighting,
against hand-made rows with known answers."""

from __future__ import annotations

import pytest

from mjtraj.rl.practice import TRACKING_SHARE, execution_summary, execution_table, tracking_heavy, weighting_agreement


def row(method, status="ok", family="nominal", **values):
    base = {"cost_position": 0.0, "cost_velocity": 0.0, "cost_torque": 1.0, "rms_err": 0.0, "max_err": 0.0,
            "end_err": 0.0, "end_speed": 0.0, "settle_time": 0.0, "peak_dtau": 1.0}
    base.update(values)
    base["cost"] = base["cost_position"] + base["cost_velocity"] + base["cost_torque"]
    return {"method": method, "status": status, "family": family, **base}


def test_the_summary_counts_successes_and_averages_what_ran():
    rows = [row("a", end_speed=0.1), row("a", "not_settled", end_speed=0.3), row("a", "diverged")]
    rows[2].update({k: float("nan") for k in ("cost", "end_speed")})
    s = execution_summary(rows)
    assert s["success"] == pytest.approx(1 / 3)
    assert s["end_speed"] == pytest.approx(0.2)  # the diverged row has no metrics
    assert s["cost"] == 1.0


def test_seeds_of_a_configuration_pool_into_one_line():
    rows = [row("ppo [s1]", cost_torque=1.0), row("ppo [s2]", cost_torque=3.0), row("cubic+PID", cost_torque=5.0)]
    text, record = execution_table(rows, {"ppo": ["ppo [s1]", "ppo [s2]"]}, ["nominal"])
    assert record["nominal"]["ppo"]["cost"] == 2.0 and record["nominal"]["cubic+PID"]["cost"] == 5.0
    assert text.count("\n| nominal |") == 2


def test_the_tracking_heavy_weighting_scales_the_position_part_alone():
    r = row("a", cost_position=2.0, cost_velocity=3.0, cost_torque=5.0)
    assert tracking_heavy(r) == 2.0 / TRACKING_SHARE**2 + 8.0


def test_kendalls_tau_reads_a_reversal_and_an_agreement():
    """Method a saves torque and tracks badly, c tracks well: under J_settle a < b < c, under the tracking-heavy
    weighting c < b < a, tau -1; on the other family the orders agree, tau 1. Both are means over the scenarios on
    which every method ran: a diverged row leaves its scenario out, a row not at rest keeps it."""
    def two(method, family="nominal", status=("ok", "ok"), **values):
        return [dict(row(method, s, family, **values), scenario=k) for k, s in enumerate(status)]

    rows = [*two("a", cost_position=1e-4, cost_torque=1.0), *two("b", cost_position=2e-5, cost_torque=1.1),
            *two("c", cost_position=1e-6, cost_torque=1.2, status=("ok", "not_settled"))]
    rows += [*two("a", "aggressive", cost_position=1e-6, cost_torque=1.0),
             *two("b", "aggressive", cost_position=2e-6, cost_torque=2.0),
             *two("c", "aggressive", ("ok", "diverged"), cost_position=3e-6, cost_torque=3.0)]
    rows[-1].update(cost=float("nan"), cost_torque=float("nan"), cost_position=float("nan"))
    (a1,) = [r for r in rows if (r["method"], r["family"], r["scenario"]) == ("a", "aggressive", 1)]
    a1.update(cost_torque=100.0, cost=100.0)  # left out with c's divergence on that scenario
    text, record = weighting_agreement(rows, {}, ["nominal", "aggressive"])
    nominal = record["nominal"]
    assert nominal["scenarios"] == 2 and record["aggressive"]["scenarios"] == 1
    assert nominal["by_score"] == ["a", "b", "c"] and nominal["by_tracking_heavy"] == ["c", "b", "a"]
    assert nominal["kendall_tau"] == pytest.approx(-1.0)
    assert record["aggressive"]["kendall_tau"] == pytest.approx(1.0)
    assert record["aggressive"]["score"]["a"] == pytest.approx(1.0 + 1e-6)
    assert "| nominal | 2 | a < b < c | c < b < a | -1.00 |" in text
