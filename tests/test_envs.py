"""UR5Track-v0: registration, Gymnasium contract, the env is compare's closed loop, vector == single, bad input."""

from __future__ import annotations

import inspect
import os
import re
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from mjtraj.envs import BENCHMARK_VARIANTS
from mjtraj.envs.settings import ACTION_MODES, argument_defaults
from mjtraj.envs.ur5_track import UR5TrackEnv
from mjtraj.envs.vector import UR5TrackVectorEnv

from mjtraj.core import LoopConfig, option_names
from mjtraj.core.metrics import METRIC_NAMES
from mjtraj.core.model import JointInfo
from mjtraj.exceptions import InvalidInputError
from mjtraj.study.comparison import compare


def episode(env, *, seed=None, actions=None):
    """Run one episode; (observations, rewards, last info)."""
    obs, _ = env.reset(seed=seed)
    observations, rewards = [obs], []
    k = 0
    while True:
        action = env.action_space.sample() if actions is None else actions[k]
        obs, reward, terminated, truncated, info = env.step(action)
        observations.append(obs)
        rewards.append(reward)
        k += 1
        if terminated or truncated:
            return np.array(observations), np.array(rewards), info



def test_registered_and_the_episode_follows_the_duration():
    spec = gym.spec("UR5Track-v0")
    assert spec.max_episode_steps is None  # the env ends its episodes itself, after N = duration/dt steps
    for duration, steps in ((2.0, 100), (3.0, 150)):
        env = gym.make("UR5Track-v0", duration=duration)
        env.reset(seed=0)
        count, done = 0, False
        while not done:
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            done = terminated or truncated
            count += 1
        assert count == steps and terminated and not truncated
        assert env.unwrapped.dt == 0.02


def test_reset_options_run_one_episode_of_that_task(scenario):
    env = UR5TrackEnv(task="random")
    obs, _ = env.reset(seed=0, options={"q0": [0.0, -1.0, 0.5], "qg": [0.5, -1.5, 0.0], "duration": 1.0})
    np.testing.assert_array_equal(obs[:3], [0.0, -1.0, 0.5])
    assert env.reference.steps == 50 and np.allclose(env.reference.q[-1], [0.5, -1.5, 0.0], atol=1e-15)
    env.reset(seed=0)
    assert env.reference.steps == 100  # the next plain reset is the env's own task again
    with pytest.raises(InvalidInputError, match=r"^options: unknown key 'goal'; valid: q0, qg, duration, scenario$"):
        env.reset(options={"goal": [0, 0, 0]})
    with pytest.raises(InvalidInputError, match=r"^options: a random-task env needs both q0 and qg \(rad\)$"):
        env.reset(options={"qg": [0.5, -1.5, 0.0]})
    paper = UR5TrackEnv()
    paper.reset(options={"duration": 1.5})
    np.testing.assert_array_equal(paper.reference.q[0], scenario.task.q0)
    assert paper.reference.steps == 75


@pytest.mark.slow
def test_make_with_module_prefix_needs_no_prior_import():
    code = ("import gymnasium as gym, sys; env = gym.make('mjtraj:UR5Track-v0'); env.reset(seed=1); "
            "print(type(env.unwrapped).__module__, 'envs' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["mjtraj.envs.ur5_track", "False"]  # and nothing named plain `envs` was imported



CHECK_ENV = """
import warnings, gymnasium as gym, mjtraj
from gymnasium.utils.env_checker import check_env
for mode in {modes!r}:
    env = gym.make("UR5Track-v0", action_mode=mode, task="random", preview=2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)  # every declared render mode too, the window ('human') included
    env.close()
print("checked")
"""


@pytest.mark.slow
def test_gymnasium_check_env_without_warnings(display):
    """Gymnasium's checker, warnings as errors, in every action mode; it renders every declared mode, so it runs
    where a window can open (a virtual display, MUJOCO_GL unset: off-screen frames on OSMesa, the window on GLFW)."""
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env["DISPLAY"] = display
    done = subprocess.run([sys.executable, "-c", CHECK_ENV.format(modes=ACTION_MODES)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip() == "checked"



@pytest.mark.parametrize("planner", ["optimal", "cubic", "quintic", "trapezoidal"])
def test_pid_paper_episode_is_compare(planner, scenario):
    """One implementation: the env's episode metrics equal `mjtraj compare`'s, and the return is -J_exec."""
    expected = compare(scenario).metrics[planner]
    env = gym.make("UR5Track-v0", planner=planner)
    _, rewards, info = episode(env, seed=0)
    assert rewards.size == scenario.task.steps
    for name in METRIC_NAMES:
        if name == "rms_tau_total":
            assert np.isnan(info["metrics"][name])  # not measured in the env (a G(q) per recorded pose)
            continue
        assert info["metrics"][name] == pytest.approx(getattr(expected, name), rel=1e-12, abs=1e-12), name
    assert -rewards.sum() == pytest.approx(expected.cost, rel=1e-12)
    assert info["diverged"] is False



def test_reward_terms_and_info(scenario):
    """The reward's two terms are -(x^T Q_exec x) and -(dtau^T R_exec dtau) with the paper scenario's weights, and
    residual mode adds residual_scale a N m (default 6) before the saturation, torque mode 60 a N m."""
    action = np.array([0.5, -0.2, 0.1], dtype=np.float32)
    for kwargs, scale in (({"action_mode": "torque"}, 60.0),
                          ({"action_mode": "residual", "residual_scale": 100}, 100.0),
                          ({"action_mode": "torque", "residual_scale": 3.0}, 60.0)):
        other = UR5TrackEnv(**kwargs)
        other.reset(seed=0)
        _, _, _, _, info = other.step(action)
        base = info["tau_ff"] if kwargs["action_mode"] == "residual" else 0.0
        np.testing.assert_allclose(info["dtau"], np.clip(base + scale * action.astype(float), -60, 60), rtol=0,
                                   atol=1e-12)
    env = UR5TrackEnv(action_mode="residual")
    env.reset(seed=0)
    _, reward, _, _, info = env.step(action)
    e, dtau = info["e"], info["dtau"]
    assert np.array_equal(e, np.zeros(3)) and np.array_equal(scenario.task.q0, env.reference.q[0])
    np.testing.assert_allclose(dtau, np.clip(info["tau_ff"] + 6 * action.astype(float), -60, 60), rtol=0, atol=1e-12)
    assert info["reward_tracking"] == 0.0  # the arm starts on the reference, at rest
    assert info["reward_effort"] == pytest.approx(-np.sum(dtau**2 * scenario.R_exec), rel=1e-14)
    _, reward, _, _, info = env.step(np.zeros(3, dtype=np.float32))  # now the error is not zero
    x = np.concatenate([info["e"], env.unwrapped.reference.qd[1] - env.unwrapped.loop.rollout().qd[0, 1]])
    assert info["reward_tracking"] == pytest.approx(-np.sum(x**2 * scenario.Q_exec), rel=1e-12)
    assert info["reward_tracking"] < 0.0
    assert reward == info["reward_tracking"] + info["reward_effort"]
    assert set(info) == {"tau_ff", "tau_fb", "dtau", "saturated", "e", "reward_tracking", "reward_effort",
                         "reward_baseline"}
    assert info["reward_baseline"] == 0.0  # no baseline unless reward_baseline="controller"
    env.close()


def test_observation_layout():
    env = UR5TrackEnv(preview=2, task="random")
    obs, _ = env.reset(seed=3)
    ref = env.reference
    obs, *_ = env.step(env.action_space.sample())
    q, qd = obs[:3], obs[3:6]
    np.testing.assert_array_equal(obs[6:9], ref.q[1])
    np.testing.assert_array_equal(obs[9:12], ref.qd[1])
    np.testing.assert_array_equal(obs[12:15], ref.q[1] - q)
    np.testing.assert_array_equal(obs[15:18], ref.qd[1] - qd)
    assert obs[18] == 1 / 100
    np.testing.assert_array_equal(obs[19:25], np.concatenate([ref.q[2], ref.qd[2]]))
    np.testing.assert_array_equal(obs[25:31], np.concatenate([ref.q[3], ref.qd[3]]))
    assert obs.shape == env.observation_space.shape == (31,)

@pytest.mark.parametrize("frame", ["relative", "reference"])
def test_a_framed_preview_is_the_reference_ahead_minus_its_origin(frame):
    """preview_frame='relative' gives each preview sample minus the observed (here measured, noisy) q and qd,
    'reference' minus q_ref and qd_ref now, and neither changes anything else; the observations stay inside the
    space."""
    kwargs = {"preview": 2, "task": "random", "measurement_noise": 0.01, "observe_measured": True, "settle": 0.5}
    absolute, framed = UR5TrackEnv(**kwargs), UR5TrackEnv(**kwargs, preview_frame=frame)
    obs_a, _ = absolute.reset(seed=3)
    obs_f, _ = framed.reset(seed=3)
    moving = 0  # periods whose preview differs from the reference now: there the two origins differ
    for _ in range(110):  # through the motion's end into the settle window (the preview held at the goal)
        action = absolute.action_space.sample()
        obs_a, *_ = absolute.step(action)
        obs_f, *_ = framed.step(action)
        origin = obs_a[:6] if frame == "relative" else obs_a[6:12]  # (q, qd) or (q_ref, qd_ref)
        np.testing.assert_array_equal(obs_f[:19], obs_a[:19])
        np.testing.assert_array_equal(obs_f[19:25], obs_a[19:25] - origin)
        np.testing.assert_array_equal(obs_f[25:31], obs_a[25:31] - origin)
        assert framed.observation_space.contains(obs_f)
        moving += not np.allclose(obs_a[6:9], obs_a[19:22], rtol=0, atol=1e-6)
    assert not np.allclose(obs_a[:3], absolute.loop.positions[0], rtol=0, atol=1e-4)  # both observe the noise
    assert moving > 50


def test_observe_refuses_an_unknown_frame():
    """`observe`'s frame was a bool (relative) before the reference frame: an old call's True is refused by name
    rather than read as another frame."""
    from mjtraj.envs import observe

    env = UR5TrackEnv(preview=1)
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match=r"^frame: expected one of absolute, relative, reference, got True$"):
        observe(env.loop, 1, False, False, True)  # type: ignore[arg-type]


def test_seeded_resets_are_identical():
    env = UR5TrackEnv(task="random", action_mode="torque")
    env.action_space.seed(5)
    actions = [env.action_space.sample() for _ in range(100)]
    first = episode(env, seed=11, actions=actions)
    second = episode(env, seed=11, actions=actions)
    np.testing.assert_array_equal(first[0], second[0])
    np.testing.assert_array_equal(first[1], second[1])
    other = episode(env, seed=12, actions=actions)
    assert not np.array_equal(first[0][0], other[0][0])



def test_random_tasks_stay_in_range_and_bounded(model):
    env = UR5TrackEnv(task="random", max_displacement=0.7)
    joints = JointInfo.of(model)
    for seed in range(50):
        env.reset(seed=seed)
        q0, qg = env.reference.q[0], env.reference.q[-1]
        assert np.all((joints.lower <= q0) & (q0 <= joints.upper) & (joints.lower <= qg) & (qg <= joints.upper))
        assert np.max(np.abs(qg - q0)) <= 0.7



def test_actions_are_clipped():
    clipped, inside = UR5TrackEnv(action_mode="torque"), UR5TrackEnv(action_mode="torque")
    big = np.array([5.0, -7.0, 0.5])
    clipped.reset(seed=0)
    inside.reset(seed=0)
    a = clipped.step(big)
    b = inside.step(np.clip(big, -1, 1))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[4]["dtau"], [60.0, -60.0, 30.0])



@pytest.mark.parametrize("bad", [[np.nan, 0, 0], [0, np.inf, 0]])
def test_non_finite_actions_raise(bad):
    env = UR5TrackEnv(action_mode="residual")
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match=r"^action: expected finite values in \[-1, 1\], got "):
        env.step(np.array(bad))



def test_wrong_action_shape_raises():
    env = UR5TrackEnv(action_mode="torque")
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match=r"^action: expected shape \(3,\), got \(2,\)$"):
        env.step(np.zeros(2))



def test_step_before_reset_and_after_the_end_raises():
    env = UR5TrackEnv()
    with pytest.raises(InvalidInputError, match=r"^step: call reset\(\) first"):
        env.step(env.action_space.sample())
    episode(env, seed=0)
    with pytest.raises(InvalidInputError, match=r"^step: call reset\(\) first"):
        env.step(env.action_space.sample())



def test_divergence_terminates_with_nan_metrics():
    env = UR5TrackEnv(action_mode="torque", task="explicit", q0=[0, -1.5707963267948966, 0],
                      qg=[0, -1.5707963267948966, 0])
    env.reset(seed=0)
    for k in range(100):  # noqa: B007 - full torque one way: the arm leaves the (constant) reference by more than pi
        _, _, terminated, _, info = env.step(np.ones(3))
        if terminated:
            break
    assert terminated and k < 99 and info["diverged"] is True
    assert all(np.isnan(v) for v in info["metrics"].values())



@pytest.mark.parametrize("task", ["paper", "random"])
def test_vector_env_equals_single_envs(task):
    """num_envs sub-envs seeded s + i give the same trajectories as single envs reset with s + i, bit for bit,
    across an autoreset into the second episode."""
    n, steps = 3, 130
    venv = gym.make_vec("UR5Track-v0", num_envs=n, vectorization_mode="vector_entry_point", task=task,
                        action_mode="residual")
    assert isinstance(venv.unwrapped, UR5TrackVectorEnv)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.2, 0.2, size=(steps, n, 3)).astype(np.float32)
    obs, _ = venv.reset(seed=40)
    vec_obs, vec_rew, vec_done = [obs], [], []
    for k in range(steps):
        obs, reward, terminated, truncated, info = venv.step(actions[k])
        vec_obs.append(obs)
        vec_rew.append(reward)
        vec_done.append(terminated | truncated)
    vec_obs, vec_rew, vec_done = np.array(vec_obs), np.array(vec_rew), np.array(vec_done)
    assert vec_done[99].all() and not vec_done[100].any()  # the autoreset step
    for i in range(n):
        env = gym.make("UR5Track-v0", task=task, action_mode="residual")
        obs, _ = env.reset(seed=40 + i)
        single_obs, single_rew = [obs], []
        for k in range(steps):
            if k == 100:  # next-step autoreset: the vector env resets here instead of stepping
                obs, _ = env.reset()
                single_obs.append(obs)
                single_rew.append(0.0)
                continue
            obs, reward, *_ = env.step(actions[k, i])
            single_obs.append(obs)
            single_rew.append(reward)
        np.testing.assert_array_equal(vec_obs[:, i], np.array(single_obs))
        np.testing.assert_array_equal(vec_rew[:, i], np.array(single_rew))
    venv.close()



def test_vector_env_reports_metrics_of_ended_episodes(scenario):
    venv = gym.make_vec("UR5Track-v0", num_envs=2, vectorization_mode="vector_entry_point", planner="quintic")
    venv.reset(seed=0)
    for _ in range(100):
        *_, info = venv.step(np.zeros((2, 3), dtype=np.float32))
    assert info["_metrics"].tolist() == [True, True]
    expected = compare(scenario, ["quintic"]).metrics["quintic"]
    assert info["metrics"]["rms_err"].tolist() == [expected.rms_err] * 2



def card_table() -> tuple[str, dict[str, str]]:
    """The env card's Arguments section: its table of the benchmark envs (text), and its arguments table, name ->
    default as the card writes it."""
    doc = inspect.getdoc(UR5TrackEnv)
    table = doc.split("## Arguments")[1].split("##")[0]
    benchmark, arguments = table.split("| argument         | default ")
    rows = re.findall(r"^\| (\w+)\s+\| (\S+)\s+\|", "| argument " + arguments, flags=re.M)
    return benchmark, {name: value for name, value in rows if name != "argument"}


def test_docstring_arguments_table_matches_the_code():
    """The Arguments table documents every argument the env accepts, with the default the code applies."""
    benchmark, documented = card_table()
    code = {name: repr(value).replace("'", '"') for name, value in argument_defaults().items()}
    assert documented == code
    lines = [[cell.strip() for cell in line.strip().strip("|").split("|")] for line in benchmark.splitlines()
             if line.strip().startswith("| ")]
    names, variants = lines[0][1:], lines[1:]
    assert [row[0] for row in variants] == list(BENCHMARK_VARIANTS)
    for row in variants:
        shown = {name: cell for name, cell in zip(names, row[1:], strict=True) if cell != "-"}
        assert shown == {name: repr(value).replace("'", '"') for name, value in BENCHMARK_VARIANTS[row[0]].items()}
    env = UR5TrackEnv()  # and those defaults are what an env built without arguments uses
    s = env.settings
    applied = {"planner": s.planner_name, "action_mode": s.action_mode, "residual_scale": s.residual_scale,
               "task": s.task_mode, "family": s.family, "observe_control": s.observe_control,
               "observe_plant": s.observe_plant, "observe_disturbance": s.observe_disturbance, "history": s.history,
               "teacher": s.teacher,
               "observe_task": s.observe_task,
               "observe_measured": s.observe_measured, "settle": s.settle,
               "plant_randomization": s.plant_randomization, "measurement_noise": s.measurement_noise,
               "reward_baseline": s.reward_baseline, "floor": s.floor,
               "max_displacement": s.max_displacement, "duration": s.duration, "dt": s.dt, "preview": s.preview,
               "preview_frame": s.preview_frame,
               "width": s.width, "height": s.height, "camera": s.camera, "render_quality": s.render_quality,
               "render_mode": s.render_mode,
               **{name: getattr(s.loop, name) for name in option_names(LoopConfig, scenario_only=False)}}
    assert applied == {k: v for k, v in argument_defaults().items()
                       if k not in ("q0", "qg", "Q_exec", "R_exec", "xml_file", "torque_limit")}
    env.close()


@pytest.mark.parametrize("cls", [UR5TrackEnv, UR5TrackVectorEnv])
def test_the_signature_shows_every_argument_with_its_default(cls):
    """`help()` and `inspect.signature` (what editors ask) show every argument of the card's table, keyword-only, with
    the card's default; the vector env's own arguments come first. An unknown keyword is still the one-line error."""
    import pydoc

    _, documented = card_table()
    parameters = inspect.signature(cls).parameters
    env_args = {name: p for name, p in parameters.items() if name in documented}
    assert {name: repr(p.default).replace("'", '"') for name, p in env_args.items()} == documented
    assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in env_args.values())
    own = [name for name in parameters if name not in documented]
    assert own == ([] if cls is UR5TrackEnv else ["num_envs", "max_episode_steps", "autoreset_mode"])
    assert f"{cls.__name__}(" + ("*, planner" if cls is UR5TrackEnv else "num_envs") in pydoc.render_doc(
        cls, renderer=pydoc.plaintext)
    with pytest.raises(InvalidInputError, match=r"^speed: unknown argument; valid: planner, q0, qg, [^\n]*, delay$"):
        cls(speed=2)


def test_a_subclass_with_its_own_init_shows_its_own_signature():
    class Mine(UR5TrackEnv):
        def __init__(self, gain, **kwargs):
            super().__init__(**kwargs)

    class Same(UR5TrackEnv):
        pass

    assert str(inspect.signature(Mine)) == "(gain, **kwargs)"
    assert inspect.signature(Same) == inspect.signature(UR5TrackEnv)


def test_docstring_defaults_are_the_paper_scenario(scenario):
    env = UR5TrackEnv()
    s = env.settings
    assert (s.duration, s.dt) == (scenario.task.duration, scenario.task.dt)
    assert all(getattr(s.loop, name) == getattr(scenario.loop, name) for name in option_names(LoopConfig))
    assert all(np.array_equal(getattr(s.loop.gains, k), getattr(scenario.loop.gains, k)) for k in ("kp", "ki", "kd"))
    assert s.scoring.rule == "bryson"  # Bryson's rule per task, which for the paper task is:
    q_diag, r_diag = s.weights(s.fixed_task)
    np.testing.assert_allclose(q_diag, scenario.Q_exec, rtol=1e-15)
    np.testing.assert_allclose(r_diag, scenario.R_exec, rtol=1e-15)
    env.close()


def test_random_episodes_are_scored_by_brysons_rule_of_their_task():
    """A random-task episode is scored with the weights a sweep scores its task with: 1/move^2 on the positions
    (move = the task's largest joint displacement, taken here from the reference), 1/pi^2 on the velocities."""
    env = UR5TrackEnv(task="random")
    env.reset(seed=11)
    ref = env.reference
    move = np.max(np.abs(ref.q[-1] - ref.q[0]))
    assert abs(move - 1.0) > 0.05  # weights that differ from the paper task's
    total, done = 0.0, False
    while not done:
        _, reward, done, _, info = env.step(np.zeros(3, dtype=np.float32))
        total += reward
    e = info["e"]
    ed = ref.qd[-2] - env.loop.rollout().qd[0, -1]  # the last period's velocity error
    assert info["reward_tracking"] == pytest.approx(-(e @ e) / move**2 - (ed @ ed) / np.pi**2, rel=1e-9)
    assert -total == pytest.approx(info["metrics"]["cost"], rel=1e-12)



@pytest.mark.parametrize(("kwargs", "message"), [
    ({"planner": "spline"}, r"^planner: unknown planner 'spline'; valid: cubic, optimal, "
                            r"nonlinear_optimal, nonlinear_min_effort, quintic, scurve, trapezoidal$"),
    ({"planner": 3}, r"^planner: expected a registered name \(cubic, optimal, nonlinear_optimal, "
                     r"nonlinear_min_effort, quintic, scurve, trapezoidal\) or an object with plan\(task, model\), "
                     r"got 3$"),
    ({"action_mode": "velocity"}, r"^action_mode: unknown value 'velocity'; valid: pid, residual, torque$"),
    ({"task": "circle"}, r"^task: unknown value 'circle'; valid: paper, random, explicit$"),
    ({"camera": "wrist"}, r"^camera: unknown camera 'wrist'; valid: front, side, top, free \(the model's cameras"),
    ({"render_quality": "ultra"}, r"^render_quality: unknown value 'ultra'; valid: fast, high$"),
    ({"task": "explicit", "q0": [0, 0, 4], "qg": [0, 0, 0]},
     r"^q0: joint 'elbow_joint' = 4.0 rad is outside its range \[-3.141592653589793, 3.141592653589793\]$"),
    ({"task": "explicit", "q0": [0, 0, 0]}, r"^task: 'explicit' needs both q0 and qg \(rad\)$"),
    ({"q0": [0, 0, 0], "qg": [0, 0, 1]}, r"^q0, qg: only used with task='explicit', got task='paper'$"),
    ({"width": 4000}, r"^width: expected at most the offscreen buffer's 1920 pixels, got 4000; raise it with the "
                      r"MJCF attribute <visual><global offwidth=\"4000\"/></visual>$"),
    ({"height": 2000}, r"^height: expected at most the offscreen buffer's 1080 pixels, got 2000; raise it with the "
                       r"MJCF attribute <visual><global offheight=\"2000\"/></visual>$"),
    ({"render_mode": "window"}, r"^render_mode: unsupported mode 'window'; valid: None, rgb_array, depth_array, "
                                r"human$"),
    ({"preview": -1}, r"^preview: expected a value >= 0, got -1$"),
    ({"Q_exec": [1, 1], "R_exec": [1, 1, 1]}, r"^Q_exec: expected 6 values, got shape \(2,\)$"),
    ({"Q_exec": [1] * 6}, r"^Q_exec, R_exec: give both \(diagonals of 2n and n weights\), or neither for Bryson's "
                          r"rule on each task$"),
    ({"speed": 2}, r"^speed: unknown argument; valid: planner, q0, qg, Q_exec, R_exec, render_mode, xml_file, "
                   r"torque_limit, "
                   r"action_mode, "
                   r"residual_scale, task, family, max_displacement, duration, dt, preview, preview_frame, "
                   r"observe_control, "
                   r"observe_plant, observe_disturbance, observe_task, observe_measured, settle, history, teacher, "
                   r"plant_randomization, "
                   r"measurement_noise, reward_baseline, floor, width, "
                   r"height, "
                   r"camera, render_quality, "
                   r"controller, "
                   r"feedforward, ff_accel, gravity_comp, anti_windup, adaptation_rate, substeps, divergence_bound, "
                   r"delay$"),
    ({"substeps": 0}, r"^substeps: expected a value >= 1, got 0$"),
    ({"preview_frame": "ahead"}, r"^preview_frame: unknown value 'ahead'; valid: absolute, relative, reference$"),
    ({"observe_plant": "estimate"}, r"^observe_plant: 'estimate' observes the adaptive law's estimate; expected "
                                    r"controller='adaptive_computed_torque', got 'pid'$"),
    ({"observe_plant": "all"}, r"^observe_plant: unknown value 'all'; valid: none, true, estimate$"),
    ({"history": -1}, r"^history: expected a value >= 0, got -1$"),
    ({"residual_scale": 0}, r"^residual_scale: expected a positive number, got 0"),
    ({"residual_scale": -5.0}, r"^residual_scale: expected a positive number, got -5.0"),
    ({"dt": True}, r"^dt: expected a number, got True$"),
    ({"duration": 1.01}, r"^duration: expected a whole number of control periods dt=0.02 s, got 1.01 s"),
])
def test_bad_arguments(kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        UR5TrackEnv(**kwargs)



def test_user_planner_object(model):
    from mjtraj.core.planners.cubic import Cubic

    env = UR5TrackEnv(planner=Cubic())
    _, rewards, info = episode(env, seed=0)
    reference = UR5TrackEnv(planner="cubic")
    _, expected, _ = episode(reference, seed=0)
    np.testing.assert_array_equal(rewards, expected)



@pytest.mark.parametrize("mode", ["pid", "residual", "torque"])
@pytest.mark.parametrize(("action", "message"), [
    (np.array([np.nan, 0.0, 0.0]), r"^action: expected finite values in \[-1, 1\], got \[nan, 0.0, 0.0\]$"),
    ("abc", r"^action: expected real numbers in \[-1, 1\], got str$"),
    ({"a": 1}, r"^action: expected real numbers in \[-1, 1\], got dict$"),
    (np.array([1j, 0, 0]), r"^action: expected real numbers in \[-1, 1\], got complex128 values$"),
    (np.zeros(2), r"^action: expected shape \(3,\), got \(2,\)$"),
    (np.zeros((1, 3)), r"^action: expected shape \(3,\), got \(1, 3\)$"),  # a batch of one: the vector env's
])
def test_actions_are_checked_in_every_mode(mode, action, message):
    env = UR5TrackEnv(action_mode=mode)
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match=message):
        env.step(action)


def test_native_vector_env_is_gymnasiums_sync_vector_env():
    """Oracle: Gymnasium's own SyncVectorEnv over single envs. Observations, rewards, terminated and truncated
    agree bit for bit over several episodes and autoresets."""
    kwargs = {"task": "random", "duration": 0.4}
    sync = gym.make_vec("UR5Track-v0", num_envs=2, vectorization_mode="sync", **kwargs)
    native = gym.make_vec("UR5Track-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    first_sync, _ = sync.reset(seed=5)
    first_native, _ = native.reset(seed=5)
    np.testing.assert_array_equal(first_sync, first_native)
    actions = np.random.default_rng(0).uniform(-0.05, 0.05, (45, 2, 3)).astype(np.float32)
    for action in actions:  # 20 steps an episode, with NEXT_STEP autoresets in between
        for expected, got in zip(sync.step(action)[:4], native.step(action)[:4], strict=True):
            np.testing.assert_array_equal(got, expected)
    sync.close()
    native.close()


def test_observe_control_appends_the_integral_and_the_next_feedforward():
    """Oracles: the integral observed after step k is sum_j e_j dt over the steps so far (the PID's rectangle rule,
    from info["e"]); the feedforward observed after step k is the tau_ff that step k+1 applies (info); the first 19
    values are the plain observation; the space holds every observation (Gymnasium's check_env)."""
    from gymnasium.utils.env_checker import check_env

    env = UR5TrackEnv(action_mode="residual", task="random", observe_control=True)
    plain = UR5TrackEnv(action_mode="residual", task="random")
    assert env.observation_space.shape == (25,)
    obs, _ = env.reset(seed=3)
    ref, _ = plain.reset(seed=3)
    assert np.array_equal(obs[:19], ref) and np.array_equal(obs[19:22], np.zeros(3))
    rng = np.random.default_rng(0)
    integral, previous, k = np.zeros(3), obs, 0
    done = False
    while not done:
        action = rng.uniform(-1, 1, 3).astype(np.float32)
        obs, _, done, _, info = env.step(action)
        ref, *_ = plain.step(action)
        np.testing.assert_array_equal(info["tau_ff"], previous[22:25])
        integral = integral + info["e"] * env.unwrapped.dt
        np.testing.assert_allclose(obs[19:22], integral, rtol=1e-12, atol=1e-15)
        assert np.array_equal(obs[:19], ref) and env.observation_space.contains(obs)
        previous, k = obs, k + 1
    assert k == 100
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)
    env.close()
    plain.close()


def test_an_env_whose_arguments_were_refused_closes_quietly():
    """Gymnasium's __del__ closes an env whose __init__ raised: close must not depend on what __init__ set."""
    from mjtraj.envs.ur5_track import UR5TrackEnv
    from mjtraj.envs.vector import UR5TrackVectorEnv

    from mjtraj.exceptions import InvalidInputError

    for cls, kwargs in ((UR5TrackEnv, {}), (UR5TrackVectorEnv, {"num_envs": 2})):
        with pytest.raises(InvalidInputError):
            cls(bogus=1, **kwargs)
        half_made = cls.__new__(cls)
        half_made.close()  # must not raise
