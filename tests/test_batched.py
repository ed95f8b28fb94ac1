"""Batched training (mjtraj.rl.batched): the untrained policy is the law alone, the exported policy acts as skrl's
mean action, a tiny run writes what it says and is scored by the protocol."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from mjtraj.cli import main
from mjtraj.rl.adapters import from_object, load_any
from mjtraj.rl.batched import MixedFamilies, _agent, export_policy, validation_sets
from mjtraj.rl.batched_policy import BatchedSettings
from mjtraj.rl.episodes import run_episodes

TINY = {"steps": 96, "num_envs": 6, "rollouts": 8, "evaluations": 2, "validation": 2, "seed": 3}


@pytest.mark.slow
def test_the_untrained_policy_is_the_law_alone(tmp_path):
    """Oracle: the law with no policy. The mean's last layer starts at zero, so on every family's validation tasks
    the exported policy scores exactly what the law scores alone."""
    settings = BatchedSettings(**TINY)
    env = MixedFamilies(settings)
    module = export_policy(_agent(settings, env, tmp_path), settings)
    obs = torch.as_tensor(np.random.default_rng(0).normal(size=(7, env.single_observation_space.shape[0])),
                          dtype=torch.float32)
    assert torch.equal(module(obs), torch.zeros(7, 3))
    policy = from_object(module)
    for _, s, refs, weights, plants, _ in validation_sets(settings):
        mine = [o.metrics["cost"] for o in run_episodes(policy, s, refs, weights, plants)]
        alone = [o.metrics["cost"] for o in run_episodes(None, s, refs, weights, plants)]
        assert mine == alone


def test_validation_draws_each_familys_episodes_by_its_rules():
    """The validation sets hold each family's episodes as the sweeps' rules draw them from the validation stream (the
    oracle: `draw_family` on the same generators): aggressive motions last 0.5 to 1 s, mismatch ones run on drawn
    plants, and with a settle window each reference is the planned motion then the window. (The aggressive family's
    validation once drew 2-second motions: the env's random-task rule, not the family's.)"""
    from mjtraj.domain.families import AGGRESSIVE_DURATION, draw_family
    from mjtraj.rl.streams import VALIDATION_STREAM

    settings = BatchedSettings(**{**TINY, "validation": 4}, settle=0.5)
    for k, (family, s, refs, _, plants, settles) in enumerate(validation_sets(settings)):
        drawn = [draw_family(np.random.default_rng([3, VALIDATION_STREAM, k * 4 + i]), family, s.model, s.dt)
                 for i in range(4)]
        window = round(0.5 / s.dt)
        for (task, _), ref, settle in zip(drawn, refs, settles, strict=True):
            assert settle.motion_steps == round(task.duration / s.dt) and settle.window_steps == window
            assert ref.steps == settle.motion_steps + window
            np.testing.assert_allclose(ref.q[0], task.q0, rtol=0, atol=1e-12)
            np.testing.assert_allclose(ref.q[-1], task.qg, rtol=0, atol=1e-12)
            if family == "aggressive":
                assert AGGRESSIVE_DURATION[0] <= task.duration <= AGGRESSIVE_DURATION[1]
        if family == "mismatch":
            assert [p.payload for p in plants] == [p.payload for _, p in drawn]
        else:
            assert plants is None and all(p is None for _, p in drawn)


@pytest.mark.slow
def test_a_tiny_run_writes_its_files_and_its_policy_acts_as_skrls_mean(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["rl", "train", "--algo", "ppo", "--batched", "--steps", "96", "--num-envs", "6", "--evaluations",
                 "2", "--validation", "2", "--hyperparameter", "rollouts=8", "--seed", "3", "--out", str(out),
                 "--no-progress"]) == 0
    assert "trained 96 steps" in capsys.readouterr().out
    record = json.loads((out / "run.json").read_text())
    assert record["settings"]["rollouts"] == 8 and record["timesteps"] == 96
    assert record["streams"]["train"]["gym_seeds"][0] == 3 + 16 * 2**32  # the training stream [3, 16, 0]
    rows = (out / "learning_curve.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].endswith("worst_ratio")
    (out / "learning_curve.png").unlink()  # the run draws its curve, and `rl plot` draws it again
    assert main(["rl", "plot", str(out)]) == 0 and (out / "learning_curve.png").stat().st_size > 0
    policy = load_any(str(out / "best.pt"))
    assert policy.label.startswith("cubic+adaptive CT+residual batched PPO (6 N m, nominal+aggressive+mismatch")
    assert policy.record["streams"] == record["streams"] and len(policy.sha256) == 64
    # the exported module is skrl's deterministic action: its observation standardiser, then the mean network
    from mjtraj.rl.batched_policy import load_batched

    module = load_batched(out / "policy.pt")
    obs = torch.as_tensor(np.random.default_rng(1).normal(size=(5, module.mean.numel())), dtype=torch.float32)
    expected = torch.clamp(module.net(torch.clamp((obs - module.mean) / (module.std + module.epsilon), -module.clip,
                                                  module.clip)), -1, 1)
    assert torch.equal(module(obs), expected) and float(module.clip) == 5.0


@pytest.mark.slow
def test_a_batched_policy_is_scored_by_the_protocol(tmp_path):
    from mjtraj.rl.evaluate import evaluate

    out = tmp_path / "run"
    assert main(["rl", "train", "--algo", "ppo", "--batched", "--steps", "96", "--num-envs", "6", "--evaluations",
                 "1", "--validation", "2", "--hyperparameter", "rollouts=8", "--out", str(out), "--no-progress"]) == 0
    report = evaluate([str(out / "best.pt")], families=("nominal",), scenarios=2, reps=10, out=tmp_path / "eval")
    (method,) = [m for m in report.summaries["nominal"] if "batched PPO" in m]
    assert report.summaries["nominal"][method].failures == 0


@pytest.mark.parametrize(("argv", "message"), [
    (["--algo", "sac", "--batched"], "batched: trains PPO (skrl's); got --algo sac"),
    (["--algo", "ppo", "--batched", "--hyperparameter", "gamma=0.9"],
     "hyperparameter: unknown name 'gamma' for --batched; valid: discount, epochs, gae_lambda, hidden, "
     "initial_std, learning_rate, minibatches, observe_control, preview, residual_scale, rollouts"),
    (["--algo", "ppo", "--batched", "--preview", "-1"], "preview: expected an integer >= 0, got -1"),
    (["--algo", "ppo", "--batched", "--observe-plant", "true"],
     "observe_plant: unknown value 'true'; valid: none, estimate"),
    (["--algo", "ppo", "--batched", "--history", "-2"], "history: expected an integer >= 0, got -2"),
    (["--algo", "ppo", "--batched", "--families", "nominal,extreme"],
     "families: unknown value 'extreme'; valid: nominal, aggressive, mismatch"),
    (["--algo", "ppo", "--batched", "--num-envs", "2"],
     "num_envs: expected at least one sub-env per family (3), got 2"),
    (["--algo", "ppo", "--batched", "--initial-std", "0"], "initial_std: expected a positive number, got 0.0"),
])
def test_bad_batched_settings_are_refused_in_one_line(argv, message, capsys, tmp_path):
    assert main(["rl", "train", *argv, "--out", str(tmp_path / "r"), "--no-progress"]) == 2
    assert capsys.readouterr().err == f"mjtraj: error: {message}\n"


@pytest.mark.slow
@pytest.mark.parametrize("extra", [{}, {"controller": "adaptive_computed_torque", "reward_baseline": "controller",
                                      "preview": 3, "observe_control": True, "measurement_noise": 1e-4}])
def test_aggressive_sub_envs_run_episodes_of_every_length_side_by_side(extra):
    """Oracle: UR5TrackEnv on the same seeds. Four sub-envs of the aggressive family in one vector env autoreset into
    episodes of other lengths at other times (the closed loop runs references of several lengths side by side):
    each sub-env's observations, rewards and episode costs are the single env's seeded s + i, bit for bit."""
    from mjtraj.envs import UR5TrackEnv, UR5TrackVectorEnv

    kwargs = {"action_mode": "residual", "task": "random", "family": "aggressive", **extra}
    vector = UR5TrackVectorEnv(4, autoreset_mode="SameStep", **kwargs)
    actions = np.random.default_rng(3).uniform(-0.2, 0.2, (130, 4, 3))
    first, _ = vector.reset(seed=11)
    observations, rewards, costs, lengths = [first], [], [[] for _ in range(4)], set()
    for a in actions:
        obs, reward, terminated, truncated, info = vector.step(a)
        observations.append(obs)
        rewards.append(reward)
        for i in np.flatnonzero(terminated | truncated):
            costs[i].append(info["metrics"]["cost"][i])
    assert len(set(vector.loop.ends.tolist())) > 1  # lengths differ across sub-envs at the end
    for i in range(4):
        single = UR5TrackEnv(**kwargs)
        obs, _ = single.reset(seed=11 + i)
        seen, got, ended, steps = [obs], [], [], 0
        for a in actions:
            obs, reward, terminated, truncated, info = single.step(a[i])
            got.append(reward)
            steps += 1
            if terminated or truncated:
                ended.append(info["metrics"]["cost"])
                lengths.add(steps)
                steps = 0
                obs, _ = single.reset()
            seen.append(obs)
        np.testing.assert_array_equal(np.array(observations)[:, i], np.array(seen))
        np.testing.assert_array_equal(np.array(rewards)[:, i], got)
        assert costs[i] == ended and len(ended) >= 2
    assert len(lengths) > 2


@pytest.mark.slow
def test_bench_train_reports_both_rates_and_their_ratio():
    from mjtraj.bench import TRAIN_MIXES, bench_train

    rows = bench_train(num_envs=6, iterations=1)
    assert [row["families"] for row in rows] == ["+".join(mix) for mix in TRAIN_MIXES]
    for row in rows:
        assert row["train_steps_per_s"] > 0 and row["env_steps_per_s"] > 0
        assert row["ratio"] == pytest.approx(row["train_steps_per_s"] / row["env_steps_per_s"], rel=1e-12)
        assert row["minutes_10M"] == pytest.approx(1e7 / row["train_steps_per_s"] / 60, rel=1e-12)


def test_a_file_that_is_not_a_batched_policy_is_refused(tmp_path):
    from mjtraj.exceptions import InvalidInputError

    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    with pytest.raises(InvalidInputError, match=r"^policy: .*other\.pt is not a policy saved by mjtraj rl train "
                                                r"--batched$"):
        load_any(str(other))


@pytest.mark.slow
def test_a_run_that_sees_the_preview_stops_on_patience_and_its_policy_observes_the_same(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["rl", "train", "--algo", "ppo", "--batched", "--steps", "192", "--num-envs", "6", "--evaluations",
                 "8", "--validation", "2", "--hyperparameter", "rollouts=4", "--preview", "3", "--observe-control",
                 "--patience", "1", "--out", str(out), "--no-progress"]) == 0
    record = json.loads((out / "run.json").read_text())
    rows = (out / "learning_curve.csv").read_text().splitlines()[1:]
    # patience 1: it stops at the first validation point that is not a new best (the second at the latest)
    assert record["stopped"].startswith("patience") and record["timesteps"] < 192 and len(rows) <= 2
    assert f"stopped at {record['timesteps']} steps: patience" in capsys.readouterr().out
    policy = load_any(str(out / "best.pt"))
    env_settings = policy.record["settings"]
    assert (env_settings["preview"], env_settings["observe_control"]) == (3, True)
    from mjtraj.envs import UR5TrackVectorEnv

    from mjtraj.rl.batched_policy import load_batched

    module = load_batched(out / "best.pt")
    env = UR5TrackVectorEnv(2, **{**module.env, "task": "random"})
    assert module.mean.numel() == env.single_observation_space.shape[0]  # the policy reads the env it was trained on
    env.close()


@pytest.mark.slow
def test_a_search_writes_its_trials_and_best_continues_its_study_and_trains_with_its_best(tmp_path, capsys):
    out = tmp_path / "search"
    argv = ["rl", "search", "--steps", "96", "--num-envs", "6", "--evaluations", "2", "--validation", "2",
            "--out", str(out), "--no-progress"]
    assert main([*argv, "--trials", "2"]) == 0
    first = json.loads((out / "best.json").read_text())
    import pandas as pd

    trials = pd.read_csv(out / "trials.csv")
    assert first["trials"] == 2 and first["best"]["value"] > 0
    assert first["budget"]["training_steps"] == trials["user_attrs_timesteps"].sum() >= 192  # rollouts round up
    assert first["budget"]["training_episodes"] == trials["user_attrs_episodes"].sum()
    # validation points x tasks x families
    assert first["budget"]["validation_episodes"] == trials["user_attrs_validation_points"].sum() * 2 * 3 > 0
    assert main([*argv, "--trials", "1"]) == 0  # the study continues from its SQLite file
    again = json.loads((out / "best.json").read_text())
    assert again["trials"] == 3 and len((out / "trials.csv").read_text().splitlines()) == 4
    run = tmp_path / "run"
    assert main(["rl", "train", "--algo", "ppo", "--batched", "--steps", "96", "--num-envs", "6", "--evaluations",
                 "1", "--validation", "2", "--hyperparameters", str(out / "best.json"), "--out", str(run),
                 "--no-progress"]) == 0
    settings = json.loads((run / "run.json").read_text())["settings"]
    best = again["best"]
    assert best["learner"] == "ppo" and best["policy"] == str(out / f"trial_{best['trial']}" / "best.pt")
    assert all(settings[name] == best[name] for name in best if name not in ("value", "trial", "learner", "policy"))


@pytest.mark.slow
def test_a_search_over_learners_distils_and_fine_tunes_within_its_budget(tmp_path, capsys):
    """--learners distill,both: each trial trains the learner it drew (a distillation's rounds filling the budget, or
    half of it then PPO started from its best round), records it, and its value is its best validation point's (the
    oracle: the trial's own learning curves, read back); best.json names the best trial's policy, which
    --hyperparameters refuses as not PPO's."""
    import csv

    import pandas as pd

    from mjtraj.rl.batched import selection_value

    out = tmp_path / "search"
    assert main(["rl", "search", "--learners", "distill,both", "--steps", "1600", "--num-envs", "4", "--validation",
                 "2", "--evaluations", "2", "--settle", "0.5", "--families", "nominal,mismatch", "--trials", "3",
                 "--out", str(out), "--no-progress"]) == 0
    # round_trip: pandas' default float parser may miss the last bit of the value written, and the oracle is exact
    trials = pd.read_csv(out / "trials.csv", float_precision="round_trip")
    assert set(trials["user_attrs_learner"]) == {"distill", "both"}
    for _, trial in trials.iterrows():
        folder = out / f"trial_{trial['number']}"
        stages = [folder] if trial["user_attrs_learner"] == "distill" else [folder / "distill", folder / "ppo"]
        points = [{k: float(v) for k, v in row.items()} for stage in stages
                  for row in csv.DictReader((stage / "learning_curve.csv").open())]
        assert trial["value"] == min(selection_value(p) for p in points)
        assert not (stages[0] / "resume.pt").exists()  # a distillation's data, removed once the trial is done
        assert trial["user_attrs_timesteps"] <= 1600 + 4 * 32  # PPO's rollouts round its half up
        if trial["user_attrs_learner"] == "distill":  # 1600 steps: two rounds of 200 steps on 4 sub-envs
            assert len(points) == 2 and trial["user_attrs_timesteps"] == 1600
        else:
            assert json.loads((folder / "ppo" / "run.json").read_text())["settings"]["init"] == str(
                folder / "distill" / "best.pt")
        if trial["params_distill_action_mode"] == "torque":
            assert pd.isna(trial["params_distill_residual_scale"])
    best = json.loads((out / "best.json").read_text())["best"]
    assert best["policy"].endswith("best.pt") and (tmp_path / best["policy"]).is_file()
    capsys.readouterr()
    assert main(["rl", "train", "--algo", "ppo", "--batched", "--hyperparameters", str(out / "best.json"), "--out",
                 str(tmp_path / "run"), "--no-progress"]) == 2
    assert "is not PPO's but" in capsys.readouterr().err


def _interrupt_at(call, monkeypatch):
    """Make the batched runs' `interact` raise KeyboardInterrupt at its `call`-th call; returns the real one."""
    from mjtraj.rl import batched

    real, calls = batched.interact, []

    def crash(*args, **kwargs):
        calls.append(1)
        if len(calls) == call:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(batched, "interact", crash)
    return real


@pytest.mark.slow
def test_an_interrupted_run_resumed_ends_as_the_uninterrupted_one_bit_for_bit(tmp_path, capsys, monkeypatch):
    """Oracle: the same run uninterrupted. Interrupted after its second validation point (of three), `rl train
    --resume` goes on from the resume point and writes the same policies and learning curve, bit for bit (but the
    wall-clock columns); the resume point is gone once the run completes, and resuming a complete run is refused."""
    from mjtraj.rl import batched

    settings = {**TINY, "steps": 144, "evaluations": 3}
    batched.train_batched(BatchedSettings(**settings), tmp_path / "whole", progress=False)
    assert not (tmp_path / "whole" / batched.RESUME_FILE).exists()
    real = _interrupt_at(18, monkeypatch)  # past the second validation point (after period 16)
    with pytest.raises(KeyboardInterrupt):
        batched.train_batched(BatchedSettings(**settings), tmp_path / "cut", progress=False, command="tiny")
    assert (tmp_path / "cut" / batched.RESUME_FILE).is_file() and not (tmp_path / "cut" / "run.json").exists()
    monkeypatch.setattr(batched, "interact", real)
    assert main(["rl", "train", "--resume", str(tmp_path / "cut"), "--no-progress"]) == 0
    assert "resumed" in capsys.readouterr().out
    for name in ("policy.pt", "best.pt"):
        a = torch.load(tmp_path / "whole" / name, weights_only=False)
        b = torch.load(tmp_path / "cut" / name, weights_only=False)
        for key, value in a["state"].items():
            assert torch.equal(value, b["state"][key]), (name, key)
    clock = ("wall_s", "steps_per_s")
    curves = [[{k: v for k, v in zip(rows[0].split(","), line.split(","), strict=True) if k not in clock}
               for line in rows[1:]] for rows in ((tmp_path / run / "learning_curve.csv").read_text().splitlines()
                                                  for run in ("whole", "cut"))]
    assert curves[0] == curves[1] and len(curves[0]) == 3
    record = json.loads((tmp_path / "cut" / "run.json").read_text())
    assert record["resumed"] == [{"timesteps": 96}] and record["command"] == "tiny"
    assert not (tmp_path / "cut" / batched.RESUME_FILE).exists()
    assert main(["rl", "train", "--batched", "--resume", str(tmp_path / "cut"), "--no-progress"]) == 2
    assert "holds no resume point of a batched run" in capsys.readouterr().err


@pytest.mark.parametrize(("flag", "value"), [("--trials", "0"), ("--steps", "-5")])
def test_a_search_refuses_a_bad_budget_in_one_line_and_writes_nothing(flag, value, tmp_path, capsys):
    out = tmp_path / "search"
    assert main(["rl", "search", flag, value, "--out", str(out), "--no-progress"]) == 2
    name = flag.removeprefix("--")
    assert capsys.readouterr().err == f"mjtraj: error: {name}: expected a whole number >= 1, got {value}\n"
    assert not out.exists()


def _distilled(tmp_path):
    """A tiny distillation's deployable policy file (a residual on PID imitating computed torque, preview 2)."""
    from mjtraj.rl.distill import DistillSettings, distill

    settings = DistillSettings(teacher="computed_torque", controller="pid", families=("nominal", "mismatch"),
                               num_envs=4, rounds=1, steps=20, epochs=2, hidden=(16, 16), preview=2,
                               residual_scale=6.0)
    return distill(settings, tmp_path / "distilled", progress=False).policy


@pytest.mark.slow
def test_a_run_started_from_a_distilled_policy_acts_as_it_before_training(tmp_path):
    """`init`: before any update the run's exported policy is the distilled one, bit for bit, on observations of
    every family (the oracle: the distilled module itself); the settings it must share are refused by name when they
    differ."""
    from mjtraj.exceptions import InvalidInputError
    from mjtraj.rl.batched import new_agent
    from mjtraj.rl.batched_policy import load_batched

    path = _distilled(tmp_path)
    shared = {"controller": "pid", "residual_scale": 6.0, "hidden": (16, 16), "preview": 2}
    settings = BatchedSettings(**{**TINY, **shared, "families": ("nominal", "mismatch"), "num_envs": 4,
                                  "settle": 0.5, "init": str(path)})
    env = MixedFamilies(settings)
    obs = torch.as_tensor(env.reset(), dtype=torch.float32)
    started = export_policy(new_agent(settings, env, tmp_path / "run"), settings)
    distilled = load_batched(path)
    assert torch.equal(started(obs), distilled(obs)) and started(obs).abs().max() > 0
    with pytest.raises(InvalidInputError, match=r"^init: .* was trained with other settings: hidden \(16, 16\) "
                                                r"\(this run: \(8,\)\)$"):
        new_agent(BatchedSettings(**{**TINY, **shared, "hidden": (8,), "families": ("nominal", "mismatch"),
                                     "num_envs": 4, "init": str(path)}), env, tmp_path / "other")


def test_with_a_settle_window_validation_scores_the_window_and_the_rest_rule():
    """`settle`: each validation reference ends with the window holding its task's goal, and the law alone's
    outcomes are scored over it (J_settle above the motion's J_exec) and held to the at-rest rule."""
    settings = BatchedSettings(**{**TINY, "families": ("nominal",), "num_envs": 2, "settle": 0.5})
    (_, s, refs, weights, plants, settles), = validation_sets(settings)
    assert s.settle_steps == 25 and settles is not None and plants is None
    for ref, settle in zip(refs, settles, strict=True):
        assert ref.info["settle_steps"] == 25 and ref.steps == settle.motion_steps + 25
        assert np.array_equal(ref.q[-1], settle.goal)
    outcomes = run_episodes(None, s, refs, weights, plants, settles)
    assert all(o.status == "ok" and o.metrics["cost"] > o.metrics["cost_motion"] > 0 for o in outcomes)
    assert all(o.metrics["end_speed"] < 0.05 for o in outcomes)


def test_protocol_v2s_validation_is_paired_with_the_law_alone():
    """`_paired` by hand: a failure where the law came to rest is a missed episode; episodes the law failed do not
    count; the ratio is that of the sums of J_settle over the episodes both came to rest on. Points rank by missed
    episodes first, then the worst ratio; a search's one number ranks them alike (each missed episode outweighs any
    ratio)."""
    from mjtraj.rl.batched import _paired, selection_key, selection_value
    from mjtraj.study import Outcome

    def rows(*cells):
        return [Outcome("ok", metrics={"cost": c}) if c is not None else Outcome("not_settled", "moving")
                for c in cells]

    assert _paired(rows(1.0, 2.0, None), rows(2.0, 2.0, None)) == (0, 3.0 / 4.0)
    assert _paired(rows(1.0, None, 5.0), rows(2.0, None, None)) == (0, 0.5)
    assert _paired(rows(1.0, None, None), rows(2.0, 3.0, 4.0)) == (2, 0.5)
    assert _paired(rows(None), rows(None)) == (0, 1.0)
    assert _paired(rows(None), rows(1.0)) == (1, 1.0)
    one_missed, none_missed = {"worst_ratio": 0.5, "missed": 1}, {"worst_ratio": 2.0, "missed": 0}
    assert sorted([one_missed, none_missed], key=selection_key) == [none_missed, one_missed]
    assert selection_key({"worst_ratio": 0.7, "missed": 0}) < selection_key(none_missed)
    assert selection_key({"worst_ratio": 0.9}) == (0.0, 0.9)  # protocol v1: no missed column
    assert selection_value(one_missed) == 0.5 + 1e6 and selection_value(none_missed) == 2.0
    points = [one_missed, none_missed, {"worst_ratio": 40.0, "missed": 0}, {"worst_ratio": 0.1, "missed": 3},
              {"worst_ratio": 0.3, "missed": 1}]
    assert sorted(points, key=selection_value) == sorted(points, key=selection_key)


@pytest.mark.slow
def test_a_run_started_from_a_policy_resumes_only_with_that_policy_file(tmp_path, monkeypatch):
    """An `init` run interrupted after a validation point records its init file's sha256; resumed with another file
    in its place it is refused by name (its scaler's clip and epsilon come from the file), with the same one it
    completes (on protocol v2's episodes, the window taken from the distilled policy by the command line)."""
    import shutil

    from mjtraj.exceptions import InvalidInputError
    from mjtraj.rl import batched

    path = _distilled(tmp_path)
    kept = tmp_path / "kept.pt"
    shutil.copy(path, kept)
    argv = ["rl", "train", "--algo", "ppo", "--batched", "--init", str(kept), "--steps", "96", "--num-envs", "4",
            "--families", "nominal,mismatch", "--evaluations", "2", "--validation", "2", "--hyperparameter",
            "rollouts=8", "--seed", "3", "--out", str(tmp_path / "run"), "--no-progress"]
    real = _interrupt_at(20, monkeypatch)  # past the first validation point (after period 16)
    assert main(argv) == 130  # the command line's answer to an interrupt
    monkeypatch.setattr(batched, "interact", real)
    saved = torch.load(tmp_path / "run" / batched.RESUME_FILE, weights_only=False)["progress"]["record"]
    assert saved["settings"]["settle"] == 0.5 and saved["init_sha256"] == batched.file_sha256(kept)
    shutil.copy(_distilled(tmp_path / "other"), kept)  # another policy of the same settings in its place
    with pytest.raises(InvalidInputError, match=r"^init: .*kept.pt is not the policy file the run started from"):
        batched.resume_batched(tmp_path / "run", progress=False)
    shutil.copy(path, kept)
    report = batched.resume_batched(tmp_path / "run", progress=False)
    assert report.score == "J_settle" and "missed" in report.best_point
    header = (tmp_path / "run" / "learning_curve.csv").read_text().splitlines()[0].split(",")
    assert header[-5:] == ["mismatch_ratio", "mismatch_cost", "mismatch_missed", "worst_ratio", "missed"]


def test_ppo_refuses_a_cubic_output_by_name_and_writes_nothing(tmp_path):
    """PPO's Gaussian explores around the network's output itself: a cubic output (a distillation's) is refused
    before the run's folder is made."""
    from mjtraj.exceptions import InvalidInputError
    from mjtraj.rl import batched

    with pytest.raises(InvalidInputError, match=r"^output: PPO explores around the network's output itself, expected "
                                                r"linear, got 'cubic' \(a cubic output is a distillation's\)$"):
        batched.train_batched(BatchedSettings(**{**TINY, "output": "cubic"}), tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()
