"""Arms users bring: no silent wrong numbers (gains that fit every drawn task, missed goals visible), and no refusal
of a reasonable file (default classes, geared motors, sensors and keyframes of the replaced actuators, a body
named like ours, a narrow joint range, an explicit task in the env). The arm files are written here."""

from __future__ import annotations

from collections import Counter

import mujoco
import numpy as np
import pytest
from mjtraj.envs import UR5TrackEnv

from mjtraj.core.arm import prepare_arm
from mjtraj.core.gains import free_inertia, free_inertia_at, workspace_poses
from mjtraj.domain.pipeline import GOAL_TOLERANCE, goal_checked
from mjtraj.domain.scenario import scenario_for_model
from mjtraj.exceptions import ModelError
from mjtraj.study import Outcome, SweepSettings, perturbed_plant, run_unit

LIGHT = """<mujoco model="light">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 0.1">
      <joint name="pan" axis="0 0 1" range="-3 3" actuatorfrcrange="-5 5"/>
      <geom type="cylinder" size="0.03 0.02" mass="0.1"/>
      <body name="upper" pos="0 0 0.03">
        <joint name="lift" axis="0 1 0" range="-1.5 1.5" actuatorfrcrange="-5 5"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.01" mass="0.1"/>
        <body name="fore" pos="0 0 0.3">
          <joint name="elbow" axis="0 1 0" range="-2.8 2.8" actuatorfrcrange="-5 5"/>
          <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.01" mass="0.1"/>
          <site name="attachment_site" pos="0 0 0.3"/>
          <geom type="sphere" pos="0 0 0.3" size="0.02" mass="0.2"/>
        </body>
      </body>
    </body>
  </worldbody>
  <keyframe><key name="home" qpos="0 1.4 0"/></keyframe>
</mujoco>
"""
"""A light arm whose home pose (stretched out) is its heaviest for the pan joint: gains sized on the home move
are about 85 times too stiff for the folded poses random tasks reach."""

GEARED = """<mujoco model="geared">
  <compiler angle="radian"/>
  <default>
    <motor gear="50" ctrlrange="-1 1"/>
    <joint damping="0.1"/>
  </default>
  <worldbody>
    <body name="l1" pos="0 0 0.1">
      <joint name="j1" axis="0 0 1" range="-3 3" actuatorfrcrange="-20 20"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1"/>
      <body name="l2" pos="0.4 0 0">
        <joint name="j2" axis="0 1 0" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.5"/>
        <body name="payload" pos="0.3 0 0"><geom type="sphere" size="0.02" mass="0.05"/></body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="m1" joint="j1"/>
    <motor name="m2" joint="j2"/>
  </actuator>
  <sensor><actuatorfrc name="f1" actuator="m1"/><jointpos name="p2" joint="j2"/></sensor>
  <keyframe><key name="home" qpos="0 0.3" ctrl="0.5 -0.5"/></keyframe>
</mujoco>
"""
"""A default class that gears every motor by 50, a keyframe with ctrl, an actuator sensor, and a body named
payload: what Menagerie-style files have."""


@pytest.fixture
def arms(tmp_path):
    out = {}
    for name, text in (("light", LIGHT), ("geared", GEARED)):
        out[name] = tmp_path / f"{name}.xml"
        out[name].write_text(text)
    return out


def test_drawn_tasks_get_gains_for_the_whole_workspace_and_track_every_nominal_task(arms):
    """Oracle: with the home move's gains the cubic's nominal rows miss their goals (now visible as missed_goal);
    with the workspace rule every one ends within 2 % of its move (terminal and RMS error)."""
    home = scenario_for_model(arms["light"])
    drawn = scenario_for_model(arms["light"], workspace=True)
    lightest_move, _ = free_inertia(home.model, home.task.q0, home.task.qg)
    lightest_all, _ = free_inertia_at(home.model, workspace_poses(home.model, home.task.q0, home.task.qg))
    assert lightest_move[0] > 50 * lightest_all[0]  # the pan joint: the stretched home move is far the heaviest
    np.testing.assert_allclose(drawn.loop.gains.kp, home.loop.gains.kp * lightest_all / lightest_move)
    settings = SweepSettings(families=("nominal",), scenarios=30, seed=0, model=str(arms["light"]),
                             planners=("cubic",))
    assert np.array_equal(settings.base.loop.gains.kp, drawn.loop.gains.kp)
    rows = run_unit(settings, ("nominal", 0)).rows
    assert Counter(r["status"] for r in rows) == {"ok": 30}
    for r in rows:
        assert float(r["terminal_err"]) < 0.02 * float(r["max_displacement"])
        assert float(r["rms_err"]) < 0.02 * float(r["max_displacement"])
    import mjtraj.study.sweep as sweep_module

    original = sweep_module.scenario_for_model
    try:  # the old rule, for the record: the same tasks with the home move's gains
        sweep_module.scenario_for_model = lambda path, torque_limit=None, workspace=True: original(path)
        old = run_unit(SweepSettings(families=("nominal",), scenarios=30, seed=0, model=str(arms["light"]),
                                     planners=("cubic",)), ("nominal", 0)).rows
    finally:
        sweep_module.scenario_for_model = original
    assert sum(r["status"] == "missed_goal" for r in old) >= 5
    assert all(r["status"] != "ok" or float(r["terminal_err"]) <= GOAL_TOLERANCE * float(r["max_displacement"])
               for r in old)


def test_the_env_sizes_gains_for_drawn_tasks_and_takes_an_explicit_task(arms):
    drawn = UR5TrackEnv(xml_file=arms["light"], task="random")
    assert np.array_equal(drawn.settings.loop.gains.kp, scenario_for_model(arms["light"], workspace=True).loop.gains.kp)
    explicit = UR5TrackEnv(xml_file=arms["light"], task="explicit", q0=[0.0, 0.2, 0.3], qg=[0.4, 0.5, 0.9])
    obs, info = explicit.reset(seed=0)
    np.testing.assert_array_equal(info["task"]["qg"], [0.4, 0.5, 0.9])


def assert_ran(rows):
    """Every row executed, and is ok exactly when it ends within the goal rule (mismatched light arms often miss:
    a row that does is never ok)."""
    for r in rows:
        assert r["status"] in ("ok", "missed_goal"), r["reason"]
        missed = float(r["terminal_err"]) > GOAL_TOLERANCE * float(r["max_displacement"])
        assert (r["status"] == "missed_goal") == missed


def test_a_missed_goal_is_a_status_with_its_reason():
    ok = Outcome("ok", "", {"terminal_err": 0.3})
    assert goal_checked(ok, 2.0) is ok
    missed = goal_checked(ok, 1.0)
    assert missed.status == "missed_goal" and missed.metrics == ok.metrics
    assert missed.reason == "terminal error 0.3 rad > 0.2 x the move (1 rad)"
    failed = Outcome("diverged", "x")
    assert goal_checked(failed, 1.0) is failed


def test_motors_ignore_the_files_default_class_and_geared_limits_count(arms):
    model = prepare_arm(arms["geared"], dt=0.02)
    np.testing.assert_array_equal(model.actuator_gear[:, 0], [1.0, 1.0])
    # j1: gear 50 x ctrl 1 = 50 N m, within the joint's own 20 N m; j2: 50 N m
    np.testing.assert_array_equal(model.actuator_ctrlrange, [[-20.0, 20.0], [-50.0, 50.0]])
    assert [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, i) for i in range(model.nsensor)] == ["p2"]
    np.testing.assert_array_equal(model.key_ctrl, [[0.0, 0.0]])


def test_an_arm_with_a_body_named_payload_runs_the_mismatch_family(arms, tmp_path):
    settings = SweepSettings(families=("mismatch",), scenarios=3, seed=1, model=str(arms["geared"]),
                             planners=("cubic",))
    rows = run_unit(settings, ("mismatch", 0)).rows
    assert_ran(rows)
    clash = tmp_path / "clash.xml"
    clash.write_text(GEARED.replace('name="payload"', 'name="mjtraj_payload"'))
    with pytest.raises(ModelError, match=r"a body is named 'mjtraj_payload', the name mjtraj gives the mismatch "
                                         r"family's payload; rename it$"):
        perturbed_plant(prepare_arm(clash), str(clash))


def test_the_default_goal_stays_inside_a_narrow_range(tmp_path):
    narrow = tmp_path / "narrow.xml"
    narrow.write_text(GEARED.replace('range="-2 2"', 'range="-0.2 0.4"'))
    task = scenario_for_model(narrow).task
    assert -0.2 <= task.qg[1] <= 0.4 and task.qg[1] != task.q0[1]
    assert task.qg[0] - task.q0[0] == 0.5


def test_frontier_draws_no_figure_when_nothing_succeeded(tmp_path):
    from mjtraj.study import load_scenario
    from mjtraj.study.frontier import frontier
    from mjtraj.study.plots import frontier_figure

    result = frontier(load_scenario(), alphas=(1.0,), splits=(0.5,))
    for row in result.rows:
        row.metrics.update({k: float("nan") for k in row.metrics})
    assert frontier_figure(result, tmp_path / "f.png") is None and not (tmp_path / "f.png").exists()


def test_an_arm_without_cameras_renders_through_the_free_camera(arms):
    env = UR5TrackEnv(xml_file=arms["light"], task="random", render_mode="rgb_array", width=64, height=48)
    assert env.settings.camera == "free"
    env.reset(seed=1)
    frame = env.render()
    assert frame.shape == (48, 64, 3) and frame.std() > 5  # an arm was drawn, not a blank image
    env.close()


def test_unnamed_joints_and_bodies_are_named_in_the_copy_and_run_every_family(tmp_path):
    unnamed = tmp_path / "unnamed.xml"
    unnamed.write_text(LIGHT.replace(' name="base"', "").replace(' name="upper"', "").replace(' name="fore"', "")
                       .replace(' name="lift"', "").replace(' name="elbow"', ""))
    text = unnamed.read_text()
    model = prepare_arm(unnamed)
    assert [model.joint(j).name for j in range(model.njnt)] == ["pan", "joint1", "joint2"]
    assert unnamed.read_text() == text  # named in mjtraj's copy only
    for family in ("nominal", "mismatch"):
        settings = SweepSettings(families=(family,), scenarios=2, seed=0, model=str(unnamed), planners=("cubic",))
        assert_ran(run_unit(settings, (family, 0)).rows)


def test_dry_friction_is_left_out_of_linearisations_and_every_planner_plans(arms, tmp_path):
    """Oracle: the friction arm linearises exactly as the same arm without friction loss; compare then runs every
    planner (the optimal one had been refused: friction read as a 10^6 N m s/rad damper at rest)."""
    from mjtraj.core.linearize import linearize
    from mjtraj.study import compare

    rough = tmp_path / "rough.xml"
    rough.write_text(GEARED.replace('<joint damping="0.1"/>', '<joint damping="0.1" frictionloss="2"/>'))
    with_friction, without = prepare_arm(rough, dt=0.02), prepare_arm(arms["geared"], dt=0.02)
    assert with_friction.dof_frictionloss.tolist() == [2.0, 2.0]
    for q in ([0.0, 0.3], [1.0, -0.5]):
        for a, b in zip(linearize(with_friction, q), linearize(without, q), strict=True):
            np.testing.assert_array_equal(a, b)
    result = compare(scenario_for_model(rough))
    assert all(np.isfinite(m.cost) for m in result.metrics.values()) and "optimal" in result.planners


@pytest.mark.slow
def test_shipped_arms_by_name_and_a_tuned_file_that_works_from_any_folder(tmp_path, capsys, monkeypatch):
    from mjtraj.cli import main

    env = UR5TrackEnv(xml_file="planar_2link", task="random")
    assert env.settings.n == 2
    env.close()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "light.xml").write_text(LIGHT)
    assert main(["compare", "--model", "ur5_6dof", "--no-figures", "--out", "out6"]) == 0
    out = capsys.readouterr().out
    assert "6 joints" in out and "Table I as published" not in out  # the paper's table is the UR5's, not any arm's
    assert main(["tune", "--model", "arms/light.xml", "--planners", "trapezoidal", "--scenarios", "2", "--budget",
                 "1", "--out", "tuned.toml", "--no-progress"]) == 0
    capsys.readouterr()
    monkeypatch.chdir(tmp_path / "arms")
    assert main(["compare", "--config", str(tmp_path / "tuned.toml"), "--no-figures", "--out", "o"]) == 0
    with pytest.raises(ModelError, match=r"model file not found: nope \(a shipped arm is named without a folder: "
                                         r"planar_2link, ur5_3dof, ur5_6dof\)$"):
        prepare_arm("nope")


def test_the_mismatch_ranges_scale_with_the_arm_and_not_for_the_ur5(arms):
    """Oracle: the scales by hand from the rule's parts (total body mass over the shipped UR5's; saturation over
    60 N m; the workspace gain rule's kp over the UR5's least; holding torques from MuJoCo's bias force); every
    light-arm draw within its scaled ranges; the UR5's draws are those of the unscaled rule, bit for bit, at its
    20 ms period and at a finer one."""
    from mjtraj.core.gains import gain_rule
    from mjtraj.domain.families import HOLD_FRACTION, holding_torque
    from mjtraj.study import arm_scales, draw_perturbation, draw_scenario, load_scenario

    ur5 = load_scenario().model
    light = scenario_for_model(arms["light"], workspace=True).model
    mass, torque = arm_scales(light, 0.02)
    kp = gain_rule(light, light.qpos0, light.qpos0, 0.02, workspace=True).kp
    kp_ur5 = gain_rule(ur5, ur5.qpos0, ur5.qpos0, 0.02, workspace=True).kp
    limit = light.actuator_ctrlrange[:, 1]
    np.testing.assert_allclose(torque, np.minimum(limit / 60.0, kp / kp_ur5.min()), rtol=1e-15)
    assert np.any(kp / kp_ur5.min() < limit / 60.0)  # the loop's authority binds on this light arm
    hold, hold_ur5 = holding_torque(light), holding_torque(ur5)
    stiff = np.min(kp / np.maximum(hold, 1e-12)) / np.min(kp_ur5 / np.maximum(hold_ur5, 1e-12))
    by_hand = min(np.sum(light.body_mass[1:]) / np.sum(ur5.body_mass[1:]),
                  HOLD_FRACTION * np.min(limit / np.maximum(hold, 1e-12)) / 5.0, stiff)
    assert mass == pytest.approx(by_hand, rel=1e-12)
    for i in range(20):
        p = draw_scenario("mismatch", 0, i, light, 0.02).perturbation
        assert 0 <= p.payload <= 5 * mass and np.all(p.friction <= 3 * torque) and np.all(p.damping <= torque)
    for dt in (0.02, 0.01):
        for seed in range(5):
            a = draw_perturbation(np.random.default_rng(seed), 3, arm_scales(ur5, dt))
            b = draw_perturbation(np.random.default_rng(seed), 3)
            assert a.as_dict() == b.as_dict()


def test_one_planners_failure_does_not_stop_the_others(capsys, tmp_path):
    from mjtraj.cli import main
    from mjtraj.study import compare, load_scenario

    result = compare(load_scenario().replace(task={"duration": 0.1}), ["optimal", "cubic", "scurve"])
    assert result.planners == ("cubic",) and set(result.failed) == {"optimal", "scurve"}
    assert result.failed["optimal"].startswith("InfeasibleError: optimal: x_N = 0 cannot be reached")
    assert main(["compare", "--duration", "0.1", "--planners", "optimal,scurve", "--no-figures", "--out",
                 str(tmp_path)]) == 2  # none could plan: the first reason, in one line
    assert capsys.readouterr().err.startswith("mjtraj: error: optimal: x_N = 0 cannot be reached")


def test_per_joint_torque_limits_from_the_command_line_to_the_rows(arms, tmp_path, capsys):
    from mjtraj.cli import main
    from mjtraj.study.store import read_rows

    model = prepare_arm(arms["light"], torque_limit=[3.0, 4.0, 2.5])
    np.testing.assert_array_equal(model.actuator_ctrlrange[:, 1], [3.0, 4.0, 2.5])
    with pytest.raises(Exception, match=r"^torque_limit: expected one value for every joint or one for each of the 3 "
                                        r"joints, got 2: \[3\.0, 4\.0\]$"):
        prepare_arm(arms["light"], torque_limit=[3.0, 4.0])
    out = tmp_path / "s.csv"
    assert main(["sweep", "--model", str(arms["light"]), "--torque-limit", "3,4,2.5", "--scenarios", "2",
                 "--planners", "cubic", "--family", "mismatch", "--out", str(out), "--no-progress"]) == 0
    rows = read_rows(out)
    assert {r["torque_limit"] for r in rows} == {"3.0+4.0+2.5"} and {r["status"] for r in rows} == {"ok"}
    assert SweepSettings.from_record(rows[0]).torque_limit == (3.0, 4.0, 2.5)
    assert main(["compare", "--model", str(arms["light"]), "--torque-limit", "3,4,2.5", "--no-figures", "--out",
                 str(tmp_path / "c")]) == 0
    assert "|dtau| <= [3, 4, 2.5] N m" in capsys.readouterr().out
    scenario = scenario_for_model(arms["light"], torque_limit=[3.0, 4.0, 2.5])
    from mjtraj.study import load_scenario, scenario_text

    (tmp_path / "arm.toml").write_text(scenario_text(scenario))
    assert load_scenario(tmp_path / "arm.toml").model_torque_limit == (3.0, 4.0, 2.5)


def test_frontier_says_why_a_point_failed_and_takes_the_task_flags(tmp_path, capsys):
    from mjtraj.cli import main

    assert main(["frontier", "--duration", "0.3", "--alphas", "1", "--splits", "0.5", "--no-figures",
                 "--no-progress", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "  failed: optimal (alpha 1, split 0.5): infeasible: InfeasibleError: optimal: x_N = 0 cannot be " in out
    import json

    rows = json.loads((tmp_path / "frontier.json").read_text())["rows"]
    optimal = next(r for r in rows if r["planner"] == "optimal")
    assert optimal["failed"] == 1 and optimal["failure_reasons"][0].startswith("infeasible: InfeasibleError")


def test_a_light_user_arms_fast_joints_stay_inside_its_observation_space(arms):
    """The UR5's 200 rad/s bound does not hold for a user's light joints: full residual pushes on the light arm
    leave the space's velocity bounds never violated (they had been, making SB3's checker fail at random)."""
    env = UR5TrackEnv(xml_file=arms["light"], task="random", action_mode="torque")
    space = env.observation_space
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(np.ones(3))
            assert space.contains(obs)
            done = terminated or truncated
    assert UR5TrackEnv().observation_space.high[3] == 200.0  # the UR5's bound is unchanged
