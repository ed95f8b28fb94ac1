"""The plan policy (mjtraj.rl.plan_policy) and its fit (mjtraj.rl.plan_train), against oracles: the task the
observation encodes, the pipeline's computed-torque law with the anchor, `mpc`'s own execution, a known function."""

from __future__ import annotations

import dataclasses
import json

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401 - registers the envs
from mjtraj.core.settle import Settle
from mjtraj.domain.pipeline import Job, execute_batch
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.adapters import load_any
from mjtraj.rl.evaluate import check_held_out
from mjtraj.rl.plan_policy import PLAN_ENV, PlanNetwork, PlanPolicy, held_cubic, load_plan, save_plan, task_of
from mjtraj.rl.plan_tracker import Tracker
from mjtraj.rl.plan_train import Labels, PlanSettings, env_settings, fit, label, train_plan

WINDOW = 0.5


def _zero_network(inputs: int = 49, outputs: int = 9) -> PlanNetwork:
    return PlanNetwork([(np.zeros((inputs, outputs)), np.zeros(outputs))], np.zeros(inputs), np.ones(inputs))


def _episode(policy: PlanPolicy, family: str, seed: int) -> tuple[dict, np.ndarray, float]:
    """The policy's whole episode in UR5Track-v2 (PLAN_ENV): the task, the visited positions (N + S + 1, n) and the
    episode's J_settle."""
    env = gym.make_vec("UR5Track-v2", num_envs=1, vectorization_mode="vector_entry_point", family=family,
                       **{k: v for k, v in policy.env.items() if k != "planner"})
    obs, info = env.reset(seed=seed)
    task = {k: v[0] for k, v in info["task"].items()}
    policy.reset(np.ones(1, dtype=bool))
    q = [obs[0, :3]]
    while True:
        obs, _, terminated, truncated, info = env.step(policy(obs))
        q.append(obs[0, :3])  # the ending step returns the final observation (autoreset on the next step)
        if terminated[0] or truncated[0]:
            cost = float(info["metrics"]["cost"][0])  # J_settle in an episode with a settle window
            break
    env.close()
    return task, np.array(q), cost


def test_the_task_read_from_the_first_observation_is_the_episodes():
    """task_of: q0 exactly, the goal within 1e-9 rad of the env's (info["task"]), the duration exactly, on tasks of
    every family (the aggressive family's durations vary)."""
    for family, seed in (("nominal", 3), ("aggressive", 4), ("mismatch", 5)):
        env = gym.make_vec("UR5Track-v2", num_envs=1, vectorization_mode="vector_entry_point", family=family,
                           **{k: v for k, v in PLAN_ENV.items() if k != "planner"})
        obs, info = env.reset(seed=seed)
        env.close()
        task = task_of(obs[0], 3, 0.02)
        np.testing.assert_array_equal(task.q0, info["task"]["q0"][0])
        np.testing.assert_allclose(task.qg, info["task"]["qg"][0], rtol=0, atol=1e-9)
        assert task.duration == info["task"]["duration"][0]


def test_zero_offsets_command_computed_torque_with_the_anchor_as_the_pipeline_runs_it():
    """With a network that outputs zeros and the computed_torque tracker the plan is the held cubic, and the
    episode the env runs under the policy is the one the pipeline runs with its computed-torque law and an actor
    adding -d (mpc_filter's estimate): the same positions to 1e-8 rad at every period (the policy reads the goal
    from the observation, to 1e-9 rad), and the same score to 1e-6."""
    from envs.core import disturbance_estimate

    settings = env_settings(WINDOW)
    policy = PlanPolicy(_zero_network(), {"window_steps": settings.settle_steps},
                        tracker=Tracker.of_rule("computed_torque"))
    task_info, q_env, cost_env = _episode(policy, "nominal", 11)
    task = _task(task_info)
    target = held_cubic(task, settings.planner, settings.model, settings.settle_steps)

    class Anchor:
        shadows = ("mpc_filter",)
        action_mode = "residual"

        def begin(self, loop, refs, perts):
            pass

        def act(self, loop):
            return -disturbance_estimate(loop)

    loop = dataclasses.replace(settings.loop, controller="computed_torque")
    rollout, outcomes = execute_batch(settings.model, loop, [Job(target, settings.weights(task), None, None,
                                                                 Settle.of(task, task.steps, settings.settle_steps))],
                                      actor=Anchor())
    q_pipe = np.concatenate([rollout.q[0], rollout.q_final])
    np.testing.assert_allclose(q_env, q_pipe, rtol=0, atol=1e-8)
    assert cost_env == pytest.approx(outcomes[0].metrics["cost"], rel=1e-6)


def _task(info: dict):
    from mjtraj.core.task import Task

    return Task(np.asarray(info["q0"]), np.asarray(info["qg"]), float(info["duration"]), 0.02)


def test_mpcs_own_execution_as_the_plan_reproduces_mpcs_score():
    """The oracle plan: `mpc`'s nominal execution of the episode's task (the labels `label` makes, times the move
    squared) tracked by the policy with the computed_torque tracker (which holds to the plan the tighter) scores
    `mpc`'s J_settle within 0.5 % and ends inside the settling band, on a nominal and an aggressive task."""
    settings = env_settings(WINDOW)

    class Oracle(PlanPolicy):
        def offsets(self, task, target):
            labels = label(PlanSettings(), tasks=[task])
            self.mpc_cost = float(labels.cost[0])
            return labels.y * np.max(np.abs(task.qg - task.q0)) ** 2

    for family, seed in (("nominal", 1), ("aggressive", 2)):
        policy = Oracle(_zero_network(), {"window_steps": settings.settle_steps},
                        tracker=Tracker.of_rule("computed_torque"))
        task_info, q, cost = _episode(policy, family, seed)
        assert cost == pytest.approx(policy.mpc_cost, rel=5e-3)
        settle = Settle.of(_task(task_info), 0, settings.settle_steps)
        assert np.abs(q[-1] - settle.goal).max() < settle.band  # ends inside the band, as mpc's execution does


def test_the_lqr_tracker_follows_a_tapered_plan_with_its_gains_to_the_goal_at_rest():
    """The default tracker: the plan's gain columns are Tracker().gains for the task (the score's weights, the mass
    matrix at q0); the tapered plan is the held cubic plus the offsets until the motion's end and ends at the goal
    with zero velocity and acceleration (with a network whose offsets are not zero); and the env's episode under it
    on an aggressive task (the nominal plant) ends at rest inside the band, the anchor's estimate exactly 0 at every
    period."""
    from mjtraj.core import DynamicsProbe

    settings = env_settings(WINDOW)
    rng = np.random.default_rng(3)
    network = PlanNetwork([(rng.normal(size=(49, 9)) * 1e-3, rng.normal(size=9) * 1e-2)], np.zeros(49),
                          np.full(49, 10.0))
    policy = PlanPolicy(network, {"window_steps": settings.settle_steps, "tracker": Tracker().as_dict()})
    task = _task({"q0": [0.1, -1.0, 1.2], "qg": [0.5, -0.7, 0.9], "duration": 0.6})
    plan = policy.plan(task)
    target = held_cubic(task, settings.planner, settings.model, settings.settle_steps)
    mass = DynamicsProbe(settings.model).mass_and_bias(task.q0[None], np.zeros((1, 3)))[0][0]
    kp, kd = Tracker().gains(settings.weights(task), mass, task.steps, settings.settle_steps, settings.dt)
    np.testing.assert_array_equal(plan[:, 9:12], kp)
    np.testing.assert_array_equal(plan[:, 12:], kd)
    raw = policy.offsets(task, target)
    motion = slice(0, task.steps + 1)
    np.testing.assert_allclose(plan[motion, :3] - target.q[motion], raw[motion, :3], rtol=0, atol=1e-15)
    assert np.abs(raw[-1]).max() > 1e-3  # the taper has something to remove
    np.testing.assert_allclose(plan[-1, :3], task.qg, rtol=0, atol=1e-15)
    assert np.all(plan[-1, 3:9] == 0.0)
    assert policy.observer is not None
    estimates, estimate = [], policy.observer.estimate
    policy.observer.estimate = lambda q, qd: estimates.append(estimate(q, qd)) or estimates[-1]  # type: ignore
    task_info, q, _ = _episode(policy, "aggressive", 2)
    settle = Settle.of(_task(task_info), 0, settings.settle_steps)
    assert np.abs(q[-1] - settle.goal).max() < settle.band
    assert len(estimates) == len(q) - 1 and not np.any(np.concatenate(estimates))


def test_a_fit_recovers_a_known_smooth_function():
    """fit: labels that are a smooth function of the features (sines of linear maps), uniform weights: the loss ends
    below 1 % of the zero plan's, and the saved network (NumPy) gives the torch fit's outputs."""
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, size=(2000, 5))
    a = rng.normal(size=(5, 9))
    y = np.sin(x @ a) * 0.5
    labels = Labels(x, y, np.ones_like(y), np.array([0, 2000]), np.ones(1), np.zeros(1, dtype=np.intp))
    network, losses = fit(labels, PlanSettings(epochs=60, batch=64, hidden=(64, 64), learning_rate=3e-3,
                                               weighting="family"))
    assert losses[-1] < 0.01 < losses[0]
    assert np.mean((network(x) - y) ** 2) / np.mean(y ** 2) < 0.01


def test_a_plan_policy_file_loads_as_saved_and_scores_through_rl_eval(tmp_path):
    """save_plan, load_plan: the network's outputs bit for bit and the record; load_any reads PATH.npz as a plan
    policy acting in PLAN_ENV whose sha256 covers the file."""
    rng = np.random.default_rng(1)
    layers = [(rng.normal(size=(49, 8)), rng.normal(size=8)), (rng.normal(size=(8, 9)), rng.normal(size=9))]
    network = PlanNetwork(layers, rng.normal(size=49), rng.uniform(1, 2, size=49))
    record = {"window_steps": 25, "dt": 0.02, "label": "test", "streams": [[0, 16, 0]]}
    save_plan(network, record, tmp_path / "policy.npz")
    loaded = load_plan(tmp_path / "policy.npz")
    x = rng.normal(size=(4, 49))
    np.testing.assert_array_equal(loaded.network(x), network(x))
    assert loaded.record["label"] == "test" and loaded.streams == [[0, 16, 0]]
    scored = load_any(str(tmp_path / "policy.npz"))
    assert scored.env["action_mode"] == "torque" and scored.env["observe_task"] is True
    assert not scored.env.get("observe_disturbance")  # the default tracker's anchor is its own (mpc_filter's is not)
    first = scored.sha256
    save_plan(PlanNetwork([(w * 2, b) for w, b in network.layers], network.mean, network.std), record,
              tmp_path / "policy.npz")
    assert load_any(str(tmp_path / "policy.npz")).sha256 != first
    (tmp_path / "bad.npz").write_bytes(b"not a file")
    with pytest.raises(InvalidInputError, match=r"^policy: .*bad.npz is not a plan policy file"):
        load_plan(tmp_path / "bad.npz")


def test_a_plan_file_keeps_its_tracker_and_one_of_format_1_keeps_computed_torque(tmp_path):
    """A file's record names its tracker (the default when it names none; fields it lacks as they were before they
    existed); a file of format 1 (written before trackers) is tracked as it was, by CT_RULE's gains without the
    taper; a bad tracker, or an end segment longer than the window, is refused by name."""
    save_plan(_zero_network(), {"window_steps": 25, "dt": 0.02, "tracker": Tracker().as_dict()},
              tmp_path / "default.npz")
    assert load_plan(tmp_path / "default.npz").tracker == Tracker()
    save_plan(_zero_network(), {"window_steps": 25, "dt": 0.02}, tmp_path / "none.npz")
    assert load_plan(tmp_path / "none.npz").tracker == Tracker()
    lacking = {k: v for k, v in Tracker().as_dict().items() if k not in ("end_boost", "end_periods")}
    save_plan(_zero_network(), {"window_steps": 25, "dt": 0.02, "tracker": lacking}, tmp_path / "lacking.npz")
    assert load_plan(tmp_path / "lacking.npz").tracker == dataclasses.replace(Tracker(), end_periods=0)
    with pytest.raises(InvalidInputError, match=r"^end_periods: expected at most the settle window's 5 periods, got 8"):
        PlanPolicy(_zero_network(), {"window_steps": 5, "tracker": Tracker().as_dict()})
    ct = Tracker.of_rule("computed_torque")
    save_plan(_zero_network(), {"window_steps": 25, "dt": 0.02, "tracker": ct.as_dict()}, tmp_path / "ct.npz")
    assert load_plan(tmp_path / "ct.npz").tracker == ct
    old = {"window_steps": 25, "dt": 0.02, "format": "mjtraj-plan-policy/1"}
    np.savez(tmp_path / "old.npz", **_zero_network().arrays(), record=np.array(json.dumps(old)))
    assert load_plan(tmp_path / "old.npz").tracker == ct
    save_plan(_zero_network(), {"window_steps": 25, "dt": 0.02, "tracker": {"rule": "pid"}}, tmp_path / "bad.npz")
    with pytest.raises(InvalidInputError, match=r"^policy: .*bad.npz is not a plan policy file .*tracker: "):
        load_plan(tmp_path / "bad.npz")


def test_rl_eval_refuses_a_plan_policy_on_the_streams_it_trained_on(tmp_path):
    """A plan policy declares its training streams; scored on a scenario drawn from one of them it is refused (the
    oracle: a record naming the nominal family's scenario 2 under seed 5; `mjtraj rl plan` trains on TRAIN_STREAM,
    which no evaluation draws from, so for its own files this is a safeguard)."""
    record = {"window_steps": 25, "dt": 0.02, "label": "test", "streams": [[5, 0, 2]]}
    save_plan(_zero_network(), record, tmp_path / "policy.npz")
    scored = load_any(str(tmp_path / "policy.npz"))
    check_held_out(scored, "nominal", 5, 2)  # scenarios 0 and 1: apart
    with pytest.raises(InvalidInputError, match=r"^seed: 1 of the nominal scenarios under seed 5 share a seed stream"):
        check_held_out(scored, "nominal", 5, 3)


def test_plan_settings_refuse_bad_values_by_name():
    for kwargs, pattern in (({"tasks": 0}, r"^tasks: expected a whole number >= 1, got 0$"),
                            ({"families": ("nominal", "noisy")}, r"^families: "),
                            ({"families": ()}, r"^families: expected at least one"),
                            ({"hidden": (8, 0)}, r"^hidden: expected layer widths >= 1"),
                            ({"learning_rate": -1.0}, r"^learning_rate: "),
                            ({"seed": -1}, r"^seed: ")):
        with pytest.raises(InvalidInputError, match=pattern):
            PlanSettings(**kwargs)


def test_a_run_reuses_its_labels_and_refuses_another_runs(tmp_path):
    """train_plan on a folder with labels of the same task settings fits again without labelling (the same
    labels, so the same policy bit for bit: the fit is seeded); labels of other settings are refused by name."""
    settings = PlanSettings(families=("nominal",), tasks=2, epochs=2, hidden=(8,))
    first = train_plan(settings, tmp_path, progress=False)
    saved = (tmp_path / "labels.npz").stat().st_mtime_ns
    again = train_plan(settings, tmp_path, progress=False)
    assert (tmp_path / "labels.npz").stat().st_mtime_ns == saved
    assert again.record["seconds"]["labels"] == first.record["seconds"]["labels"]
    x = np.random.default_rng(2).normal(size=(3, 49))
    np.testing.assert_array_equal(load_plan(first.policy).network(x), load_plan(again.policy).network(x))
    assert json.loads((tmp_path / "run.json").read_text())["samples"] == first.record["samples"]
    with pytest.raises(InvalidInputError, match=r"^out: .*labels.npz holds labels of other settings"):
        train_plan(PlanSettings(families=("nominal",), tasks=3, epochs=2, hidden=(8,)), tmp_path, progress=False)


def test_a_run_with_another_tracker_reuses_the_fit_and_one_with_another_fit_fits_again(tmp_path):
    """train_plan on a folder whose policy was fitted with the same fit settings rewrites only the policy: the same
    network bit for bit (and the first fit's seconds and command) with the new tracker; other fit settings (epochs)
    fit again."""
    settings = PlanSettings(families=("nominal",), tasks=2, epochs=2, hidden=(8,))
    first = train_plan(settings, tmp_path, progress=False, command="first")
    assert first.record["tracker"] == Tracker().as_dict() and load_plan(first.policy).tracker == Tracker()
    network = load_plan(first.policy).network
    retracked = train_plan(dataclasses.replace(settings, tracker="computed_torque", workers=2), tmp_path,
                           progress=False, command="second")
    loaded = load_plan(retracked.policy)
    assert loaded.tracker == Tracker.of_rule("computed_torque")
    for (w, b), (w0, b0) in zip(loaded.network.layers, network.layers, strict=True):
        np.testing.assert_array_equal(w, w0)
        np.testing.assert_array_equal(b, b0)
    assert retracked.record["seconds"] == first.record["seconds"] and retracked.record["fit_command"] == "first"
    refit = train_plan(dataclasses.replace(settings, epochs=3), tmp_path, progress=False, command="third")
    assert refit.record["fit_command"] == "third" and len(refit.record["loss"]) == 3


def test_a_plan_run_ships_as_a_baseline_that_plans_as_its_run(tmp_path, monkeypatch, capsys):
    """Oracle: the run's own policy.npz. `rl ship` of a plan run writes policy.npz and run.json; as baseline:NAME it
    is listed and described by its name and seed, loads with the run file's bits (sha256) and plans as the run's
    policy, bit for bit; a folder without run.json is refused by name."""
    import shutil

    from mjtraj.cli import main
    from mjtraj.core import Task
    from mjtraj.rl import baselines

    run = tmp_path / "run"
    train_plan(PlanSettings(families=("nominal",), tasks=2, epochs=2, hidden=(8,), seed=3), run, progress=False)
    folder = tmp_path / "baselines"
    assert main(["rl", "ship", str(run), "--name", "plan_tiny", "--into", str(folder)]) == 0
    assert sorted(p.name for p in (folder / "plan_tiny").iterdir()) == ["policy.npz", "run.json"]
    monkeypatch.setattr(baselines, "baselines_folder", lambda: folder)
    assert baselines.baseline_names() == ["plan_tiny"]
    capsys.readouterr()
    assert main(["rl", "baselines"]) == 0
    mine = load_plan(run / "policy.npz")
    listed = capsys.readouterr().out
    assert listed.startswith("baseline:plan_tiny  plan tracked with LQR gains (task weighting, 2 tasks, 2 epochs")
    assert listed.count("\n") == 1 and "seed 3" in listed and "checkpoint" not in listed
    shipped = load_any("baseline:plan_tiny")
    assert shipped.source == "baseline:plan_tiny" and shipped.sha256 == load_any(str(run / "policy.npz")).sha256
    task = Task(np.array([0.2, -1.1, 1.3]), np.array([0.6, -0.8, 1.0]), 0.9, mine.dt)
    np.testing.assert_array_equal(load_plan(folder / "plan_tiny" / "policy.npz").plan(task), mine.plan(task))
    (tmp_path / "bare").mkdir()
    shutil.copyfile(run / "policy.npz", tmp_path / "bare" / "policy.npz")
    with pytest.raises(InvalidInputError, match=r"^run: .*run.json not found; expected a folder of rl plan"):
        baselines.ship(tmp_path / "bare", "plan_bare", into=folder)
    with pytest.raises(InvalidInputError, match=r"^student: .* is a plan run"):
        baselines.ship(run, "plan_student", into=folder, student=True)
    (folder / "older").mkdir()
    (folder / "older" / "policy.zip").write_bytes(b"an earlier baseline")
    with pytest.raises(InvalidInputError, match=r"^name: baseline 'older' already holds policy.zip"):
        baselines.ship(run, "older", into=folder)
    assert sorted(p.name for p in (folder / "older").iterdir()) == ["policy.zip"]  # nothing written beside it
    with pytest.raises(InvalidInputError, match=r"^window: expected a settle window of at least the tracker's 8"):
        train_plan(PlanSettings(families=("nominal",), tasks=2, epochs=2, hidden=(8,), window=0.1),
                   tmp_path / "short", progress=False)
    assert not (tmp_path / "short").exists()


def test_labels_do_not_depend_on_the_workers_that_make_them():
    """label with two processes gives one process's labels bit for bit (the chunks are run alike)."""
    one = label(PlanSettings(families=("nominal", "aggressive"), tasks=2, workers=1))
    two = label(PlanSettings(families=("nominal", "aggressive"), tasks=2, workers=2))
    for name in ("x", "y", "w", "starts", "cost", "family"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))
    assert one.family.tolist() == [0, 0, 1, 1]


def test_a_plan_policy_is_timed_on_its_own_episodes():
    """policy_compute with an observer: the policy gets the observations of the law's execution, each reference an
    episode it starts (the oracle: on zeros its task cannot be read and it raises), and is timed on every period of
    each, the estimators it observes with it."""
    from mjtraj.envs import Observer

    from mjtraj.exceptions import PolicyError
    from mjtraj.rl.compute import policy_compute

    settings = env_settings(WINDOW)
    policy = PlanPolicy(_zero_network(), {"window_steps": settings.settle_steps})
    with pytest.raises(PolicyError, match=r"^plan policy: an episode's first observation must be at phase 0"):
        policy(np.zeros((1, settings.obs_size)))
    tasks = [_task({"q0": [0.1, -1.0, 1.2], "qg": [0.5, -0.7, 0.9], "duration": d}) for d in (1.0, 0.6)]
    references = [held_cubic(t, settings.planner, settings.model, settings.settle_steps) for t in tasks]
    compute = policy_compute(policy, settings.obs_size, shadows=settings.shadows(), config=settings.loop,
                             model=settings.model, references=references, observer=Observer(settings, 1),
                             reset=policy.reset)
    assert compute.samples == sum(t.steps + settings.settle_steps for t in tasks)
    assert compute.what == "inference, batch 1, on its episodes"  # its anchor is its own: no estimator observed
    assert 0 < compute.median_ms <= compute.p99_ms


def test_a_fits_name_is_its_configuration_without_the_seed():
    """configuration: fits that differ only in their seed share a name (so rl eval pools them as seeds); any other
    setting that shapes the policy shows."""
    from mjtraj.rl.plan_train import configuration

    assert configuration(PlanSettings(seed=3)) == configuration(PlanSettings(seed=4)) == (
        "task weighting, 2000 tasks, 160 epochs")
    assert configuration(PlanSettings(weighting="family", hidden=(64, 64), families=("nominal",),
                                      tracker="computed_torque")) == (
        "family weighting, 2000 tasks, 160 epochs, families nominal, hidden 64/64")


def test_the_weightings_divide_by_each_tasks_cost_and_samples_or_by_its_familys_mean_cost():
    """Labels.weights on two tasks by hand: task, the score's weights over the task's J_settle and samples; family,
    over the family's mean J_settle; each over its mean."""
    w = np.array([[1.0, 2.0], [1.0, 2.0], [3.0, 3.0], [4.0, 4.0], [4.0, 4.0], [4.0, 4.0]])
    labels = Labels(np.zeros((6, 1)), np.zeros((6, 2)), w, np.array([0, 2, 3, 6]), np.array([2.0, 4.0, 8.0]),
                    np.array([0, 0, 1]))
    task = w / np.array([[4.0], [4.0], [4.0], [24.0], [24.0], [24.0]])
    family = w / np.array([[3.0], [3.0], [3.0], [8.0], [8.0], [8.0]])
    np.testing.assert_allclose(labels.weights("task"), task / task.mean(), rtol=1e-15)
    np.testing.assert_allclose(labels.weights("family"), family / family.mean(), rtol=1e-15)


def test_fits_of_one_configuration_pool_as_seeds_in_rl_eval(tmp_path):
    """Two plan policy files of one configuration and tracker and other seeds are one configuration of two seeds in
    rl eval; one of another configuration is its own, and so is one of the same configuration with another tracker
    (a file of format 1; a file whose tracker departs from its rule's in one field, named in the name)."""
    from mjtraj.rl.evaluate import _labels, configurations

    task, family = "task weighting, 2000 tasks, 200 epochs", "family weighting, 2000 tasks, 200 epochs"
    trackers = {"a": Tracker(), "b": Tracker(), "c": Tracker(), "e": Tracker(end_periods=0)}
    for name, named in (("a", task), ("b", task), ("c", family), ("e", task)):
        (tmp_path / name).mkdir()
        save_plan(_zero_network(), {"window_steps": 25, "dt": 0.02, "label": named,
                                    "tracker": trackers[name].as_dict()}, tmp_path / name / "policy.npz")
    old = {"window_steps": 25, "dt": 0.02, "label": task, "format": "mjtraj-plan-policy/1"}
    (tmp_path / "d").mkdir()
    np.savez(tmp_path / "d" / "policy.npz", **_zero_network().arrays(), record=np.array(json.dumps(old)))
    loaded = [load_any(str(tmp_path / name / "policy.npz")) for name in "abcde"]
    groups = configurations(loaded, _labels(loaded))
    assert sorted(len(v) for v in groups.values()) == [1, 1, 1, 2]  # another tracker: apart
    assert "plan tracked with LQR gains (task weighting, 2000 tasks, 200 epochs)" in groups
    assert "plan tracked with LQR gains, end_periods 0 (task weighting, 2000 tasks, 200 epochs)" in groups
    assert "plan tracked by computed torque (task weighting, 2000 tasks, 200 epochs)" in groups


def test_each_periods_command_uses_the_gains_of_its_own_sample():
    """Alignment of plan samples and gains: two policies alike but for the gains of one sample k (ten times larger in
    one copy) command the same torque at every period of an episode up to k, and another one at period k."""
    settings = env_settings(WINDOW)
    k = 7

    class Spiked(PlanPolicy):
        def plan(self, task):
            plan = super().plan(task)
            plan[k, 3 * self.n:] *= 10.0
            return plan

    rng = np.random.default_rng(4)
    network = PlanNetwork([(rng.normal(size=(49, 9)) * 1e-3, rng.normal(size=9) * 1e-2)], np.zeros(49),
                          np.full(49, 10.0))
    plain, spiked = PlanPolicy(network, {"window_steps": settings.settle_steps}), Spiked(
        network, {"window_steps": settings.settle_steps})
    env = gym.make_vec("UR5Track-v2", num_envs=1, vectorization_mode="vector_entry_point", family="nominal",
                       **{key: v for key, v in plain.env.items() if key != "planner"})
    obs, _ = env.reset(seed=6)
    plain.reset(np.ones(1, dtype=bool))
    spiked.reset(np.ones(1, dtype=bool))
    for period in range(k + 1):
        action, other = plain(obs), spiked(obs)
        if period < k:
            np.testing.assert_array_equal(action, other)
        else:
            assert np.abs(action - other).max() > 0.0
        obs, *_ = env.step(action)
    env.close()
