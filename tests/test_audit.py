"""The audit's verdict rules on synthetic sweep rows whose answers are known: holds, does not hold, inconclusive,
depends. Inverting a rule fails here."""

from __future__ import annotations

import numpy as np
import pytest

from mjtraj.core.metrics import METRIC_NAMES
from mjtraj.exceptions import InvalidInputError
from mjtraj.study.audit import SweepData, below, write_audit
from mjtraj.study.rows import EXTRA_METRICS
from mjtraj.study.store import VERSION_COLUMNS, csv_text

PLANNERS = ("optimal", "cubic", "quintic", "trapezoidal")


def synthetic(path, costs, *, scenarios=40, families=("nominal",), config="paper.toml (shipped)", planners=PLANNERS):
    """A sweep file whose J_exec of a planner in scenario i is costs[family][planner] * d_i, d_i a random scenario
    difficulty shared by the planners (paired, as real scenarios are); every other metric equals the cost."""
    rng = np.random.default_rng(0)
    rows = []
    for family in families:
        for i in range(scenarios):
            difficulty = rng.uniform(0.5, 1.5)
            for planner in planners:
                value = costs[family][planner] * difficulty
                row = {"family": family, "scenario": i, "unit": 0, "planner": planner, "ff_accel": "sample",
                       "gravity_comp": "native", "status": "ok", "reason": "",
                       **{m: value for m in METRIC_NAMES}, **{m: value for m in EXTRA_METRICS},
                       "max_displacement": 1.2, "duration": 2.0, **{v: "x" for v in VERSION_COLUMNS}, "sweep_seed": 0,
                       "config": config}
                rows.append(row)
    columns = list(rows[0])
    path.write_text(csv_text(columns, rows))
    return path


def verdicts(text):
    table = text.split("## Verdicts", 1)[1].split("\n\nVerdict rule")[0]
    return {line.split("|")[1].strip(): line.split("|")[3].strip() for line in table.strip().splitlines()[2:]}


def test_a_clear_win_holds_a_clear_loss_does_not(tmp_path):
    """The optimal planner at half the classical cost: claims 1-3 hold; at twice it: they do not."""
    win = {"nominal": {"optimal": 1.0, "cubic": 2.0, "quintic": 2.0, "trapezoidal": 3.0}}
    loss = {"nominal": {"optimal": 4.0, "cubic": 2.0, "quintic": 2.5, "trapezoidal": 3.0}}
    good = verdicts(write_audit([synthetic(tmp_path / "w.csv", win)], tmp_path / "w.md", figures=False))
    bad = verdicts(write_audit([synthetic(tmp_path / "l.csv", loss)], tmp_path / "l.md", figures=False))
    assert [good[k] for k in "123"] == ["holds"] * 3
    assert [bad[k] for k in "123"] == ["does not hold"] * 3
    assert good["4"] == "holds" and bad["4"] == "does not hold"  # trapezoidal is worst; then optimal is
    # quintic > cubic holds; a tie holds in no condition, which the stated rule reports as "does not hold"
    assert good["5"] == "does not hold" and bad["5"] == "holds"


def test_equal_planners_are_inconclusive_in_their_condition(tmp_path):
    """Per condition, a tie is inconclusive (the overall column then reads 'does not hold', as the stated rule says:
    it holds in no condition)."""
    same = {"nominal": dict.fromkeys(PLANNERS, 2.0)}
    text = write_audit([synthetic(tmp_path / "s.csv", same)], tmp_path / "s.md", figures=False)
    for claim in "123":
        detail = text.split(f"## Claim {claim}:", 1)[1].split("## ", 1)[0]
        assert detail.count("| nominal, ff_accel=sample, gravity_comp=native |") == 1
        assert detail.rstrip().splitlines()[-1].rsplit("|", 2)[1].strip().startswith("inconclusive")


def test_a_claim_true_in_one_family_only_depends(tmp_path):
    costs = {"nominal": {"optimal": 1.0, "cubic": 2.0, "quintic": 2.0, "trapezoidal": 3.0},
             "mismatch": {"optimal": 4.0, "cubic": 2.0, "quintic": 2.0, "trapezoidal": 3.0}}
    path = synthetic(tmp_path / "d.csv", costs, families=("nominal", "mismatch"))
    result = verdicts(write_audit([path], tmp_path / "d.md", figures=False))
    assert result["3"] == "depends: holds only in nominal (every controller variant)"


@pytest.mark.parametrize(("ratio", "expected"), [(2.0, "yes"), (0.5, "no"), (1.0, "inconclusive")])
def test_below_reads_the_interval(tmp_path, ratio, expected):
    """'A below B' is yes when the whole 95 % interval of mean(B)/mean(A) lies above 1, no when below 1."""
    costs = {"nominal": {"optimal": 1.0, "cubic": ratio, "quintic": 1.0, "trapezoidal": 1.0}}
    data = SweepData([synthetic(tmp_path / "b.csv", costs)])
    verdict, r = below(data, data.conditions[0], "optimal", "cubic", "cost")
    assert verdict == expected and r.ratio == pytest.approx(ratio, rel=0.01)


def test_the_papers_columns_with_their_arithmetic(tmp_path):
    costs = {"nominal": {"optimal": 1.0, "cubic": 2.0, "quintic": 2.0, "trapezoidal": 3.0}}
    text = write_audit([synthetic(tmp_path / "w.csv", costs)], tmp_path / "w.md", figures=False)
    section = text.split("## The paper's columns and our definitions", 1)[1].split("\n## ", 1)[0]
    assert "Int.: 100 (6.329 - 4.535) / 6.329 = 28.35 %; RMS: 28.00 %" in section
    assert "100 (0.0003622 - 0.0002825) / 0.0003622 = 22.0 %; as an increase over optimal: 28.2 %" in section
    assert "The paper's Table I gives 0.35 to 0.42" in section
    # the synthetic rows have int_dtau = rms_dtau = rms_dtau_norm = cost and T = 2: the ratios are 1/6
    assert "| nominal, ff_accel=sample, gravity_comp=native | cubic | 0.167 | 0.167 |" in section


def test_several_weight_sets_side_by_side(tmp_path):
    """A Bryson-weighted sweep and a tuned one: one verdict column each, never mixed."""
    bryson = {"nominal": {"optimal": 4.0, "cubic": 2.0, "quintic": 2.5, "trapezoidal": 3.0}}
    tuned = {"nominal": {"optimal": 1.0, "cubic": 2.0, "quintic": 2.5, "trapezoidal": 3.0}}
    paths = [synthetic(tmp_path / "b.csv", bryson), synthetic(tmp_path / "t.csv", tuned, config="paper_tuned")]
    text = write_audit(paths, tmp_path / "a.md", figures=False)
    table = text.split("## Verdicts", 1)[1].split("\n\nVerdict rule")[0].strip().splitlines()
    assert table[0] == "| # | claim (paper) | Bryson weights (paper.toml) | paper_tuned |"
    claim3 = next(line for line in table if line.startswith("| 3 |"))
    assert claim3.endswith("| does not hold | holds |")


def test_too_few_scenarios_get_no_verdict(tmp_path):
    costs = {"nominal": {"optimal": 1.0, "cubic": 2.0, "quintic": 2.0, "trapezoidal": 3.0}}
    text = write_audit([synthetic(tmp_path / "one.csv", costs, scenarios=1)], tmp_path / "one.md", figures=False)
    assert verdicts(text)["3"] == "no verdict (fewer than 10 paired scenarios)"


def test_conclusions_and_where_it_pays_read_the_rows(tmp_path):
    win = {"nominal": {"optimal": 1.0, "cubic": 2.0, "quintic": 2.0, "trapezoidal": 3.0}}
    text = write_audit([synthetic(tmp_path / "w.csv", win)], tmp_path / "w.md", figures=False)
    conclusions = text.split("## Conclusions", 1)[1].split("\n## ", 1)[0]
    assert ("- these weights, nominal motions (40 scenarios): J_exec lower than the cubic's, ratio 0.500 [0.500, "
            "0.500], won in 100 % of them; RMS tracking error ratio 0.500 [0.500, 0.500].") in conclusions
    pays = text.split("## Where control-aware planning pays", 1)[1].split("\n## ", 1)[0]
    assert ("| nominal, ff_accel=sample, gravity_comp=native | max abs(dq) in (1, 1.5] rad | 40 | "
            "2.000 [2.000, 2.000] | 100 % |") in pays


def test_effort_left_on_the_table_is_each_planners_effort_over_the_nonlinear_bound(tmp_path):
    """Every metric is the cost here, so each cell is the ratio of the planners' factors to the bound's."""
    costs = {"nominal": {"optimal": 3.0, "cubic": 2.0, "quintic": 2.5, "trapezoidal": 2.2, "nonlinear_min_effort": 1.0}}
    path = synthetic(tmp_path / "b.csv", costs, planners=(*PLANNERS, "nonlinear_min_effort"))
    text = write_audit([path], tmp_path / "b.md", figures=False)
    section = text.split("## Effort left on the table", 1)[1].split("\n## ", 1)[0]
    assert "nominal, ff_accel=sample, gravity_comp=native (40 scenarios with a bound):" in section
    assert "| cubic | quintic | trapezoidal | optimal |" in section
    assert ("| 2.000 [2.000, 2.000] | 2.500 [2.500, 2.500] | 2.200 [2.200, 2.200] | 3.000 [3.000, 3.000] |"
            in section)
    without = write_audit([synthetic(tmp_path / "w.csv", {"nominal": costs["nominal"]})], tmp_path / "w.md",
                          figures=False)
    assert "(not measured: add `nonlinear_min_effort` to the sweep's planners" in without


@pytest.mark.slow
def test_truncated_and_unfinished_sweeps_are_refused(tmp_path):
    from mjtraj.cli import main
    from mjtraj.study.runner import run_sweep
    from mjtraj.study.sweep import SweepSettings

    whole = tmp_path / "whole.csv"
    run_sweep(SweepSettings(scenarios=6, batch=3, planners=("optimal", "cubic")), whole, workers=1, progress=False)
    lines = whole.read_text().splitlines(keepends=True)
    torn = tmp_path / "torn.csv"
    torn.write_text("".join(lines[:-1]) + lines[-1][:40])  # a row cut early
    with pytest.raises(InvalidInputError, match=r"^sweep: .*torn\.csv ends inside a row \(a torn write\)"):
        write_audit([torn], tmp_path / "a.md", figures=False)
    torn.write_text("".join(lines[:-1]) + lines[-1][:40] + "\n")  # the same, with a line end
    with pytest.raises(InvalidInputError, match=r"^sweep: .*torn\.csv line 13 has fewer cells than the header"):
        write_audit([torn], tmp_path / "a.md", figures=False)
    unfinished = tmp_path / "unfinished.csv"
    unfinished.write_text("".join(lines[:1 + 6]))  # the first unit only
    with pytest.raises(InvalidInputError, match=r"^sweep: .*unfinished\.csv is incomplete: 6 of 12 rows; finish it "
                                                r"with the same mjtraj sweep command and --resume, or pass --partial"):
        write_audit([unfinished], tmp_path / "a.md", figures=False)
    cut_mid_unit = tmp_path / "mid.csv"
    cut_mid_unit.write_text("".join(lines[:1 + 8]))  # a unit and a part of the next
    with pytest.raises(InvalidInputError, match=r"is incomplete: 6 of its 8 rows are in complete units"):
        write_audit([cut_mid_unit], tmp_path / "a.md", figures=False)
    text = write_audit([cut_mid_unit], tmp_path / "a.md", figures=False, partial=True)
    assert "Partial audit: " in text and "2 rows of incomplete units left out" in text
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\xff\xfe\x00\x01binary")
    assert main(["audit", str(binary), "--out", str(tmp_path / "b.md")]) == 2


def test_a_claim_holding_on_the_paper_task_only_depends_on_it(tmp_path):
    """One motion is compared directly: 1 % better there holds (no interval needed), while a loss on 40 random
    scenarios does not; inverting the task's numbers inverts its verdict."""
    loss = {"nominal": {"optimal": 4.0, "cubic": 2.0, "quintic": 2.5, "trapezoidal": 3.0}}
    for optimal, expected in ((0.99, "depends: holds only in paper task (every controller variant)"),
                              (1.01, "does not hold")):
        task = {"paper task": {"optimal": optimal, "cubic": 1.0, "quintic": 1.0, "trapezoidal": 1.0}}
        paths = [synthetic(tmp_path / "n.csv", loss), synthetic(tmp_path / "t.csv", task, scenarios=1,
                                                               families=("paper task",))]
        text = write_audit(paths, tmp_path / "a.md", figures=False)
        assert verdicts(text)["3"] == expected
        assert "| paper task, ff_accel=sample, gravity_comp=native | cubic: " + (
            "+1.0 % (one motion)" if optimal < 1 else "-1.0 % (one motion)") in text


@pytest.mark.slow
def test_progress_names_each_stage_as_it_begins(tmp_path):
    costs = {"nominal": {"optimal": 1.0, "cubic": 2.0, "quintic": 3.0, "trapezoidal": 3.0}}
    stages: list[str] = []
    write_audit([synthetic(tmp_path / "p.csv", costs)], tmp_path / "p.md", progress=stages.append, tasks=False)
    assert stages == ["reading p.csv", "the claims", "the figures"]


def test_missed_goals_are_counted_as_failures_and_leave_the_verdicts(tmp_path):
    """A planner whose every mismatch row missed its goal: the summary counts them, its comparisons have no pairs
    (said so, never '+nan %'), and the other family's verdicts are unchanged."""
    costs = {f: {"optimal": 1.0, "cubic": 2.0, "quintic": 2.0, "trapezoidal": 3.0} for f in ("nominal", "mismatch")}
    path = synthetic(tmp_path / "m.csv", costs, families=("nominal", "mismatch"))
    rows = path.read_text().splitlines()
    header = rows[0].split(",")
    status = header.index("status")
    edited = [rows[0]]
    for line in rows[1:]:
        cells = line.split(",")
        if cells[0] == "mismatch" and cells[header.index("planner")] == "optimal":
            cells[status] = "missed_goal"
        edited.append(",".join(cells))
    path.write_text("\n".join(edited) + "\n")
    text = write_audit([path], tmp_path / "m.md", figures=False, tasks=False)
    assert "+nan" not in text and "- (no paired rows: no ok execution on one side)" in text
    summary = [line for line in text.splitlines() if line.startswith("| mismatch") and "| optimal |" in line]
    assert summary and all("| 0 | 40 | 40 |" in line for line in summary)
    claim = text.split("## Claim 1", 1)[1].split("## Claim 2")[0]
    mismatch = [line for line in claim.splitlines() if line.startswith("| mismatch")]
    assert mismatch and all("no paired rows" in line for line in mismatch), mismatch
    assert verdicts(text)["1"] == "holds"  # where pairs exist (nominal); mismatch gives no verdict
