"""The benchmark protocol: any policy scored beside the planners and control laws, its statistics and their
failure rule (oracles: the classical rows bit for bit, rliable's own metric, closed forms, invariants)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
import torch
from rliable import metrics

from mjtraj.cli import main
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.adapters import BENCHMARK_ENV, load_any
from mjtraj.rl.evaluate import evaluate
from mjtraj.rl.protocol_stats import improvement, probability_of_improvement, ratio_of_means, summarize
from mjtraj.study import draw_scenario, load_scenario, no_perturbation
from mjtraj.study.store import read_rows
from mjtraj.study.tuning import GAIN_PARAMETERS, objective, points, training_stream, tune_gains


def zero(obs):
    """A single-observation policy: no residual."""
    assert obs.shape == (19,)
    return np.zeros(3)


def costs(rows, method, family="nominal"):
    return [r["cost"] for r in rows if r["method"] == method and r["family"] == family]


@pytest.mark.slow
@pytest.mark.parametrize("protocol", ["v1", "v2"])
def test_a_zero_residual_is_the_controller_alone_bit_for_bit_under_each_law(tmp_path, protocol):
    """A user's callable (one observation), a torch module and a computed-torque callable that add nothing score
    exactly as cubic+PID and cubic+CT, scenario by scenario, with the same statuses (v2's settle window included)."""

    class ZeroModule(torch.nn.Module):
        def forward(self, x):
            return torch.zeros(x.shape[0], 3)

    class ZeroCT:
        env = {"controller": "computed_torque"}
        name = "zero on CT"

        def __call__(self, obs):
            return np.zeros(3)

    report = evaluate([zero, ZeroModule(), ZeroCT()], families=("nominal", "aggressive"), scenarios=4, seed=3,
                      reps=20, out=tmp_path, protocol=protocol)
    rows = read_rows(report.csv)
    for family in ("nominal", "aggressive"):
        pid, ct = costs(rows, "cubic+PID", family), costs(rows, "cubic+CT", family)
        assert len(pid) == 4 and pid != ct  # computed torque ran because a policy acts on it
        assert costs(rows, "zero", family) == pid
        assert costs(rows, "ZeroModule", family) == pid
        assert costs(rows, "zero on CT", family) == ct
        statuses = {m: [r["status"] for r in rows if r["method"] == m and r["family"] == family]
                    for m in ("cubic+PID", "zero", "cubic+CT", "zero on CT")}
        assert statuses["zero"] == statuses["cubic+PID"] and statuses["zero on CT"] == statuses["cubic+CT"]
    if protocol == "v2":  # the settle window ran: the episode's score is above the motion's J_exec
        assert all(float(r["cost"]) > float(r["cost_motion"]) for r in rows if r["status"] in ("ok", "not_settled"))
        assert report.reference == "cubic+adaptive CT"
        return
    kinds = {r["method"]: (r["policy_kind"], json.loads(r["policy_env"])["controller"]) for r in rows if r["policy"]}
    assert kinds == {"zero": ("callable", "pid"), "ZeroModule": ("torch", "pid"),
                     "zero on CT": ("callable", "computed_torque")}
    s = report.summaries["nominal"]["zero"]
    assert (s.ratio_of_means.value, s.iqm.value, s.probability_of_improvement.value, s.failures) == (1.0, 0.0, 0.5, 0)


@pytest.mark.slow
def test_a_recurrent_policy_is_told_when_its_episodes_start(tmp_path):
    """Oracle: the phase in the observation is 0 exactly at the first call after each reset, on every batch (the
    aggressive family's episodes come in batches of one length each); after the executions, the compute table times
    it on one episode of the family (one more reset, of one episode)."""

    class Counting:
        batched = True

        def __init__(self):
            self.k, self.calls, self.resets = 0, [], []

        def reset(self, starts):
            self.resets.append(starts.copy())
            self.k = 0

        def __call__(self, obs):
            self.calls.append((self.k, obs[:, 18].copy()))
            self.k += 1
            return np.zeros((len(obs), 3))

    policy = Counting()
    evaluate([policy], families=("aggressive",), scenarios=5, seed=1, reps=20, out=tmp_path)
    assert len(policy.resets) >= 3 and all(r.all() for r in policy.resets)
    assert sum(len(r) for r in policy.resets[:-1]) == 5 and len(policy.resets[-1]) == 1
    for k, phase in policy.calls:
        assert (phase == 0).all() if k == 0 else (phase > 0).all()


@pytest.mark.slow
def test_a_privileged_policy_receives_each_scenarios_plant(tmp_path):
    class Privileged:
        batched = True
        privileged = True

        def __init__(self):
            self.seen = []

        def __call__(self, obs, plants):
            if obs[0, 18] == 0:
                self.seen += plants
            return np.zeros((len(obs), 3))

    policy = Privileged()
    evaluate([policy], families=("mismatch", "nominal"), scenarios=3, seed=2, reps=20, out=tmp_path)
    model = load_scenario().model
    expected = [draw_scenario("mismatch", 2, i, model, 0.02).perturbation.as_dict() for i in range(3)]
    assert policy.seen == expected + [no_perturbation(3).as_dict()] * 3


@pytest.mark.slow
def test_the_cli_scores_a_users_file_beside_the_classical_methods(tmp_path, capsys, monkeypatch):
    (tmp_path / "mine.py").write_text("import numpy as np\n\ndef policy(obs):\n    return np.full(3, 0.1)\n")
    tuned = tmp_path / "gains.toml"
    assert main(["tune", "--gains", "--family", "mismatch", "--scenarios", "3", "--budget", "2", "--out",
                 str(tuned)]) == 0
    out = tmp_path / "eval"
    code = main(["rl", "eval", "--policy", f"{tmp_path / 'mine.py'}:policy", "--policy-env", "residual_scale=2",
                 "--family", "nominal,mismatch", "--scenarios", "3", "--controllers", "pid,computed_torque",
                 "--tuned-gains", str(tuned), "--reps", "20", "--out", str(out), "--no-progress", "--protocol", "v1"])
    assert code == 0, capsys.readouterr().err
    text = capsys.readouterr().out
    for method in ("cubic+PID", "cubic+CT", "cubic+PID (tuned gains)", "mine.py:policy"):
        assert f"| {method} | 1 |" in text
    rows = read_rows(out / "eval.csv")
    assert {json.loads(r["policy_env"])["residual_scale"] for r in rows if r["policy"]} == {2}
    summary = (out / "SUMMARY.md").read_text()
    assert summary.startswith("# Benchmark summary (OFF-PROTOCOL)\n\n**Off-protocol**: families nominal,mismatch (v1: "
                              "nominal,aggressive,mismatch); scenarios 3 (v1: 200); reps 20 (v1: 2000). ")
    assert "\nRegenerate: `mjtraj rl eval --policy " in summary
    assert "By payload on the mismatch family" in summary and (out / "profiles.png").stat().st_size > 10_000
    assert (out / "intervals.png").stat().st_size > 10_000
    record = json.loads((out / "summary.json").read_text())
    assert record["controllers"] == ["pid", "computed_torque"] and record["reference"] == "cubic+PID"


def test_policies_that_cannot_be_loaded_are_refused_with_the_reason(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^policy: cannot import module 'no_such_module'"):
        load_any("no_such_module:policy")
    with pytest.raises(InvalidInputError, match=r"^policy: module 'json' has no attribute 'nothing'$"):
        load_any("json:nothing")
    with pytest.raises(InvalidInputError, match=r"^policy: no baseline 'nope'; shipped: "):
        load_any("baseline:nope")
    with pytest.raises(InvalidInputError, match=r"^policy: unknown env setting 'gain'; valid: planner, controller"):
        load_any(zero, settings={"gain": 2})
    with pytest.raises(InvalidInputError, match=r"^policy: expected a callable"):
        load_any(3)
    assert load_any(zero).env == BENCHMARK_ENV


def test_improvement_and_ratio_follow_their_closed_forms_and_the_failure_rule():
    cost = np.array([[1.0, 4.0, np.nan, np.nan, 2.0]])
    ref = np.array([2.0, 2.0, 2.0, np.nan, np.nan])
    np.testing.assert_array_equal(improvement(cost, ref), [[0.5, -1.0, -np.inf, 0.0, 1.0]])
    assert ratio_of_means(cost[:, :2], np.array([[2.0, 2.0]]))[0] == 5.0 / 4.0
    assert ratio_of_means(cost, ref[None, :])[0] == np.inf


def test_our_probability_of_improvement_is_rliables():
    rng = np.random.default_rng(4)
    for runs in (1, 3, 5):
        x = rng.integers(0, 4, size=(runs, 30)).astype(float)  # ties on purpose
        y = rng.integers(0, 4, size=(1, 30)).astype(float)
        assert probability_of_improvement(x, y)[0] == pytest.approx(metrics.probability_of_improvement(x, y),
                                                                    abs=1e-12)


def test_turning_episodes_into_failures_never_improves_a_summary():
    rng = np.random.default_rng(11)
    for trial in range(6):
        cost = rng.gamma(2.0, 1.0, size=(3, 40))
        ref = rng.gamma(2.0, 1.0, size=40)
        before = summarize(cost, ref, reps=50, seed=trial)
        failed = cost.copy()
        failed[rng.random(cost.shape) < 0.1 + 0.05 * trial] = np.nan
        after = summarize(failed, ref, reps=50, seed=trial)
        assert after.failures > before.failures == 0
        assert after.ratio_of_means.value >= before.ratio_of_means.value
        assert after.iqm.value <= before.iqm.value
        assert after.probability_of_improvement.value <= before.probability_of_improvement.value
        assert after.wins <= before.wins


def test_same_seed_same_intervals():
    rng = np.random.default_rng(2)
    cost, ref = rng.gamma(2.0, 1.0, size=(2, 25)), rng.gamma(2.0, 1.0, size=25)
    state = np.random.get_state()[1].copy()  # noqa: NPY002 - the global generator rliable uses
    assert summarize(cost, ref, reps=50) == summarize(cost, ref, reps=50)
    np.testing.assert_array_equal(np.random.get_state()[1], state)  # noqa: NPY002 - left as it was


def test_tuned_gains_are_the_best_of_their_trials():
    """Oracle: every trial re-scored by the tuning objective; the file's gains are the best trial's factors."""
    base = load_scenario()
    tuned, tuning = tune_gains(base, family="mismatch", scenarios=3, budget=4, seed=1)
    draws = [draw_scenario("mismatch", 1, i, base.model, 0.02, stream=training_stream("mismatch")) for i in range(3)]
    from mjtraj.core.planners import make
    from mjtraj.core.scoring import Scoring

    assert [t.parameters for t in tuning.trials] == points(GAIN_PARAMETERS, 4, 1)
    best = min(tuning.trials, key=lambda t: t.objective)
    assert best is tuning.best
    factors = best.parameters
    np.testing.assert_array_equal(tuned.loop.gains.kp, base.loop.gains.kp * factors["kp_scale"])
    np.testing.assert_array_equal(tuned.loop.gains.kd, base.loop.gains.kd * factors["kd_scale"])
    assert objective(tuned, make("cubic"), draws, Scoring(), "mismatch")[0] == best.objective
    with pytest.raises(InvalidInputError, match=r"^gains: expected a scenario whose control law has free "
                       r"parameters \(pid, adaptive_computed_torque\), got 'computed_torque'$"):
        tune_gains(load_scenario("paper_computed_torque"))



@pytest.mark.slow
def test_a_shipped_baseline_rescores_to_the_summarys_rows(tmp_path):
    """Anyone re-scoring a shipped baseline under protocol v1 gets the benchmark's own rows
    (docs/results/benchmark/eval.csv): the same statuses, and costs within 1e-6 relative. The policy's float32 torch
    kernels differ in their last bits across x86-64 CPUs, and the mismatched plants' dry friction amplifies that: on an
    AVX-512 Xeon every one of the 200 policy costs differed from the rows (written on another machine, with the same
    libraries and the code before or after this test's change alike), by at most 1.5e-9 relative. On the machine that
    wrote them they agree bit for bit. The reference's float64 rows are checked first."""
    from pathlib import Path

    shipped = read_rows(Path(__file__).resolve().parent.parent / "docs" / "results" / "benchmark" / "eval.csv")
    name = "ppo_batched_s1"  # a torch policy, whose float32 kernels the docstring speaks of
    mine = [r for r in shipped if r["policy"] == f"baseline:{name}" and r["family"] == "mismatch"]
    assert len(mine) == 200
    report = evaluate([f"baseline:{name}"], families=("mismatch",), scenarios=200, seed=1, reps=10,
                      out=tmp_path, protocol="v1")
    rows = read_rows(report.csv)
    for method, want in (("cubic+PID", [r for r in shipped if r["method"] == "cubic+PID"
                                        and r["family"] == "mismatch"]), (None, mine)):
        got = [r for r in rows if (r["method"] == method if method else r["policy"] == f"baseline:{name}")]
        assert [r["status"] for r in got] == [r["status"] for r in want]
        assert [float(r["cost"]) for r in got] == pytest.approx([float(r["cost"]) for r in want], rel=1e-6,
                                                                 nan_ok=True)


def test_a_run_off_the_published_protocol_says_so(tmp_path):
    """The default is protocol v2 and each protocol's own settings depart from nothing; any other family, count, seed
    or resample count is named in summary.json's protocol and in SUMMARY.md's title and first lines."""
    import inspect

    from mjtraj.rl.protocol import PROTOCOL_V1, PROTOCOL_V2, departures

    defaults = {k: v.default for k, v in inspect.signature(evaluate).parameters.items()}
    assert defaults["protocol"] == "v2" and defaults["families"] is None and defaults["reps"] is None
    assert departures(*PROTOCOL_V1.values()) == [] and departures(*PROTOCOL_V2.values(), protocol="v2") == []
    assert departures(*PROTOCOL_V1.values(), protocol="v2") == [
        "families nominal,aggressive,mismatch (v2: nominal,aggressive,mismatch,noisy)"]
    evaluate([], families=("nominal",), scenarios=2, seed=3, reps=20, out=tmp_path, protocol="v1")
    protocol = json.loads((tmp_path / "summary.json").read_text())["protocol"]
    assert protocol == ("off-protocol: families nominal (v1: nominal,aggressive,mismatch); scenarios 2 (v1: 200); "
                        "seed 3 (v1: 1); reps 20 (v1: 2000)")
    summary = (tmp_path / "SUMMARY.md").read_text().splitlines()
    assert summary[0] == "# Benchmark summary (OFF-PROTOCOL)"
    assert summary[2].startswith("**Off-protocol**: families nominal (v1: nominal,aggressive,mismatch); ")


def test_a_summary_and_its_rows_record_the_provenance_of_their_numbers(tmp_path):
    """summary.json's versions, SUMMARY.md's header and every row of eval.csv carry the full provenance (versions of
    every numeric library, BLAS, CPU, commit), each field what its own source says."""
    from oracles import assert_provenance

    evaluate([], families=("nominal",), scenarios=2, seed=3, reps=20, out=tmp_path, protocol="v1")
    versions = json.loads((tmp_path / "summary.json").read_text())["versions"]
    assert_provenance(versions)
    assert versions["python"] == ".".join(map(str, sys.version_info[:3]))
    for row in read_rows(tmp_path / "eval.csv"):
        assert_provenance(row)
    header = (tmp_path / "SUMMARY.md").read_text().split("\n\n")[:5]
    (line,) = [p for p in header if p.startswith("Computed with ")]
    assert "\n" not in line and line.startswith(f"Computed with mjtraj {versions['mjtraj']}, mujoco ")
    for name in ("numpy", "scipy", "osqp", "daqp", "numba", "pin", "torch"):
        assert f" {name} {versions[name]}," in line
    for name in ("blas", "cpu"):
        assert f" {name.upper()} {versions[name]!r}," in line
    assert (f" commit {versions['commit']}," if versions["commit"] else " no git commit,") in line


def test_every_method_keeps_one_colour_and_policies_never_share_one():
    """Classical methods take their law's fixed colour in every run; policies get distinct colours, the same for
    the same list of methods."""
    from mjtraj.rl.protocol_stats import LAW_COLORS, method_colors

    policies = [f"cubic+PID+residual SAC seed {k}" for k in range(20)]
    methods = ["cubic+PID", "cubic+CT", "cubic+adaptive CT", "cubic+MPC", "cubic+PID (tuned gains)", *policies]
    colors = method_colors(methods)
    assert colors["cubic+PID"] == LAW_COLORS["PID"] and colors["cubic+MPC"] == LAW_COLORS["MPC"]
    assert method_colors(["cubic+CT"])["cubic+CT"] == colors["cubic+CT"]  # whatever else the run holds
    assert len({colors[m] for m in methods}) == len(methods)
    assert method_colors(methods) == colors


def test_figures_are_written_in_every_format_asked_for(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mjtraj.exceptions import InvalidInputError
    from mjtraj.study import save_figure

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    paths = save_figure(fig, tmp_path / "f.png", ("png", "svg", "pdf"))
    assert [p.name for p in paths] == ["f.png", "f.svg", "f.pdf"]
    assert paths[1].read_text().lstrip().startswith("<?xml") and paths[2].read_bytes().startswith(b"%PDF")
    with pytest.raises(InvalidInputError, match=r"^figure_format: unknown value 'jpg'"):
        save_figure(fig, tmp_path / "g.png", ("jpg",))
    plt.close(fig)


def test_a_policys_fingerprint_covers_its_file_its_weights_and_the_files_it_declares(tmp_path):
    """A class instance from FILE.py:ATTR records its file's sha256 (it recorded '' before); a torch module's
    fingerprint changes with any weight; a declared weights file is covered, and one that is missing is refused."""
    import hashlib

    import torch

    from mjtraj.rl.adapters import fingerprint, from_object

    source = tmp_path / "mine.py"
    source.write_text("import numpy as np\n\nclass Damped:\n    files = ['w.npy']\n\n    def __call__(self, obs):\n"
                      "        return np.zeros(3)\n\npolicy = Damped()\n")
    np.save(tmp_path / "w.npy", np.zeros(3))
    first = load_any(f"{source}:policy").sha256
    assert len(first) == 64
    np.save(tmp_path / "w.npy", np.ones(3))
    assert load_any(f"{source}:policy").sha256 not in (first, "")
    (tmp_path / "w.npy").unlink()
    with pytest.raises(InvalidInputError, match=r"^policy: its files attribute names 'w.npy', which is not a file"):
        load_any(f"{source}:policy")
    plain = tmp_path / "plain.py"
    plain.write_text("def policy(obs):\n    return obs[:3] * 0\n")
    assert load_any(f"{plain}:policy").sha256 == hashlib.sha256(plain.read_bytes()).hexdigest()

    net = torch.nn.Linear(19, 3)
    before = from_object(net).sha256
    with torch.no_grad():
        net.weight[0, 0] += 1e-6
    assert fingerprint(net) != before and len(before) == 64


@pytest.mark.slow
def test_every_method_is_paired_against_the_named_one_and_an_unknown_name_is_refused(tmp_path):
    """Oracles: the ratio is the ratio of the two methods' mean J_exec in eval.csv; a method against itself is
    1 [1, 1], better with probability one half."""
    import pandas as pd

    report = evaluate([], families=("nominal",), scenarios=4, seed=3, reps=20, controllers=("pid", "computed_torque"),
                      out=tmp_path, versus="cubic+CT", protocol="v1")
    record = json.loads(report.summary_json.read_text())["versus"]
    assert record["method"] == "cubic+CT"
    rows = pd.read_csv(report.csv)
    mean = rows.groupby("method")["cost"].mean()
    pid = record["nominal"]["cubic+PID"]
    assert pid["ratio"]["value"] == pytest.approx(mean["cubic+PID"] / mean["cubic+CT"], rel=1e-12)
    assert pid["ratio"]["low"] <= pid["ratio"]["value"] <= pid["ratio"]["high"]
    itself = record["nominal"]["cubic+CT"]
    assert (itself["ratio"]["value"], itself["ratio"]["low"], itself["ratio"]["high"]) == (1.0, 1.0, 1.0)
    assert itself["beats"]["value"] == 0.5
    assert "Paired against cubic+CT" in report.markdown.read_text()
    with pytest.raises(InvalidInputError, match=r"^versus: expected a method of this evaluation, one of "
                                                r"cubic\+PID, cubic\+CT; got 'cubic\+MPC'$"):
        evaluate([], families=("nominal",), scenarios=2, seed=3, reps=20, controllers=("pid", "computed_torque"),
                 out=tmp_path / "b", versus="cubic+MPC", protocol="v1")
    assert not (tmp_path / "b" / "eval.csv").exists()  # refused before anything ran
    several = evaluate([], families=("nominal",), scenarios=4, seed=3, reps=20,
                       controllers=("pid", "computed_torque"), out=tmp_path / "c", versus=("cubic+CT", "cubic+PID"),
                       protocol="v1")
    pairs = json.loads(several.summary_json.read_text())["versus"]
    assert [p["method"] for p in pairs] == ["cubic+CT", "cubic+PID"]
    assert pairs[0]["nominal"] == record["nominal"]  # the same pairing as asked alone, and the other beside it
    assert pairs[1]["nominal"]["cubic+CT"]["ratio"]["value"] == pytest.approx(
        mean["cubic+CT"] / mean["cubic+PID"], rel=1e-12)
    assert "Paired against cubic+CT, cubic+PID on the same scenarios (a table each)" in several.markdown.read_text()


@pytest.mark.slow
def test_protocol_v2_scores_the_window_and_its_noisy_family_is_the_sweeps_own(tmp_path):
    """v2's rows are the sweep's under a 0.5 s window (the noisy family: the mismatch scenarios measured with 1 mrad
    of noise), bit for bit; the summary names the protocol, its score and reference, and carries the execution
    table and the rankings under both weightings."""
    from mjtraj.study.sweep import SweepSettings, run_unit

    report = evaluate([], families=("mismatch", "noisy"), scenarios=2, seed=3, reps=20, out=tmp_path)
    rows = read_rows(report.csv)
    for family, noise in (("mismatch", 0.0), ("noisy", 1e-3)):
        sweep = run_unit(SweepSettings(families=("mismatch",), scenarios=2, seed=3, planners=("cubic",),
                                       settle=0.5, sensor_noise=noise), ("mismatch", 0)).rows
        mine = [r for r in rows if r["family"] == family and r["method"] == "cubic+PID"]
        assert [float(r["cost"]) for r in mine] == [r["cost"] for r in sweep]
        assert [r["status"] for r in mine] == [r["status"] for r in sweep]
    assert costs(rows, "cubic+PID", "mismatch") != costs(rows, "cubic+PID", "noisy")
    record = json.loads(report.summary_json.read_text())
    assert (record["reference"], record["score"], record["settle"], record["noisy_sigma"]) == (
        "cubic+adaptive CT", "J_settle", 0.5, 1e-3)
    assert record["protocol"].startswith("off-protocol: families mismatch,noisy (v2: ")
    assert set(record["executions"]) == {"mismatch", "noisy"} and "kendall_tau" in record["weightings"]["noisy"]
    summary = report.markdown.read_text()
    assert "What the executions did" in summary and "| noisy | cubic+adaptive CT |" in summary
    assert "Kendall's tau" in summary


def _wrong_signature(obs, extra):
    return np.zeros(3)


def _wrong_shape(obs):
    return np.zeros(2)


def _nan_action(obs):
    return np.full(3, np.nan)


def _raises(obs):
    return np.zeros(3)[obs.size]  # an IndexError, as a bug in a user's policy would raise


@pytest.mark.slow
@pytest.mark.parametrize("policy, message", [
    (_wrong_signature, r"^policy _wrong_signature: on observation 0 \(shape \(19,\)\) it raised TypeError: "
                       r"_wrong_signature\(\) missing 1 required positional argument: 'extra'$"),
    (_wrong_shape, r"^policy _wrong_shape: on observation 0 \(shape \(19,\)\) it returned actions of shape \(2,\); "
                   r"expected \(3,\) per observation$"),
    (_nan_action, r"^policy _nan_action: on observation 0 it returned the action \[nan, nan, nan\]; expected finite "
                  r"values \(values outside \[-1, 1\] are clipped\)$"),
    (_raises, r"^policy _raises: on observation 0 \(shape \(19,\)\) it raised IndexError: index 19 is out of bounds "
              r"for axis 0 with size 3$"),
])
def test_a_broken_policy_stops_the_evaluation_with_its_error(tmp_path, capsys, policy, message):
    """Four bugs a user's policy can have are errors, not scores: one line naming the policy, what it did and the
    observation; the command exits 2. With --keep-going the rows record it and SUMMARY.md counts it."""
    from mjtraj.exceptions import PolicyError

    with pytest.raises(PolicyError, match=message):
        evaluate([policy], families=("nominal",), scenarios=2, seed=3, reps=10, out=tmp_path / "a")
    report = evaluate([policy], families=("nominal",), scenarios=2, seed=3, reps=10, out=tmp_path / "b",
                      keep_going=True)
    rows = [r for r in read_rows(report.csv) if r["policy"]]
    assert {r["status"] for r in rows} == {"error"}
    summary = report.markdown.read_text()
    assert "Rows whose evaluation raised (status error), by reason:\n\n- 2 x PolicyError: policy " in summary


class _RaisesOnItsSixthCall:
    """A callable policy that raises on the sixth observation it is given (index 5, the second of its batch)."""

    def __init__(self):
        self.calls = 0

    def __call__(self, obs):
        self.calls += 1
        if self.calls == 6:
            raise RuntimeError("boom on the sixth call")
        return np.zeros(3)


def test_a_callable_that_raises_is_named_on_the_observation_it_failed_on(tmp_path):
    """A callable policy is called once per observation, so its error names that observation's index (not the first
    of the batch it came in)."""
    from mjtraj.exceptions import PolicyError

    with pytest.raises(PolicyError, match=r"^policy .*: on observation 5 \(shape \(19,\)\) it raised RuntimeError: "
                                          r"boom on the sixth call$"):
        evaluate([_RaisesOnItsSixthCall()], families=("nominal",), scenarios=2, seed=3, reps=10, out=tmp_path)


@pytest.mark.slow
def test_the_cli_says_a_broken_policy_in_one_line(tmp_path, capsys):
    (tmp_path / "mine.py").write_text("import numpy as np\n\ndef policy(obs):\n    return np.zeros(4)\n")
    code = main(["rl", "eval", "--policy", f"{tmp_path / 'mine.py'}:policy", "--family", "nominal", "--scenarios",
                 "2", "--reps", "10", "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("mjtraj: error: policy ") and "it returned actions of shape (4,); expected (3,)" in err
    # --keep-going: the rows record it, the terminal says why they failed, and the policy, which ran no episode, is
    # not ranked
    code = main(["rl", "eval", "--policy", f"{tmp_path / 'mine.py'}:policy", "--family", "nominal", "--scenarios",
                 "2", "--reps", "10", "--out", str(tmp_path / "kept"), "--no-progress", "--keep-going"])
    out = capsys.readouterr().out
    assert code == 0
    assert "Rows whose evaluation raised (status error), by reason:\n\n- 2 x PolicyError: policy " in out
    ranking = next(line for line in out.splitlines() if line.startswith("| nominal | ") and " < " in line)
    assert "mine.py:policy" not in ranking and "cubic+PID" in ranking
    assert "Not ranked, no episode of theirs ran (every row an error): mine.py:policy (nominal)." in out


@pytest.mark.slow
def test_a_plain_sb3_zip_scores_once_its_env_is_named(tmp_path, capsys):
    """A PPO trained with plain stable-baselines3 on `benchmark_vec_env` and saved by `model.save`: refused without
    --policy-env by a message that holds the command that scores it (the user's own, every option kept); that command
    scores it, on v2's observation."""
    from stable_baselines3 import PPO

    from mjtraj.rl.sb3_env import benchmark_vec_env

    model = PPO("MlpPolicy", benchmark_vec_env(2), n_steps=32, batch_size=32, seed=0, device="cpu")
    model.learn(64)
    model.save(tmp_path / "plain.zip")
    args = ["rl", "eval", "--policy", str(tmp_path / "plain.zip"), "--family", "nominal", "--scenarios", "2",
            "--reps", "10", "--out", str(tmp_path / "out"), "--no-progress"]
    assert main(args) == 2
    err = capsys.readouterr().err
    command = err.split("e.g. ")[1].strip()  # the user's own command, with the env it lacks
    assert command == " ".join(["mjtraj", *args, "--policy-env", "observe_task=true", "--policy-env",
                                "observe_measured=true"])
    assert main(command.split()[1:]) == 0
    rows = read_rows(tmp_path / "out" / "eval.csv")
    assert {r["method"] for r in rows if r["policy"]} == {"plain.zip (PPO)"}


def test_a_zip_of_another_algorithm_is_refused_by_name(tmp_path):
    """A plain SB3 zip's algorithm is read from its policy class's module; one mjtraj cannot act with is refused
    naming it and the supported algorithms."""
    import zipfile

    from mjtraj.rl.adapters import sb3_algorithm

    def saved(module):
        path = tmp_path / f"{module}.zip"
        with zipfile.ZipFile(path, "w") as archive:
            archive.writestr("data", json.dumps({"policy_class": {"__module__": module}}))
        return path

    assert sb3_algorithm(saved("stable_baselines3.common.policies")) == "ppo"
    assert sb3_algorithm(saved("stable_baselines3.sac.policies")) == "sac"
    with pytest.raises(InvalidInputError, match=r"holds a policy of sb3_contrib.tqc.policies; expected one of SAC, "
                                                r"PPO, TD3, RecurrentPPO \(stable-baselines3 or sb3-contrib\)$"):
        sb3_algorithm(saved("sb3_contrib.tqc.policies"))


@pytest.mark.slow
def test_every_summary_gives_each_methods_per_period_compute(tmp_path):
    """summary.json's compute: every law timed on each period of its own execution of each family's first scenario
    (the oracle for the count: those episodes' periods, motion and window), every policy on its inference calls;
    SUMMARY.md shows the table."""
    from mjtraj.core.settle import SETTLE_WINDOW, window_steps
    from mjtraj.domain.families import draw_scenario
    from mjtraj.rl.compute import POLICY_CALLS
    from mjtraj.study import load_scenario

    def policy(obs):
        return np.zeros(3)

    report = evaluate([policy], families=("nominal", "aggressive"), scenarios=2, reps=20,
                      controllers=("pid", "mpc"), out=tmp_path)
    compute = json.loads(report.summary_json.read_text())["compute"]
    base = load_scenario()
    window = window_steps(SETTLE_WINDOW, base.task.dt)
    periods = sum(draw_scenario(family, 1, 0, base.model, base.task.dt).task.steps + window
                  for family in ("nominal", "aggressive"))
    for law in ("cubic+PID", "cubic+MPC", "cubic+adaptive CT"):
        assert compute[law]["samples"] == periods, law
        assert 0 < compute[law]["median_ms"] <= compute[law]["p99_ms"]
    mine = [v for k, v in compute.items() if k not in ("cubic+PID", "cubic+MPC", "cubic+adaptive CT")]
    assert len(mine) == 1 and mine[0]["samples"] == POLICY_CALLS and mine[0]["what"] == "inference, batch 1"
    assert "| method | what is timed | median ms | p99 ms | periods or calls |" in report.markdown.read_text()
