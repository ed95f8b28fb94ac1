"""RL on UR5Track-v0: SB3 contract, seed streams, train -> eval end to end, reloads, fairness oracles, bad input."""

from __future__ import annotations

import copy
import json
import re
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from mjtraj.envs.settings import resolve
from mjtraj.envs.ur5_track import UR5TrackEnv
from mjtraj.envs.vector import UR5TrackVectorEnv
from stable_baselines3 import SAC
from stable_baselines3.common.env_checker import check_env
from stable_baselines3.common.vec_env import VecNormalize

from mjtraj.cli import main
from mjtraj.core import random_task
from mjtraj.core.metrics import METRIC_NAMES
from mjtraj.core.model import JointInfo
from mjtraj.core.planners.optimal import bryson_weights
from mjtraj.domain.families import FAMILIES, PAYLOAD_MASS, draw_perturbation, draw_scenario
from mjtraj.exceptions import InvalidInputError, MissingExtraError
from mjtraj.rl.episodes import run_episodes
from mjtraj.rl.evaluate import check_held_out, configurations, evaluate
from mjtraj.rl.extra import require_sb3
from mjtraj.rl.policy import Normalization, Policy, load_policy
from mjtraj.rl.sb3_env import SB3TrackVecEnv
from mjtraj.rl.streams import TRAIN_STREAM, VALIDATION_STREAM, shared_streams, stream_seed, training_entropies
from mjtraj.rl.train import TrainSettings, train, validation_set
from mjtraj.study.store import numeric, read_rows
from mjtraj.study.sweep import SweepSettings, plan_scenarios, run_unit

TINY = {"steps": 240, "evaluations": 2, "checkpoints": 2, "validation": 4}


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny SAC residual run through the CLI (the README's command with a small budget)."""
    out = tmp_path_factory.mktemp("run") / "sac"
    code = main(["rl", "train", "--algo", "sac", "--action-mode", "residual", "--planner", "cubic", "--task",
                 "random", "--steps", "240", "--seed", "3", "--evaluations", "2", "--checkpoints", "2",
                 "--validation", "4", "--out", str(out), "--no-progress"])
    assert code == 0
    return out



@pytest.mark.parametrize("action_mode", ["residual", "torque"])
def test_sb3_check_env(action_mode):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(UR5TrackEnv(action_mode=action_mode, task="random", preview=1))



def test_stream_seed_is_the_list_seed_and_plain_seeds_collide_with_scenarios():
    for seed, stream, index in [(0, TRAIN_STREAM, 0), (7, 17, 3), (2**32 - 1, 16, 255)]:
        a = np.random.default_rng(stream_seed(seed, stream, index)).random(5)
        np.testing.assert_array_equal(a, np.random.default_rng([seed, stream, index]).random(5))
    # the hazard the streams avoid: a plain gym seed s is the nominal family's scenario 0 under seed s
    np.testing.assert_array_equal(np.random.default_rng(5).random(3), np.random.default_rng([5, 0, 0]).random(3))
    with pytest.raises(InvalidInputError, match=r"^seed: expected a whole number in \[0, 2\^32\), got 4294967296$"):
        stream_seed(2**32, TRAIN_STREAM, 0)



def test_sb3_vec_env_is_the_vector_env_with_same_step_autoreset():
    """Sub-env i of the SB3 adapter is UR5TrackEnv seeded with the TRAIN_STREAM seed (s, i), bit for bit, across an
    autoreset: terminal_observation is the single env's last observation, and the returned one its next reset's."""
    venv = SB3TrackVecEnv(2, action_mode="residual", task="random")
    venv.seed(9)
    obs = venv.reset()
    singles = [UR5TrackEnv(action_mode="residual", task="random") for _ in range(2)]
    first = [env.reset(seed=s)[0] for env, s in zip(singles, training_entropies(9, 2), strict=True)]
    np.testing.assert_array_equal(obs, np.array(first))
    rng = np.random.default_rng(0)
    for _ in range(100):
        actions = rng.uniform(-0.05, 0.05, (2, 3)).astype(np.float32)
        obs, reward, dones, infos = venv.step(actions)
        for i, env in enumerate(singles):
            o, r, done, _, info = env.step(actions[i])
            assert np.float32(r) == reward[i] and done == dones[i]
            if done:
                np.testing.assert_array_equal(infos[i]["terminal_observation"], o)
                assert infos[i]["TimeLimit.truncated"] is False
                assert infos[i]["metrics"] == pytest.approx(info["metrics"], rel=0, abs=0, nan_ok=True)
                np.testing.assert_array_equal(obs[i], env.reset()[0])
            else:
                np.testing.assert_array_equal(obs[i], o)
    assert dones.all()



def test_gymnasium_same_step_mode_matches_next_step_mode():
    kwargs = {"num_envs": 3, "task": "random", "action_mode": "torque"}
    same = UR5TrackVectorEnv(autoreset_mode=gym.vector.AutoresetMode.SAME_STEP, **kwargs)
    nxt = UR5TrackVectorEnv(**kwargs)
    a, _ = same.reset(seed=4)
    b, _ = nxt.reset(seed=4)
    np.testing.assert_array_equal(a, b)
    actions = np.full((3, 3), 0.01, dtype=np.float32)
    for _ in range(100):
        a, *_, info_a = same.step(actions)
        b, *_, info_b = nxt.step(actions)
    np.testing.assert_array_equal(np.stack(info_a["final_obs"]), b)  # the final observations
    b, reward, terminated, _, _ = nxt.step(actions)  # NEXT_STEP's reset step
    np.testing.assert_array_equal(a, b)
    assert not reward.any() and not terminated.any()
    with pytest.raises(InvalidInputError, match=r"^autoreset_mode: expected one of"):
        UR5TrackVectorEnv(autoreset_mode="sometimes")



def test_pid_through_the_policy_path_is_the_sweep(model):
    """Fairness oracle: the policy path without actions gives the sweep's planner rows bit for bit, on the nominal
    and on the perturbed plants (same plant, controller, saturation and scoring); a zero residual is PID alone."""
    from mjtraj.domain.families import perturbed_plant
    from mjtraj.domain.pipeline import Job, execute
    from mjtraj.rl.episodes import PolicyActor

    for family in FAMILIES:
        settings = SweepSettings(families=(family,), scenarios=6, seed=2, planners=("cubic",))
        rows = run_unit(settings, (family, 0)).rows
        draws = [draw_scenario(family, 2, i, model, 0.02) for i in range(6)]
        refs = plan_scenarios(settings, draws)["cubic"]
        weights = [bryson_weights(s.task, JointInfo.of(model).torque_limit) for s in draws]
        env = resolve(planner="cubic", action_mode="residual")
        plant = perturbed_plant(model) if family == "mismatch" else None
        jobs = [Job(ref, w, s.perturbation) for ref, w, s in zip(refs, weights, draws, strict=True)]
        pid = execute(env.model, env.loop, jobs, plant=plant)
        zero = execute(env.model, env.loop, jobs, plant=plant,
                       actor=PolicyActor(lambda obs: np.zeros((len(obs), 3), np.float32), env))
        for i, row in enumerate(rows):
            for name in METRIC_NAMES:
                assert np.array_equal(pid[i].metrics[name], numeric(row[name]), equal_nan=True), (family, i, name)
                assert np.array_equal(zero[i].metrics[name], pid[i].metrics[name], equal_nan=True)


@pytest.mark.parametrize("scale", [3.0, 10.0, 60.0])
def test_the_policy_path_scales_actions_as_the_env(scale):
    """A constant residual action through the policy path (evaluation) gives the env's episode, cost bit for bit, at
    any residual_scale; the scale changes the torque (oracle: the env's own step)."""
    from mjtraj.domain.pipeline import Job, execute
    from mjtraj.rl.episodes import PolicyActor

    action = np.array([0.4, -0.3, 0.2], dtype=np.float32)
    env = UR5TrackEnv(action_mode="residual", residual_scale=scale)
    env.reset(seed=0)
    done, ret = False, 0.0
    while not done:
        _, reward, done, _, info = env.step(action)
        ret += reward
    s = env.settings
    job = Job(s.planner.plan(s.fixed_task, s.model), s.weights(s.fixed_task))
    out = execute(s.model, s.loop, [job], actor=PolicyActor(lambda obs: np.tile(action, (len(obs), 1)), s))
    assert out[0].metrics["cost"] == info["metrics"]["cost"]
    assert out[0].metrics["cost"] == pytest.approx(-ret, rel=1e-9)
    env.close()


def test_the_policy_path_observes_as_the_env_with_observe_control():
    """A policy acting on the appended feedforward and integral gives, through the evaluation path, the env's own
    episode (cost bit for bit): both paths build the same observation."""
    from mjtraj.domain.pipeline import Job, execute
    from mjtraj.rl.episodes import PolicyActor

    def policy(obs):
        return np.clip(obs[:, -3:] / 30.0 - 5.0 * obs[:, -6:-3], -1, 1).astype(np.float32)

    env = UR5TrackEnv(action_mode="residual", observe_control=True)
    obs, _ = env.reset(seed=0)
    done = False
    while not done:
        obs, _, done, _, info = env.step(policy(obs[None])[0])
    s = env.settings
    job = Job(s.planner.plan(s.fixed_task, s.model), s.weights(s.fixed_task))
    out = execute(s.model, s.loop, [job], actor=PolicyActor(policy, s))
    assert out[0].metrics["cost"] == info["metrics"]["cost"]
    assert TrainSettings(observe_control=True).env_kwargs()["observe_control"] is True
    env.close()


def test_a_policy_records_its_residual_scale_and_old_records_mean_the_saturation():
    record = {"settings": {"algo": "sac"},
              "env": {**TrainSettings(residual_scale=4.0).env_kwargs(), "task": "paper"}}
    norm = Normalization(np.zeros(19), np.ones(19), 1e-8, 10.0)
    policy = Policy(None, record, norm, 0)
    assert policy.settings().residual_scale == 4.0 and policy.label == "cubic+PID+residual SAC (4 N m)"
    del record["env"]["residual_scale"]  # a record written before residual_scale existed: 60 N m was used
    legacy = Policy(None, record, norm, 0)
    assert np.array_equal(legacy.settings().action_scale, np.full(3, 60.0))
    assert TrainSettings().env_kwargs()["residual_scale"] == 6.0


@pytest.mark.slow
def test_saved_policy_reloads_with_identical_actions(tmp_path):
    """Oracle: SB3's own path (VecNormalize.normalize_obs + predict) on the in-memory model."""
    venv = VecNormalize(SB3TrackVecEnv(2, action_mode="torque", task="random"), clip_obs=10.0)
    model = SAC("MlpPolicy", venv, seed=1, device="cpu", learning_starts=50)
    model.learn(150)
    record = {"settings": {"algo": "sac", "seed": 1}, "env": {"planner": "cubic", "action_mode": "torque",
                                                               "task": "random"},
              "streams": {"train": {"gym_seeds": training_entropies(1, 2)}, "validation": {"count": 0}}}
    path = Policy(model, record, Normalization.of(venv), int(model.num_timesteps)).save(tmp_path / "p.zip")
    obs = np.array([venv.unnormalize_obs(np.random.default_rng(k).normal(size=19)) for k in range(64)])
    expected, _ = model.predict(venv.normalize_obs(obs), deterministic=True)
    loaded = load_policy(path)
    np.testing.assert_array_equal(loaded.act(obs), expected)
    np.testing.assert_array_equal(load_policy(path).act(obs), loaded.act(obs))



@pytest.mark.slow
def test_train_writes_every_artifact(trained):
    run = json.loads((trained / "run.json").read_text())
    assert run["status"] == "complete" and run["timesteps"] == 240
    assert run["settings"]["seed"] == 3 and run["env"]["action_mode"] == "residual"
    assert {"mjtraj", "mujoco", "numpy", "stable_baselines3", "torch", "gymnasium"} <= set(run["versions"])
    assert run["streams"]["train"]["gym_seeds"] == [stream_seed(3, TRAIN_STREAM, i) for i in range(4)]
    assert run["hyperparameters"]["resolved"]["batch_size"] == 256  # SB3's default, recorded
    curve = read_rows(trained / "learning_curve.csv")
    assert [int(r["timesteps"]) for r in curve] == [0, 120, 240]
    assert all(numeric(r["pid_cost_mean"]) == numeric(curve[0]["pid_cost_mean"]) for r in curve)
    assert (trained / "learning_curve.png").stat().st_size > 10_000
    checkpoints = sorted((trained / "checkpoints").glob("*.zip"))
    assert [p.name for p in checkpoints] == ["step_000000120.zip"]  # and the final one, policy.zip
    assert load_policy(checkpoints[0]).timesteps == 120
    # the curve's last row is the saved final policy on the validation tasks (replayed here)
    final = load_policy(trained / "policy.zip")
    settings = TrainSettings(**{**TINY, "seed": 3})
    refs, weights, plants = validation_set(settings, final.settings())
    assert plants is None  # trained on the nominal plant
    replay = [o.metrics["cost"] for o in run_episodes(final.act, final.settings(), refs, weights) if o.status == "ok"]
    assert numeric(curve[-1]["val_cost_mean"]) == np.mean(replay)
    pid = [o.metrics["cost"] for o in run_episodes(None, final.settings(), refs, weights)]
    assert numeric(curve[0]["pid_cost_mean"]) == np.mean(pid)
    # best.zip is the curve's best validation point, selected on the validation tasks only
    costs = [numeric(r["val_cost_mean"]) if int(r["val_diverged"]) == 0 else np.inf for r in curve]
    best = int(np.argmin(costs))
    assert run["best_validation"]["timesteps"] == int(curve[best]["timesteps"])
    assert run["best_validation"]["cost_mean"] == costs[best]
    best_policy = load_policy(trained / "best.zip")
    assert best_policy.timesteps == int(curve[best]["timesteps"])
    replay = [o.metrics["cost"] for o in run_episodes(best_policy.act, final.settings(), refs, weights)]
    assert np.mean(replay) == costs[best]



@pytest.mark.slow
def test_plot_redraws_a_run(trained, tmp_path, capsys):
    png = trained / "learning_curve.png"
    png.unlink()
    assert main(["rl", "plot", str(trained)]) == 0
    assert png.stat().st_size > 10_000 and capsys.readouterr().out == f"wrote {png}\n"
    assert main(["rl", "plot", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (f"mjtraj: error: run: {tmp_path / 'run.json'} not found; expected a folder "
                                       "written by mjtraj rl train\n")



@pytest.mark.slow
def test_eval_rows_are_the_sweeps_and_the_policys(trained, tmp_path, capsys):
    code = main(["rl", "eval", "--policy", str(trained / "policy.zip"), "--family", "aggressive", "--scenarios", "5",
                 "--seed", "3", "--planners", "cubic,optimal", "--reps", "50", "--out", str(tmp_path),
                 "--no-progress", "--protocol", "v1"])
    assert code == 0
    table = capsys.readouterr().out
    assert "| cubic+PID+residual SAC (6 N m) | 1 | " in table and "| optimal+PID | 1 | " in table
    rows = read_rows(tmp_path / "eval.csv")
    sweep = run_unit(SweepSettings(families=("aggressive",), scenarios=5, seed=3, planners=("cubic", "optimal")),
                     ("aggressive", 0)).rows
    planner_rows = [r for r in rows if r["policy"] == ""]
    assert len(planner_rows) == len(sweep) == 10
    for got, want in zip(planner_rows, sweep, strict=True):
        assert all(got[k] == (repr(v) if isinstance(v, float) else str(v)) or got[k] == v == "nan"
                   for k, v in want.items() if k not in ("reason",)), got["planner"]
    mine = [r for r in rows if r["policy"]]
    assert [r["scenario"] for r in mine] == [str(i) for i in range(5)]
    assert all(r["method"] == "cubic+PID+residual SAC (6 N m)" and r["policy_timesteps"] == "240" and
               r["policy_kind"] == "sb3-zip" for r in mine)
    # the policy rows replay: its episodes on the same references, batched as eval batches them (scenarios of one
    # length together: torch's float32 kernels round differently for different batch sizes), give the same numbers
    policy = load_policy(trained / "policy.zip")
    model = policy.settings().model
    draws = [draw_scenario("aggressive", 3, i, model, 0.02) for i in range(5)]
    refs = plan_scenarios(SweepSettings(families=("aggressive",), scenarios=5, seed=3, planners=("cubic",)),
                          draws)["cubic"]
    limit = JointInfo.of(model).torque_limit
    replayed = 0
    for steps in sorted({r.steps for r in refs}):
        ids = [i for i, r in enumerate(refs) if r.steps == steps]
        outcomes = run_episodes(policy.act, policy.settings(), [refs[i] for i in ids],
                                [bryson_weights(draws[i].task, limit) for i in ids])
        for j, i in enumerate(ids):
            assert mine[i]["status"] == "ok" and numeric(mine[i]["cost"]) == outcomes[j].metrics["cost"]
            replayed += 1
    assert replayed == 5
    summary = (tmp_path / "SUMMARY.md").read_text()
    assert summary.count("| cubic+PID+residual SAC (6 N m) | 1 |") == 1
    assert "By payload" not in summary  # no payloads on the aggressive family
    assert summary.startswith("# Benchmark summary (OFF-PROTOCOL)\n\n**Off-protocol**: families aggressive (v1: ")
    assert "\nRegenerate: `mjtraj rl eval --policy " in summary
    record = json.loads((tmp_path / "summary.json").read_text())
    got = record["summary"]["aggressive"]["cubic+PID+residual SAC (6 N m)"]
    assert {"failures", "iqm", "probability_of_improvement", "ratio_of_means"} <= set(got)
    assert record["torch_threads"] == 1


@pytest.mark.slow
def test_a_wrapped_zip_scores_as_the_zip_bit_for_bit(trained, tmp_path):
    """A user's batched callable around the loaded policy gives the zip's own rows."""
    policy = load_policy(trained / "policy.zip")

    class Wrapped:
        batched = True
        env = {k: policy.env_kwargs[k] for k in ("planner", "controller", "action_mode", "residual_scale",
                                                  "observe_control", "preview")}

        def __call__(self, obs):
            return policy.act(obs)

    report = evaluate([trained / "policy.zip", Wrapped()], families=("nominal", "mismatch"), scenarios=4, seed=2,
                      reps=20, out=tmp_path)
    rows = read_rows(report.csv)
    for family in ("nominal", "mismatch"):
        zipped = [r["cost"] for r in rows if r["family"] == family and r["policy_kind"] == "sb3-zip"]
        wrapped = [r["cost"] for r in rows if r["family"] == family and r["policy_kind"] == "callable"]
        assert zipped == wrapped and len(zipped) == 4


@pytest.mark.slow
def test_configurations_sharing_a_label_are_told_apart_by_their_settings(trained):
    """Seeds of one configuration share a row; two budgets of it get their own, named by what differs."""
    def variant(seed, steps, stem="policy"):
        base = load_policy(trained / "policy.zip")
        record = copy.deepcopy(base.record)
        record["settings"].update(seed=seed, steps=steps)
        return Policy(base.model, record, base.normalization, base.timesteps, trained / f"{stem}.zip")

    policies = [variant(0, 240), variant(1, 240), variant(0, 480), variant(0, 480, "best")]
    groups = configurations(policies, ["a", "b", "c", "d"])
    label = policies[0].label
    assert groups == {f"{label} [steps=240]": ["a", "b"], f"{label} [steps=480]": ["c"], f"{label} best": ["d"]}


@pytest.mark.slow
def test_eval_under_mismatch_splits_by_payload(trained, tmp_path):
    """Oracle: each payload bin's ratio of mean J_exec, recomputed from the rows with numpy by the failure rule (a
    row that is not ok, a missed goal included, is +inf; scenarios where the reference failed leave the ratio)."""
    report = evaluate([trained / "policy.zip"], families=("mismatch",), scenarios=10, seed=5, reps=20, out=tmp_path,
                      protocol="v1")
    rows = read_rows(report.csv)
    ref = {int(r["scenario"]): r for r in rows if r["method"] == "cubic+PID"}
    mine = {int(r["scenario"]): r for r in rows if r["policy"]}
    assert sorted(ref) == sorted(mine) == list(range(10))
    lo, hi = PAYLOAD_MASS
    text = report.markdown.read_text().split("By payload")[1]
    header, _, _, line = text.split("\n\n")[1].splitlines()[:4]
    cells = line.split(" | ")[1:]
    assert line.startswith("| cubic+PID+residual SAC (6 N m) |") and len(cells) == 5
    for b, cell in enumerate(cells):
        inside = [k for k in ref if min(int((numeric(ref[k]["payload_kg"]) - lo) / (hi - lo) * 5), 4) == b]
        assert f"({len(inside)})" in header.split(" | ")[b + 1]
        if not inside:
            assert cell.rstrip(" |") == "-"
            continue
        kept = [k for k in inside if ref[k]["status"] == "ok"]
        cost = np.array([numeric(mine[k]["cost"]) if mine[k]["status"] == "ok" else np.inf for k in kept])
        base = np.array([numeric(ref[k]["cost"]) for k in kept])
        expected = cost.sum() / base.sum() if kept else float("nan")
        assert cell.rstrip(" |") == f"{expected:.3g}"


@pytest.mark.slow
def test_eval_scenarios_are_held_out_from_training(trained):
    """No eval task is a task the run trained on (replayed from its recorded streams), and a policy whose record
    claims plain gym seeds (the hazard) is refused."""
    policy = load_policy(trained / "policy.zip")
    env = policy.settings()
    trained_tasks = set()
    for gym_seed in policy.record["streams"]["train"]["gym_seeds"]:
        rng = np.random.default_rng(gym_seed)
        for _ in range(5):  # more episodes than the tiny run had
            task = env.sample_task(rng)
            trained_tasks.add((tuple(task.q0), tuple(task.qg)))
    for family in FAMILIES:
        for seed in (0, 3):
            check_held_out(policy, family, seed, 200)
            tasks = {(tuple(t.q0), tuple(t.qg)) for t in
                     (draw_scenario(family, seed, i, env.model, 0.02).task for i in range(200))}
            assert not tasks & trained_tasks
    hazard = Policy(policy.model, {**policy.record, "streams": {"train": {"gym_seeds": [3, 4]},
                                                                 "validation": {"count": 0}}},
                    policy.normalization, 0, trained / "policy.zip")
    with pytest.raises(InvalidInputError, match=r"^seed: 1 of the nominal scenarios under seed 3 share a seed "):
        check_held_out(hazard, "nominal", 3, 10)
    assert shared_streams([3], [[3, 0, 0]])



@pytest.mark.slow
def test_overrides_reach_the_model_and_the_record(tmp_path):
    settings = TrainSettings(algo="sac", action_mode="residual", seed=1, num_envs=2,
                             overrides={"learning_rate": 0.00123, "policy_kwargs": {"net_arch": [16, 16]}}, **TINY)
    report = train(settings, tmp_path / "hp", progress=False)
    run = json.loads((report.out / "run.json").read_text())
    assert run["hyperparameters"]["overrides"] == {"learning_rate": 0.00123, "policy_kwargs": {"net_arch": [16, 16]}}
    assert run["hyperparameters"]["resolved"]["learning_rate"] == 0.00123
    policy = load_policy(report.policy)
    widths = [layer.out_features for layer in policy.model.policy.actor.latent_pi if hasattr(layer, "out_features")]
    assert widths == [16, 16]
    assert TrainSettings(**run["settings"]) == settings  # the record rebuilds the run's settings (rl plot)


@pytest.mark.slow
def test_same_seed_same_policy(tmp_path):
    settings = TrainSettings(algo="td3", action_mode="torque", seed=5, num_envs=2, **TINY)
    a, b = train(settings, tmp_path / "a", progress=False), train(settings, tmp_path / "b", progress=False)
    pa, pb = load_policy(a.policy), load_policy(b.policy)
    for x, y in zip(pa.model.policy.parameters(), pb.model.policy.parameters(), strict=True):
        assert np.array_equal(x.detach().numpy(), y.detach().numpy())
    curve = [[{k: v for k, v in r.items() if k != "wall_s"} for r in read_rows(p / "learning_curve.csv")]
             for p in (a.out, b.out)]
    assert curve[0] == curve[1]



@pytest.mark.slow
def test_ppo_trains_and_reloads(tmp_path):
    report = train(TrainSettings(algo="ppo", action_mode="residual", task="paper", num_envs=8, **TINY),
                   tmp_path / "ppo", progress=False)
    policy = load_policy(report.policy)
    assert report.timesteps == 2048 and policy.model.n_steps == 256  # SB3's 2048 transitions per update
    assert policy.label == "cubic+PID+residual PPO (6 N m)"
    assert len(read_rows(report.out / "learning_curve.csv")) == 3



@pytest.mark.parametrize(("argv", "message"), [
    (["rl", "train", "--algo", "dqn"],
     "mjtraj: error: algo: unknown value 'dqn'; valid: sac, ppo, td3, recurrent_ppo\n"),
    (["rl", "train", "--action-mode", "pid"],
     "mjtraj: error: action_mode: unknown value 'pid'; valid: residual, torque\n"),
    (["rl", "train", "--task", "explicit"], "mjtraj: error: task: unknown value 'explicit'; valid: paper, random\n"),
    (["rl", "train", "--steps", "0"], "mjtraj: error: steps: expected a whole number >= 1, got 0\n"),
    (["rl", "train", "--residual-scale", "0"], "mjtraj: error: residual_scale: expected a positive number, got 0.0\n"),
    (["rl", "train", "--residual-scale", "-2"],
     "mjtraj: error: residual_scale: expected a positive number, got -2.0\n"),
    (["rl", "train", "--hyperparameter", "learning_rate"],
     "mjtraj: error: hyperparameter: expected NAME=VALUE, got 'learning_rate'\n"),
    (["rl", "train", "--plant-randomization", "payload"],
     "mjtraj: error: plant_randomization: unknown value 'payload'; valid: none, mismatch\n"),
    (["rl", "train", "--reward-baseline", "zero"],
     "mjtraj: error: reward_baseline: unknown value 'zero'; valid: none, controller, pid\n"),
    (["rl", "eval", "--policy", "nowhere.zip"], "mjtraj: error: policy: file not found: nowhere.zip\n"),
    (["rl", "eval", "--policy", "p.pkl"],
     "mjtraj: error: policy: expected a policy .zip saved by mjtraj rl train, got 'p.pkl'\n"),
    (["rl", "eval", "--policy", "p.pt"], "mjtraj: error: policy: file not found: p.pt\n"),
    (["rl", "eval", "--policy", "mypolicy.py"],
     "mjtraj: error: policy: expected FILE.py:ATTR (the file and the name of the policy in it, e.g. "
     "mypolicy.py:policy), got 'mypolicy.py'\n"),
    (["rl", "eval", "--seed", "-1"], "mjtraj: error: seed: expected a whole number in [0, 2^32), got -1\n"),
])
def test_cli_bad_input(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert capsys.readouterr().err == message


@pytest.mark.parametrize(("algo", "name", "some_valid"), [
    ("ppo", "buffer_size", {"learning_rate", "n_steps", "gae_lambda", "clip_range", "policy_kwargs"}),
    ("sac", "seed", {"learning_rate", "buffer_size", "tau", "ent_coef", "policy_kwargs"}),
])
def test_an_unknown_hyperparameter_lists_the_constructors_own(algo, name, some_valid, capsys, tmp_path, monkeypatch):
    """The valid names are the SB3 constructor's arguments (they vary between SB3 releases) less those mjtraj sets
    itself (policy, env, seed, device, ...)."""
    import inspect

    import stable_baselines3

    monkeypatch.chdir(tmp_path)
    assert main(["rl", "train", "--algo", algo, "--hyperparameter", f"{name}=10"]) == 2
    err = capsys.readouterr().err
    match = re.fullmatch(rf"mjtraj: error: hyperparameter: unknown name '{name}' for {algo}; valid: (.+)\n", err)
    assert match, err
    valid = set(match.group(1).split(", "))
    arguments = set(inspect.signature(getattr(stable_baselines3, algo.upper()).__init__).parameters)
    assert some_valid <= valid <= arguments
    assert not valid & {name, "policy", "env", "seed", "device", "verbose", "tensorboard_log"}
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_hyperparameter_overrides_from_a_file_and_flags(tmp_path, monkeypatch, capsys):
    """A file's JSON object, then NAME=VALUE flags (JSON values, else strings), replace the rule's defaults; a file
    that is not a JSON object and a value that is not JSON-able are refused."""
    from mjtraj.cli.common import overrides as _overrides

    file = tmp_path / "hp.json"
    file.write_text('{"learning_rate": 0.001, "ent_coef": "auto_0.1", "policy_kwargs": {"net_arch": [64, 64]}}')
    got = _overrides(file, ["learning_rate=0.0003", "train_freq=[1, \"episode\"]", "ent_coef=auto"])
    assert got == {"learning_rate": 0.0003, "ent_coef": "auto", "policy_kwargs": {"net_arch": [64, 64]},
                   "train_freq": [1, "episode"]}
    settings = TrainSettings(algo="ppo", num_envs=4, overrides={"n_steps": 64, "gamma": 0.95})
    assert settings.hyperparameters() == {"n_steps": 64, "gamma": 0.95}  # the override replaces the PPO rule
    assert TrainSettings(algo="ppo", num_envs=4).hyperparameters() == {"n_steps": 512}
    with pytest.raises(InvalidInputError, match=r"^hyperparameter: learning_rate must be a JSON value"):
        TrainSettings(overrides={"learning_rate": float("nan")})
    file.write_text("[1, 2]")
    monkeypatch.chdir(tmp_path)
    assert main(["rl", "train", "--hyperparameters", str(file)]) == 2
    assert capsys.readouterr().err == f"mjtraj: error: hyperparameters: expected a JSON object in {file}, got list\n"



@pytest.mark.slow
def test_policy_for_another_space_is_refused(trained, tmp_path):
    """A zip whose spaces are not the env's its record describes: the message says which space and both shapes."""
    other = SAC("MlpPolicy", "Pendulum-v1", seed=0, device="cpu")
    record = json.loads((trained / "policy.json").read_text())["run"]
    bad = Policy(other, record, Normalization(np.zeros(19), np.ones(19), 1e-8, 10.0), 0).save(tmp_path / "x.zip")
    with pytest.raises(InvalidInputError, match=r"^policy: x\.zip takes observations of shape \(3,\) but UR5Track-v0 "
                       r"\(action_mode=residual, preview=0\) gives shape \(19,\)$"):
        load_policy(bad)
    record["env"]["preview"] = 1  # a record that asks for preview observations the zip was not trained on
    (tmp_path / "y.json").write_text(json.dumps({**json.loads((trained / "policy.json").read_text()), "run": record}))
    (tmp_path / "y.zip").write_bytes((trained / "policy.zip").read_bytes())
    with pytest.raises(InvalidInputError, match=r"takes observations of shape \(19,\) but UR5Track-v0 "
                       r"\(action_mode=residual, preview=1\) gives shape \(25,\)$"):
        load_policy(tmp_path / "y.zip")
    (tmp_path / "z.zip").write_bytes(b"not a zip")
    (tmp_path / "z.json").write_text((trained / "policy.json").read_text())
    with pytest.raises(InvalidInputError, match=r"^policy: z\.json records a different zip than z\.zip"):
        load_policy(tmp_path / "z.zip")



@pytest.mark.slow
@pytest.mark.parametrize(("record", "message"), [
    (None, r"^policy: no record p\.json beside p\.zip; mjtraj rl train writes the two together$"),
    ("{not json", r"^policy: .*p\.json is not valid JSON \(Expecting property name"),
    ('{"format": "other"}', r"^policy: .*p\.json is not an mjtraj policy record \(expected format "
                            r"mjtraj-policy/1\)$"),
    ('{"format": "mjtraj-policy/1", "run": {"env": {}}}', r"^policy: .*p\.json lacks zip_sha256, timesteps, "
                                                          r"normalization, run\.settings, run\.streams$"),
    ("unknown-algo", r"^policy: unknown algorithm 'dqn' in p\.json; valid: sac, ppo, td3, recurrent_ppo$"),
])
def test_broken_policy_records(trained, tmp_path, record, message):
    (tmp_path / "p.zip").write_bytes((trained / "policy.zip").read_bytes())
    if record == "unknown-algo":
        body = json.loads((trained / "policy.json").read_text())
        body["run"]["settings"]["algo"] = "dqn"
        record = json.dumps(body)
    if record is not None:
        (tmp_path / "p.json").write_text(record)
    with pytest.raises(InvalidInputError, match=message):
        load_policy(tmp_path / "p.zip")



@pytest.mark.slow
def test_policy_and_engine_argument_checks(trained):
    policy = load_policy(trained / "policy.zip")
    with pytest.raises(InvalidInputError, match=r"^obs: expected shape \(B, 19\), got \(19,\)$"):
        policy.act(np.zeros(19))
    with pytest.raises(InvalidInputError, match=r"^family: expected at least one family, got none$"):
        evaluate([], families=())



@pytest.mark.slow
def test_eval_refuses_policies_trained_on_another_controller(trained, tmp_path):
    def variant(name, **env):
        body = json.loads((trained / "policy.json").read_text())
        body["run"]["env"].update(env)
        (tmp_path / f"{name}.json").write_text(json.dumps(body))
        (tmp_path / f"{name}.zip").write_bytes((trained / "policy.zip").read_bytes())
        return tmp_path / f"{name}.zip"

    planned = variant("planned", feedforward="planned")
    with pytest.raises(InvalidInputError, match=r"^policy: .*planned\.zip was trained with a different controller "
                       r"\(feedforward\) than the sweep's base scenario$"):
        evaluate([planned], scenarios=2, out=tmp_path)
    averaged = variant("averaged", ff_accel="step_average")
    with pytest.raises(InvalidInputError, match=r"^policy: .*averaged\.zip acts with ff_accel='step_average'; the "
                       r"benchmark's controller uses 'sample'$"):
        evaluate([trained / "policy.zip", averaged], scenarios=2, out=tmp_path)
    assert not list(tmp_path.glob("eval*"))  # refused before anything was written



@pytest.mark.slow
def test_train_refuses_a_folder_with_a_run(trained):
    with pytest.raises(InvalidInputError, match=r"already holds a training run \(run\.json\); choose another"):
        train(TrainSettings(**TINY), trained, progress=False)



def test_missing_rl_extra_says_how_to_install(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    with pytest.raises(MissingExtraError, match=r"^rl: stable_baselines3 is not installed; install the rl extra: "
                       r"pip install torch==2\.13\.0 && pip install 'mjtraj\[rl\]'"):
        require_sb3()
    monkeypatch.setitem(sys.modules, "sb3_contrib", None)
    assert main(["rl", "eval", "--policy", "baseline:rppo_act_100k_s2"]) == 2  # a zip needs SB3 to act ...
    assert "install the rl extra" in capsys.readouterr().err
    with pytest.raises(MissingExtraError):
        evaluate(["baseline:sac_act_history4_100k_s3"])
    # ... a plain callable does not (nor PyTorch: the README's set-up without the rl extra, tried in a fresh venv)
    def zero(obs):
        return np.zeros(3)

    report = evaluate([zero], families=("nominal",), scenarios=2, reps=10, out=tmp_path, protocol="v1")
    (summary,) = [s for m, s in report.summaries["nominal"].items() if m.endswith("zero")]
    assert summary.ratio_of_means.value == 1.0



@pytest.mark.slow
def test_a_failed_training_run_is_recorded(tmp_path, monkeypatch):
    import mjtraj.rl.train as train_module

    calls = []

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:  # the baseline ran; the first validation of the policy fails
            raise RuntimeError("validation exploded")
        return run_episodes(*args, **kwargs)

    monkeypatch.setattr(train_module, "run_episodes", failing)
    with pytest.raises(RuntimeError, match="validation exploded"):
        train(TrainSettings(**TINY), tmp_path / "run", progress=False)
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["status"] == "failed" and run["error"] == "RuntimeError: validation exploded"



@pytest.mark.slow
def test_a_policy_failing_in_eval_is_recorded_and_eval_goes_on(trained, tmp_path, monkeypatch):
    from mjtraj.rl.episodes import PolicyActor

    def failing(*args, **kwargs):
        raise RuntimeError("policy exploded")

    monkeypatch.setattr(PolicyActor, "act", failing)
    evaluate([trained / "policy.zip"], families=("nominal",), scenarios=3, reps=20, out=tmp_path, protocol="v1")
    rows = read_rows(tmp_path / "eval.csv")
    assert [(r["method"], r["status"]) for r in rows] == [("cubic+PID", "ok")] * 3 + [
        ("cubic+PID+residual SAC (6 N m)", "error")] * 3
    assert {r["reason"] for r in rows if r["policy"]} == {"RuntimeError: policy exploded"}
    summary = json.loads((tmp_path / "summary.json").read_text())["summary"]["nominal"]
    assert summary["cubic+PID+residual SAC (6 N m)"]["failures"] == 3
    assert summary["cubic+PID+residual SAC (6 N m)"]["ratio_of_means"]["value"] == "inf"



def test_mismatch_validation_tasks_carry_plants_drawn_after_each_task(model):
    """Oracle: each validation task's stream drawn by hand: the task by the env's rule, then the mismatch plant."""
    settings = TrainSettings(**{**TINY, "seed": 5, "plant_randomization": "mismatch"})
    env = resolve(**settings.env_kwargs())
    assert settings.env_kwargs()["plant_randomization"] == "mismatch"
    refs, weights, plants = validation_set(settings, env)
    for i, (ref, plant) in enumerate(zip(refs, plants, strict=True)):
        rng = np.random.default_rng([5, VALIDATION_STREAM, i])
        task = random_task(rng, model, max_displacement=1.5, duration=2.0, dt=0.02)
        assert np.array_equal(ref.q[0], task.q0) and np.array_equal(ref.q[-1], task.qg)
        assert plant.as_dict() == draw_perturbation(rng, 3).as_dict()
    perturbed = [o.metrics["cost"] for o in run_episodes(None, env, refs, weights, plants)]
    nominal = [o.metrics["cost"] for o in run_episodes(None, env, refs, weights)]
    assert np.mean(perturbed) > 10 * np.mean(nominal)  # the plants are really perturbed in validation


@pytest.mark.slow
def test_training_under_mismatch_on_the_pid_advantage_is_recorded_and_validated_on_mismatch_by_j_exec(tmp_path):
    out = tmp_path / "mm"
    assert main(["rl", "train", "--steps", "240", "--seed", "4", "--evaluations", "2", "--checkpoints", "2",
                 "--validation", "4", "--plant-randomization", "mismatch", "--reward-baseline", "pid", "--out",
                 str(out), "--no-progress"]) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["settings"]["plant_randomization"] == "mismatch" and run["env"]["plant_randomization"] == "mismatch"
    assert run["env"]["reward_baseline"] == "pid"
    policy = load_policy(out / "policy.zip")
    assert policy.settings().plant_randomization == "mismatch"
    assert policy.label == "cubic+PID+residual SAC (6 N m, mismatch-trained, PID-advantage reward)"
    settings = TrainSettings(**{**TINY, "seed": 4, "plant_randomization": "mismatch", "reward_baseline": "pid"})
    refs, weights, plants = validation_set(settings, policy.settings())
    pid = [o.metrics["cost"] for o in run_episodes(None, policy.settings(), refs, weights, plants)]
    curve = read_rows(out / "learning_curve.csv")
    assert numeric(curve[0]["pid_cost_mean"]) == np.mean(pid)


@pytest.mark.slow
def test_eval_summarises_a_configuration_over_its_seeds(trained, tmp_path):
    """Oracle: a configuration's ratio of means pools its seeds' rows, recomputed with numpy."""
    other = tmp_path / "seed4"
    main(["rl", "train", "--steps", "240", "--seed", "4", "--evaluations", "2", "--checkpoints", "2",
          "--validation", "4", "--out", str(other), "--no-progress"])
    paths = [trained / "policy.zip", other / "policy.zip", trained / "best.zip", other / "best.zip"]
    report = evaluate(paths, families=("nominal",), scenarios=6, seed=7, reps=20, out=tmp_path / "eval",
                      protocol="v1")
    rows = read_rows(report.csv)
    ref = np.array([numeric(r["cost"]) for r in rows if r["method"] == "cubic+PID"])
    lines = report.table.splitlines()[2:]
    assert [line.split(" | ")[0:2] for line in lines[1:]] == [["| cubic+PID+residual SAC (6 N m)", "2"],
                                                              ["| cubic+PID+residual SAC (6 N m) best", "2"]]
    for line, members in zip(lines[1:], [[0, 1], [2, 3]], strict=True):
        costs = np.stack([[numeric(r["cost"]) for r in rows if r["policy"] == str(paths[i])] for i in members])
        assert line.split(" | ")[2].split(" [")[0] == f"{costs.mean() / ref.mean():.3g}"


@pytest.mark.slow
def test_tensorboard_logs_the_validation_curve(tmp_path):
    """The event files carry every validation point of learning_curve.csv (read back with TensorBoard's reader)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out, logs = tmp_path / "run", tmp_path / "tb"
    assert main(["rl", "train", "--steps", "240", "--seed", "2", "--evaluations", "2", "--checkpoints", "2",
                 "--validation", "4", "--out", str(out), "--tensorboard", str(logs), "--no-progress"]) == 0
    (folder,) = [p for p in logs.iterdir() if p.is_dir()]
    events = EventAccumulator(str(folder))
    events.Reload()
    logged = events.Scalars("validation/cost_mean")
    curve = read_rows(out / "learning_curve.csv")
    assert [e.step for e in logged] == [int(r["timesteps"]) for r in curve]
    np.testing.assert_allclose([e.value for e in logged], [numeric(r["val_cost_mean"]) for r in curve], rtol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("which", [0, -1])  # a recurrent policy on running statistics; a SAC on fixed scales
def test_a_policy_whose_spaces_this_numpy_cannot_unpickle_loads_from_its_record(monkeypatch, which):
    """Under numpy 1.x the spaces a numpy-2 SB3 zip pickled raise ImportError (numpy._core): load_policy rebuilds
    them from the run's record (the spaces the model was built with) and the policy acts exactly as the normal
    load's."""
    import mjtraj.rl.policy as policy_module
    from mjtraj.rl.baselines import baseline_names, baseline_path

    path = [baseline_path(n) for n in baseline_names() if baseline_path(n).suffix == ".zip"][which]
    normal = policy_module.load_policy(path)
    real = policy_module.algorithm

    class Picky:
        def __init__(self, algo):
            self.cls = real(algo)

        def load(self, path, **kwargs):
            if "observation_space" not in kwargs.get("custom_objects", {}):
                raise ModuleNotFoundError("No module named 'numpy._core'")
            return self.cls.load(path, **kwargs)

    monkeypatch.setattr(policy_module, "algorithm", Picky)
    rebuilt = policy_module.load_policy(path)
    obs = np.random.default_rng(0).normal(size=(5, normal.model.observation_space.shape[0]))
    np.testing.assert_array_equal(rebuilt.act(obs), normal.act(obs))
    assert rebuilt.model.observation_space == normal.model.observation_space


def test_rl_baselines_lists_each_shipped_policy_with_its_checkpoint(capsys):
    """One line per shipped baseline, naming the checkpoint's steps out of the run's (its record's own numbers)."""
    from mjtraj.rl.baselines import baseline_names, baseline_path
    from mjtraj.rl.batched_policy import load_batched

    assert main(["rl", "baselines"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(baseline_names()) > 0
    for line, name in zip(lines, baseline_names(), strict=True):
        path = baseline_path(name)
        if path.suffix == ".npz":  # a plan: its name and seed, no checkpoint
            from mjtraj.rl.plan_policy import load_plan

            plan = load_plan(path)
            assert line.startswith(f"baseline:{name}  plan tracked ") and "checkpoint" not in line
            assert f"seed {plan.record['settings']['seed']}" in line
            continue
        if path.suffix == ".pt":  # a batched run's module carries its record
            record = load_batched(path).record
            steps = record["settings"]["steps"]
        else:
            record = json.loads((path.parent / "policy.json").read_text())
            steps = record["run"]["settings"]["steps"]
        assert line.startswith(f"baseline:{name}  ")
        assert f"the checkpoint at {record['timesteps']:,} of {steps:,} trained steps" in line


@pytest.mark.slow
@pytest.mark.parametrize("name", ["rppo_act_100k_s2", "sac_act_history4_100k_s3"])
def test_a_baseline_loads_to_act_without_building_an_optimiser(name, monkeypatch):
    """Oracle: SB3's own load (optimisers built) acts the same, bit for bit, on the same observations; with every
    torch optimiser's construction made to fail, mjtraj's load still succeeds (acting needs none)."""
    import torch

    from mjtraj.rl.baselines import baseline_path
    from mjtraj.rl.extra import algorithm
    from mjtraj.rl.policy import TRAINING_STATE

    path = baseline_path(name)
    record = json.loads((path.parent / "policy.json").read_text())
    reference = algorithm(record["run"]["settings"]["algo"]).load(path, device="cpu",
                                                                   custom_objects=dict.fromkeys(TRAINING_STATE))

    def refuse(self, *args, **kwargs):
        raise AssertionError("an optimiser was built")

    monkeypatch.setattr(torch.optim.Optimizer, "__init__", refuse)
    policy = load_policy(path)
    obs = np.random.default_rng(0).normal(size=(5, policy.normalization.mean.size)).astype(np.float32)
    mine = policy.model.predict(obs, deterministic=True)[0]
    theirs = reference.predict(obs, deterministic=True)[0]
    np.testing.assert_array_equal(mine, theirs)
    model = policy.model
    optimizer = model.policy.optimizer if hasattr(model.policy, "optimizer") else model.actor.optimizer
    with pytest.raises(InvalidInputError, match=r"^policy: loaded to act"):
        optimizer.step()


@pytest.mark.slow
def test_a_batched_run_ships_as_a_baseline_that_acts_as_its_run(tmp_path, monkeypatch, capsys):
    """Oracle: the run's own best.pt. `rl ship` of a batched run writes policy.pt, run.json and the curve; as
    baseline:NAME it loads (listed, described) and acts as the run's module, bit for bit; `rl baselines` says what
    it is."""
    import torch

    from mjtraj.rl import baselines
    from mjtraj.rl.adapters import load_any
    from mjtraj.rl.batched import train_batched
    from mjtraj.rl.batched_policy import BatchedSettings, load_batched

    run = tmp_path / "run"
    train_batched(BatchedSettings(steps=96, num_envs=6, rollouts=8, evaluations=2, validation=2, seed=3), run,
                  progress=False)
    folder = tmp_path / "baselines"
    assert main(["rl", "ship", str(run), "--name", "ppo_tiny", "--into", str(folder)]) == 0
    assert sorted(p.name for p in (folder / "ppo_tiny").iterdir()) == ["learning_curve.csv", "learning_curve.png",
                                                                     "policy.pt", "run.json"]
    monkeypatch.setattr(baselines, "baselines_folder", lambda: folder)
    assert baselines.baseline_names() == ["ppo_tiny"]
    capsys.readouterr()
    assert main(["rl", "baselines"]) == 0
    assert capsys.readouterr().out.startswith("baseline:ppo_tiny  PPO (BATCHED) seed 3, the checkpoint at ")
    policy = load_any("baseline:ppo_tiny")
    mine = load_batched(run / "best.pt")
    obs = np.random.default_rng(2).normal(size=(4, mine.mean.numel()))
    with torch.no_grad():
        expected = mine(torch.as_tensor(obs, dtype=torch.float32)).numpy().astype(np.float64)
    np.testing.assert_array_equal(policy.act(obs), expected)
    assert json.dumps(policy.record) == json.dumps(mine.record)  # (NaN where no episode had ended)
    assert policy.source == "baseline:ppo_tiny" and len(policy.sha256) == 64


def test_a_callable_that_declares_its_training_streams_is_held_to_them():
    """`policy.streams`: a callable that trained on the seed stream of nominal scenario 4 under seed 3 is refused
    there, scored elsewhere; a declaration that is not a list of seeds is refused in one line."""
    from mjtraj.rl.adapters import from_object

    def policy(obs):
        return np.zeros(3)

    policy.streams = [[3, 0, 4], 17]  # type: ignore[attr-defined]
    scored = from_object(policy)
    with pytest.raises(InvalidInputError, match=r"^seed: 1 of the nominal scenarios under seed 3 share a seed stream "
                                                r"with the streams .* declares it trained on"):
        check_held_out(scored, "nominal", 3, 10)
    check_held_out(scored, "nominal", 3, 4)  # scenarios 0..3: not 4
    check_held_out(scored, "aggressive", 3, 10)
    policy.streams = "seed 3"  # type: ignore[attr-defined]
    with pytest.raises(InvalidInputError, match=r"^policy: its streams attribute must be a list of seeds"):
        from_object(policy)
