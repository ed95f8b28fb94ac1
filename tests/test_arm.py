"""A user's MJCF arm: the prepared plant of the shipped planar two-link arm matches its closed-form dynamics (mass
matrix, Coriolis, gravity, so the feedforward); gravity is compensated and the servos became torque motors; the
user's file is untouched; the UR5 prepared from its file runs as the shipped one; unsupported models are one-line
errors naming the element; `mjtraj compare --model` runs the study on it."""

from __future__ import annotations

import copy
import json

import mujoco
import numpy as np
import pytest

from mjtraj.cli import main
from mjtraj.core.arm import arm_spec, prepare_arm
from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.dynamics import DynamicsProbe
from mjtraj.core.feedforward import feedforward
from mjtraj.core.model import default_model_path, load_model
from mjtraj.core.planners import make
from mjtraj.domain.scenario import scenario_for_model
from mjtraj.exceptions import ModelError

PLANAR = default_model_path().parent / "planar_2link.xml"
M1, L1, LC1, M2, LC2, G = 2.0, 0.5, 0.25, 1.0, 0.2, 9.81
I1, I2 = M1 * 0.5**2 / 12, M2 * 0.4**2 / 12


def closed_form(q, qd):
    """D(q) (2, 2), C(q, qd) qd (2,) and G(q) (2,) of the planar arm (its file's header)."""
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    d12 = I2 + M2 * (LC2**2 + L1 * LC2 * c2)
    D = np.array([[I1 + I2 + M1 * LC1**2 + M2 * (L1**2 + LC2**2 + 2 * L1 * LC2 * c2), d12], [d12, I2 + M2 * LC2**2]])
    h = M2 * L1 * LC2 * s2
    coriolis = np.array([-h * (2 * qd[0] * qd[1] + qd[1] ** 2), h * qd[0] ** 2])
    gravity = np.array([(M1 * LC1 + M2 * L1) * G * np.cos(q[0]) + M2 * LC2 * G * np.cos(q[0] + q[1]),
                        M2 * LC2 * G * np.cos(q[0] + q[1])])
    return D, coriolis, gravity


def test_the_prepared_plant_has_the_closed_form_dynamics():
    model = prepare_arm(PLANAR, dt=0.02)
    probe = DynamicsProbe(model)
    rng = np.random.default_rng(7)
    q, qd, qdd = rng.uniform(-2, 2, (20, 2)), rng.uniform(-3, 3, (20, 2)), rng.uniform(-5, 5, (20, 2))
    D, h = probe.mass_and_bias(q, qd)
    for b in range(20):
        D_ref, coriolis, gravity = closed_form(q[b], qd[b])
        np.testing.assert_allclose(D[b], D_ref, rtol=1e-12)
        np.testing.assert_allclose(h[b], coriolis, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(probe.gravity(q[b:b + 1])[0], gravity, rtol=1e-12)
        np.testing.assert_allclose(probe.inverse(q[b:b + 1], qd[b:b + 1], qdd[b:b + 1])[0],
                                   D_ref @ qdd[b] + coriolis, rtol=1e-10, atol=1e-12)
    scenario = scenario_for_model(PLANAR)
    reference = make("quintic").plan(scenario.task, scenario.model)
    ff = feedforward(scenario.model, reference)
    for k in range(0, reference.steps, 9):
        D_ref, coriolis, _ = closed_form(reference.q[k], reference.qd[k])
        np.testing.assert_allclose(ff[k], D_ref @ reference.qdd[k] + coriolis, rtol=1e-9, atol=1e-12)


def test_servos_become_motors_gravity_is_compensated_and_the_file_is_untouched():
    before = PLANAR.read_bytes()
    model = prepare_arm(PLANAR, dt=0.01)
    assert PLANAR.read_bytes() == before
    assert model.opt.timestep == 0.01 and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    np.testing.assert_array_equal(model.actuator_ctrlrange, [[-20.0, 20.0], [-20.0, 20.0]])  # the servos' force range
    assert np.all(model.actuator_biastype == mujoco.mjtBias.mjBIAS_NONE) and np.all(model.actuator_gainprm[:, 0] == 1)
    data = mujoco.MjData(model)
    data.qpos[:] = [0.4, -0.9]
    for _ in range(100):
        mujoco.mj_step(model, data)  # zero torque: a compensated arm holds any pose
    np.testing.assert_allclose(data.qpos, [0.4, -0.9], atol=1e-12)


def test_the_ur5_prepared_from_its_file_executes_as_the_shipped_model(scenario):
    shipped, prepared = scenario.model, load_model(default_model_path(), dt=scenario.task.dt)
    reference = make("cubic").plan(scenario.task, shipped)
    a = ClosedLoop(shipped, scenario.loop).run([reference])
    b = ClosedLoop(prepared, scenario.loop).run([reference])
    np.testing.assert_array_equal(a.dtau, b.dtau)
    np.testing.assert_array_equal(a.e, b.e)


ARM = '''<mujoco><worldbody><body name="a">{joint}<inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
<body name="b" pos="0.2 0 0"><joint name="j2" type="hinge" axis="0 1 0"/>
<inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body></body></worldbody>{extra}
<actuator>{actuators}</actuator></mujoco>'''
HINGE = '<joint name="j1" type="hinge" axis="0 1 0"/>'
MOTORS = '<motor joint="j1" ctrlrange="-5 5"/><motor joint="j2" ctrlrange="-5 5"/>'


@pytest.mark.parametrize(("joint", "extra", "actuators", "message"), [
    ('<joint name="j1" type="ball"/>', "", '<motor joint="j2" ctrlrange="-5 5"/>',
     r"joint 'j1' is a ball joint; mjtraj plans arms of hinge joints only$"),
    ('<joint name="j1" type="slide" axis="1 0 0"/>', "", MOTORS, r"joint 'j1' is a slide joint; "),
    ('<freejoint name="j1"/>', "", '<motor joint="j2" ctrlrange="-5 5"/>', r"joint 'j1' is a free joint; "),
    (HINGE, '<tendon><fixed name="t"><joint joint="j1" coef="1"/></fixed></tendon>', MOTORS,
     r"tendon 't': tendons are not supported$"),
    (HINGE, '<equality><joint name="e" joint1="j1" joint2="j2"/></equality>', MOTORS,
     r"equality constraint 'e': equality constraints are not supported$"),
    (HINGE, "", '<motor joint="j1" ctrlrange="-5 5"/>',
     r"joint 'j2' has no actuator force range to take the corrective saturation from; give torque_limit"),
])
def test_unsupported_models_are_one_line_errors_naming_the_element(tmp_path, joint, extra, actuators, message):
    path = tmp_path / "arm.xml"
    path.write_text(ARM.format(joint=joint, extra=extra, actuators=actuators))
    with pytest.raises(ModelError, match=rf"^model {path}: {message}"):
        prepare_arm(path)


def test_compare_runs_the_study_on_a_user_arm(tmp_path, capsys):
    assert main(["compare", "--model", str(PLANAR), "--no-figures", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "Table I (ours: MuJoCo arm planar_2link.xml, 2 joints, identical FF+PID, |dtau| <= 20 N m;" in out
    assert "q0 = [0, 0] rad, qg = [0.5, 0.5] rad" in out  # the stated task rule from qpos0
    assert main(["compare", "--model", str(PLANAR), "--config", "paper"]) == 2
    assert capsys.readouterr().err.strip() == ('mjtraj: error: model, config: give one (a scenario file names its arm '
                                               'with model = "PATH")')


def test_compare_on_a_user_arm_writes_beside_the_ur5s_results(tmp_path, monkeypatch):
    """Without --out, `compare --model ARM.xml` writes results/ARM/, and the UR5's results/ stays as it was."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "results.json").write_text("the UR5's")
    assert main(["compare", "--model", str(PLANAR), "--no-figures"]) == 0
    assert (tmp_path / "results" / "results.json").read_text() == "the UR5's"
    assert json.loads((tmp_path / "results" / PLANAR.stem / "results.json").read_text())["planners"]


def test_arm_track_env_runs_a_user_arm_like_the_loop():
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    env = gym.make("ArmTrack-v0", xml_file=str(PLANAR))
    obs, _ = env.reset(seed=0)
    assert obs.shape == (6 * 2 + 1,) and env.action_space.shape == (2,)
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(2))
        done = terminated or truncated
    scenario = scenario_for_model(PLANAR)
    rollout = ClosedLoop(scenario.model, scenario.loop).run([make("cubic").plan(scenario.task, scenario.model)])
    assert info["metrics"]["rms_err"] == pytest.approx(float(np.sqrt(np.mean(rollout.e ** 2))), rel=1e-9)
    check_env(env.unwrapped, skip_render_check=True)


def test_the_six_joint_ur5_with_its_wrist_at_zero_is_the_lumped_three_joint_model():
    """ur5_6dof.xml keeps the wrist as three links; at q4 = q5 = q6 = 0 (wrist at rest) the first three joints see
    exactly the forearm that ur5_3dof.xml lumps: the same mass matrix block, bias forces and flange."""
    six = prepare_arm(default_model_path().parent / "ur5_6dof.xml", dt=0.02)
    three = load_model(None, dt=0.02)
    probe6, probe3 = DynamicsProbe(six), DynamicsProbe(three)
    rng = np.random.default_rng(11)
    q, qd = rng.uniform(-2, 2, (30, 3)), rng.uniform(-1, 1, (30, 3))
    zero = np.zeros((30, 3))
    D6, h6 = probe6.mass_and_bias(np.hstack([q, zero]), np.hstack([qd, zero]))
    D3, h3 = probe3.mass_and_bias(q, qd)
    np.testing.assert_allclose(D6[:, :3, :3], D3, atol=1e-11)
    np.testing.assert_allclose(h6[:, :3], h3, atol=1e-10)
    np.testing.assert_allclose(probe6.gravity(np.hstack([q, zero]))[:, :3], probe3.gravity(q), atol=1e-10)
    np.testing.assert_array_equal(six.actuator_ctrlrange[:, 1], [60, 60, 60, 28, 28, 28])
    sites = []
    for model in (six, three):
        data = mujoco.MjData(model)
        data.qpos[:3] = [0.3, -1.1, 0.7]
        mujoco.mj_forward(model, data)
        sites.append(data.site("attachment_site").xpos.copy())
    np.testing.assert_allclose(sites[0], sites[1], atol=1e-12)


def test_pinocchio_agrees_on_the_six_joint_ur5():
    import pinocchio as pin  # a test dependency (extra 'test'): a missing one fails, never skips

    path = default_model_path().parent / "ur5_6dof.xml"
    pmodel = pin.buildModelFromMJCF(str(path))
    pdata = pmodel.createData()
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(5)
    for _ in range(20):
        q, v, a = rng.uniform(-2, 2, 6), rng.normal(size=6), rng.normal(size=6)
        data.qpos[:], data.qvel[:], data.qacc[:] = q, v, a
        mujoco.mj_inverse(model, data)
        np.testing.assert_allclose(pin.rnea(pmodel, pdata, q, v, a), data.qfrc_inverse, atol=1e-10)
        M = np.zeros((6, 6))
        mujoco.mj_fullM(model, data, M)
        np.testing.assert_allclose(pin.crba(pmodel, pdata, q), M, atol=1e-10)


def test_frontier_takes_a_user_arm(tmp_path, capsys):
    assert main(["frontier", "--model", str(PLANAR), "--alphas", "0,1", "--no-figures", "--out", str(tmp_path)]) == 0
    assert "on the scenario's task (planar_2link)" in capsys.readouterr().out


def test_a_stiffly_damped_arm_is_integrated_stably_by_every_part_of_the_study(tmp_path):
    """Joint damping of 30 N m s/rad on the planar arm's light second link (about 0.053 kg m^2): RK4 at 0.02 s
    diverges, one step or ten substeps short of the rule; the prepared arm is integrated by implicitfast in one
    step per period, and the executed arm, the nonlinear planner's rollouts and the floor's all stay bounded."""
    path = tmp_path / "damped.xml"
    path.write_text(PLANAR.read_text().replace('name="joint2" type="hinge"', 'name="joint2" type="hinge" damping="30"'))
    scenario = scenario_for_model(path)
    assert scenario.model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST and scenario.loop.substeps == 1
    reference = make("cubic").plan(scenario.task, scenario.model)
    ok = ClosedLoop(scenario.model, scenario.loop).run([reference])
    assert ok.diverged_step[0] == -1 and np.max(np.abs(ok.e)) < 1e-2
    bound = make("nonlinear_min_effort").plan(scenario.task, scenario.model)
    assert np.all(np.isfinite(bound.q)) and np.abs(bound.q[-1] - scenario.task.qg).max() < 1e-6
    rk4 = copy.copy(scenario.model)
    rk4.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    assert ClosedLoop(rk4, scenario.loop).run([reference]).diverged_step[0] >= 0


def test_a_continuous_joint_is_drawn_within_plus_minus_pi(tmp_path):
    """Oracle: the env's random task of an arm without a joint range is the draw by hand, [-pi, pi] there."""
    import gymnasium as gym

    free = tmp_path / "free.xml"
    free.write_text(PLANAR.read_text().replace(' range="-2.5 2.5"', ""))
    env = gym.make("ArmTrack-v0", xml_file=str(free), task="random")
    _, info = env.reset(seed=0)
    model = env.unwrapped.settings.model
    rng = np.random.default_rng(0)
    limited = model.jnt_limited.astype(bool)
    lower = np.where(limited, model.jnt_range[:, 0], -np.pi)
    upper = np.where(limited, model.jnt_range[:, 1], np.pi)
    q0 = rng.uniform(lower, upper)
    np.testing.assert_array_equal(info["task"]["q0"], q0)
    assert not limited.all()
    env.close()


@pytest.mark.slow
def test_a_sweep_and_its_audit_on_a_user_arm(tmp_path, capsys):
    from mjtraj.study.store import read_rows

    out = tmp_path / "arm.csv"
    assert main(["sweep", "--model", str(PLANAR), "--family", "nominal,aggressive", "--scenarios", "3",
                 "--planners", "optimal,cubic,quintic,trapezoidal", "--out", str(out), "--no-progress"]) == 0
    rows = read_rows(out)
    assert len(rows) == 2 * 3 * 4 and {r["model"] for r in rows} == {str(PLANAR)}
    assert {len(r["kp_0"]) > 0 and "kp_2" not in r for r in rows} == {True}  # two joints' gains
    assert main(["audit", str(out), "--out", str(tmp_path / "A.md")]) == 0
    text = (tmp_path / "A.md").read_text()
    assert "| paper task, ff_accel=sample, gravity_comp=native |" in text  # the arm's own task, run by the audit


def test_torque_limit_sets_every_joints_saturation_and_travels_with_the_scenario(tmp_path):
    from mjtraj.domain.scenario import load_scenario, scenario_from_dict
    from mjtraj.domain.toml_text import dumps
    from mjtraj.study.sweep import SweepSettings

    own = prepare_arm(PLANAR)
    np.testing.assert_array_equal(own.actuator_ctrlrange, [[-20, 20], [-20, 20]])  # the file's servo force ranges
    np.testing.assert_array_equal(prepare_arm(PLANAR, torque_limit=7.5).actuator_ctrlrange, [[-7.5, 7.5]] * 2)
    bare = tmp_path / "bare.xml"  # j2 has no force range anywhere: the flag supplies it
    bare.write_text(ARM.format(joint=HINGE, extra="", actuators='<motor joint="j1" ctrlrange="-5 5"/>'))
    np.testing.assert_array_equal(prepare_arm(bare, torque_limit=3.0).actuator_ctrlrange, [[-3, 3], [-3, 3]])
    scenario = scenario_for_model(PLANAR, torque_limit=7.5)
    np.testing.assert_array_equal(scenario.torque_limit, [7.5, 7.5])
    assert scenario.as_dict()["torque_limit"] == 7.5
    again = scenario_from_dict(scenario.as_dict())
    np.testing.assert_array_equal(again.model.actuator_ctrlrange, [[-7.5, 7.5]] * 2)
    path = tmp_path / "arm.toml"
    path.write_text(dumps(scenario.as_dict()))
    np.testing.assert_array_equal(load_scenario(path).torque_limit, [7.5, 7.5])
    settings = SweepSettings(scenarios=2, planners=("cubic",), model=str(PLANAR), torque_limit=7.5)
    assert settings.record()["torque_limit"] == 7.5
    rebuilt = SweepSettings.from_record({k: str(v) for k, v in settings.record().items()})
    assert rebuilt.torque_limit == 7.5 and rebuilt.record() == settings.record()


def test_torque_limit_bounds_the_corrective_torque_in_compare_and_the_env(tmp_path, capsys):
    import json

    import gymnasium as gym

    assert main(["compare", "--model", str(PLANAR), "--torque-limit", "2.5", "--no-figures", "--json", "--out",
                 str(tmp_path)]) == 0
    rows = json.loads(capsys.readouterr().out)["planners"]
    peaks = [row["metrics"]["peak_dtau"] for row in rows.values()]
    assert peaks and max(peaks) <= 2.5 + 1e-12 and max(peaks) > 2.0  # the move saturates at the given limit
    env = gym.make("ArmTrack-v0", xml_file=str(PLANAR), torque_limit=4.0)
    np.testing.assert_array_equal(env.unwrapped.settings.model.actuator_ctrlrange, [[-4, 4], [-4, 4]])
    env.close()


@pytest.mark.parametrize(("argv", "message"), [
    (["compare", "--torque-limit", "5"], "torque-limit: only with --model (a scenario file sets torque_limit beside "
                                         "model)"),
    (["compare", "--model", str(PLANAR), "--torque-limit", "-1"], "torque_limit: expected a positive number, got "
                                                                  "-1.0"),
    (["compare", "--model", str(PLANAR), "--torque-limit", "nan"], "torque_limit: expected a positive number, got "
                                                                   "nan"),
])
def test_bad_torque_limits_are_one_line(argv, message, capsys):
    assert main(argv) == 2
    assert capsys.readouterr().err == f"mjtraj: error: {message}\n"


def test_bad_torque_limits_in_files_and_the_env(tmp_path):
    import gymnasium as gym

    from mjtraj.domain.scenario import load_scenario, scenario_from_dict
    from mjtraj.exceptions import InvalidInputError

    paper = load_scenario().as_dict()
    with pytest.raises(InvalidInputError, match=r'^config: torque_limit: only with model = "PATH"'):
        scenario_from_dict({**paper, "torque_limit": 5.0})
    arm = scenario_for_model(PLANAR).as_dict()
    for bad in (0, -2.0, True, "5", float("inf")):
        with pytest.raises(InvalidInputError, match=r"^config: torque_limit: expected a positive number \(N m\)"):
            scenario_from_dict({**arm, "torque_limit": bad})
    with pytest.raises(InvalidInputError, match=r"^torque_limit: only with xml_file \(your own arm\), got 5"):
        gym.make("UR5Track-v0", torque_limit=5)
    with pytest.raises(InvalidInputError, match=r"^torque_limit: only for your own arm"):
        load_model(torque_limit=5.0)


def test_the_mismatch_plant_of_a_user_arm_carries_its_payload_by_the_flange_rule():
    """The planar arm has no attachment_site: the payload sits at link2's centre of mass. Oracle: the gravity
    torque of a point mass m there, m g (l1 cos q1 + lc2 cos(q1 + q2)) and m g lc2 cos(q1 + q2), is what the
    plant adds at rest, not compensated; with no payload, unit scales and no damping or friction the plant
    executes as the nominal model."""
    from mjtraj.domain.families import Perturbation, perturbed_plant, plant_fields

    model = prepare_arm(PLANAR)
    plant = perturbed_plant(model, str(PLANAR))
    payload = plant.body("mjtraj_payload")
    assert plant.body(int(payload.parentid[0])).name == "link2"
    np.testing.assert_array_equal(plant.body_pos[payload.id], [LC2, 0.0, 0.0])
    data = mujoco.MjData(plant)
    mass = 3.0
    plant.body_mass[payload.id] = mass
    for q in ([0.3, -0.7], [-1.2, 2.0], [2.5, 0.4]):
        data.qpos[:] = q
        mujoco.mj_forward(plant, data)
        uncompensated = data.qfrc_bias - data.qfrc_gravcomp
        expected = mass * G * np.array([L1 * np.cos(q[0]) + LC2 * np.cos(q[0] + q[1]), LC2 * np.cos(q[0] + q[1])])
        np.testing.assert_allclose(uncompensated, expected, atol=1e-10)
    scenario = scenario_for_model(PLANAR)
    ref = make("cubic").plan(scenario.task, scenario.model)
    identity = Perturbation(0.0, np.ones(2), np.ones(2), np.zeros(2), np.zeros(2))
    plant = perturbed_plant(scenario.model, str(PLANAR))
    nominal = ClosedLoop(scenario.model, scenario.loop).run([ref])
    fields = plant_fields(plant, [identity])
    same = ClosedLoop(scenario.model, scenario.loop, plant=plant, plant_fields=fields).run([ref])
    np.testing.assert_allclose(same.q, nominal.q, atol=1e-12)


def test_the_mismatch_family_on_a_user_arm_in_a_sweep_and_the_env(tmp_path):
    import gymnasium as gym

    from mjtraj.study.store import read_rows

    out = tmp_path / "arm.csv"
    assert main(["sweep", "--model", str(PLANAR), "--family", "mismatch", "--scenarios", "4", "--planners",
                 "cubic,optimal", "--out", str(out), "--no-progress"]) == 0
    rows = read_rows(out)
    assert len(rows) == 8 and {r["status"] for r in rows} == {"ok"}
    assert {r["family"] for r in rows} == {"mismatch"} and "mass_scale_1" in rows[0] and "mass_scale_2" not in rows[0]
    assert len({r["payload_kg"] for r in rows}) == 4  # one plant per scenario
    env = gym.make("ArmTrack-v0", xml_file=str(PLANAR), plant_randomization="mismatch")
    _, info = env.reset(seed=3)
    assert set(info["plant"]) == {"payload_kg", *(f"{name}_{j}" for name in ("mass_scale", "inertia_scale",
                                                                           "damping", "friction") for j in (0, 1))}
    terminated = truncated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(np.zeros(2))
    assert not info["diverged"]


def test_a_body_moved_by_two_joints_cannot_be_scaled_one_link_per_joint(tmp_path):
    from mjtraj.domain.families import perturbed_plant

    two = tmp_path / "two.xml"
    two.write_text(PLANAR.read_text().replace(
        '<joint name="joint2" type="hinge" axis="0 -1 0" range="-2.5 2.5"/>',
        '<joint name="joint2" type="hinge" axis="0 -1 0" range="-2.5 2.5"/>'
        '<joint name="joint3" type="hinge" axis="0 0 1" range="-1 1"/>').replace(
        '</actuator>', '<position name="servo3" joint="joint3" kp="100" forcerange="-20 20"/></actuator>'))
    with pytest.raises(ModelError, match=rf"^model {two}: body link2 is moved by two joints; the mismatch family "
                                         r"scales one link per joint, so it runs only on arms with one hinge per "
                                         r"body \(the other families run\)$"):
        perturbed_plant(prepare_arm(two), str(two))


def test_a_grippers_fingers_are_held_where_its_home_keyframe_puts_them(tmp_path, capsys):
    """Oracle: the file itself, compiled by MuJoCo at its 'home' keyframe, puts every body (fingers included)
    where the prepared arm puts it at the same hinge angles; the fingers' joints, their mimic equality and their
    actuator are gone, and compare names what it held."""
    from arm_suite import FINGERS, THREE, chain

    from mjtraj.core.arm import held_joints

    path = tmp_path / "gripper.xml"
    path.write_text(chain("gripper", THREE, tail=(
        '<equality><joint joint1="finger_left" joint2="finger_right"/></equality>'
        '<keyframe><key name="home" qpos="0.2 0.3 -0.6 0.015 0.015"/></keyframe>'),
        actuators='<actuator><position name="grip" joint="finger_left" kp="100" ctrlrange="0 0.04"/></actuator>'
        ).replace('<site name="attachment_site"', FINGERS + '<site name="attachment_site"'))
    original = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(original)
    mujoco.mj_resetDataKeyframe(original, data, 0)
    mujoco.mj_kinematics(original, data)
    model = prepare_arm(path)
    assert (model.nq, model.nu, model.neq) == (3, 3, 0)
    assert held_joints(model) == ("finger_left held at 0.015 m (its 'home' keyframe); finger_right held at 0.015 m "
                                  "(its 'home' keyframe)")
    mine = mujoco.MjData(model)
    mine.qpos[:] = data.qpos[:3]
    mujoco.mj_kinematics(model, mine)
    for body in ("hand", "left", "right"):
        np.testing.assert_allclose(mine.xpos[model.body(body).id], data.xpos[original.body(body).id], atol=1e-12)
    assert main(["compare", "--model", str(path), "--no-figures", "--out", str(tmp_path / "out")]) == 0
    assert "  held fixed (not planned): finger_left held at 0.015 m" in capsys.readouterr().out


def test_a_stiffly_damped_joint_is_integrated_implicitly(tmp_path, capsys):
    """A wrist whose damping (20 N m s/rad) over its inertia is ~10^4 1/s: RK4 at the 20 ms period blows up on a
    1 N m step (MuJoCo resets it); the prepared arm integrates by implicitfast, says why, and the wrist settles at
    the closed-form speed torque / damping. The UR5 and the lightly damped arms keep RK4 (their numbers unchanged)."""
    from arm_suite import chain

    from mjtraj.core.arm import integrator_note
    from mjtraj.core.model import load_model

    links = [("0 0 1", "-3 3", 0.1, 2.0), ("0 1 0", "-2 2", 0.4, 1.5), ("0 1 0", "-2.5 2.5", 0.35, 1.0),
             ("1 0 0", "-3 3", 0.05, 0.3)]
    path = tmp_path / "stiff.xml"
    path.write_text(chain("stiff", links, joint_extra=' damping="20"'))
    explicit = arm_spec(path, dt=0.02)
    explicit.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    for model, settles in ((explicit.compile(), False), (prepare_arm(path, dt=0.02), True)):
        data = mujoco.MjData(model)
        data.ctrl[:] = [0.0, 0.0, 0.0, 1.0]
        for _ in range(50):
            mujoco.mj_step(model, data)
        assert bool(abs(data.qvel[3] - 0.05) < 1e-6) is settles
    model = prepare_arm(path, dt=0.02)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert integrator_note(model).startswith("implicitfast, not RK4: joint j3's damping x timestep / inertia is ")
    assert main(["compare", "--model", str(path), "--no-figures", "--out", str(tmp_path / "out")]) == 0
    assert "  integrator: implicitfast, not RK4: joint j3's" in capsys.readouterr().out
    for rk4 in (load_model(), prepare_arm(PLANAR, dt=0.02), prepare_arm("ur5_6dof", dt=0.02)):
        assert rk4.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and integrator_note(rk4) == ""
