"""Computed torque, the second control law inside the one closed loop: on the exact model it tracks a realisable
reference with zero error; batch equals single; its output is its formula; it is selectable from scenario files,
the command line and the env, and recorded in sweep rows."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

from mjtraj.cli import main
from mjtraj.core.closed_loop import ClosedLoop, LoopConfig
from mjtraj.core.controller import ComputedTorque
from mjtraj.core.dynamics import DynamicsProbe
from mjtraj.core.planners import make
from mjtraj.core.reference import Reference
from mjtraj.domain.scenario import default_scenario_path
from mjtraj.study.store import read_rows


def realisable(model, q0, torques):
    """The nominal plant's own motion under zero-order-held torques (N, n) from rest at q0, as a reference whose
    qdd_ref,k is the acceleration at (q_k, qd_k, u_k): exactly what inverse dynamics at that state inverts."""
    data = mujoco.MjData(model)
    data.qpos[:] = q0
    q, qd, qdd = [data.qpos.copy()], [data.qvel.copy()], []
    for u in torques:
        data.ctrl[:] = u
        mujoco.mj_forward(model, data)
        qdd.append(data.qacc.copy())
        mujoco.mj_step(model, data)
        q.append(data.qpos.copy())
        qd.append(data.qvel.copy())
    qdd.append(np.zeros(model.nv))
    N = len(torques)
    t = np.arange(N + 1) * model.opt.timestep
    return Reference("rollout", t, np.array(q), np.array(qd), np.array(qdd), u_plan=np.array(torques))


def computed_torque(scenario, **changes):
    return LoopConfig(scenario.loop.gains, controller="computed_torque", **changes)


def test_on_the_exact_model_it_tracks_a_realisable_reference_with_zero_error(scenario):
    model = scenario.model
    k = np.arange(100)[:, None]
    torques = 1.5 * np.sin(2 * np.pi * k / 100 * np.array([1.0, 2.0, 3.0])) + np.array([0.0, 0.5, -0.3])
    reference = realisable(model, scenario.task.q0, torques)
    lower, upper = model.jnt_range.T
    assert np.all((reference.q > lower + 0.1) & (reference.q < upper - 0.1))  # no joint-limit force: a free arm
    rollout = ClosedLoop(model, computed_torque(scenario)).run([reference])
    assert np.max(np.abs(rollout.e)) < 1e-10 and np.max(np.abs(rollout.dtau[0] - torques)) < 1e-9
    feedback_only = ClosedLoop(model, LoopConfig(scenario.loop.gains, feedforward="none")).run([reference])
    assert np.max(np.abs(feedback_only.e)) > 1e-3  # PID alone does not: the reference is a real test


def test_its_output_is_its_formula(scenario):
    """dtau = clip(D(q) (qdd_ref + kp e + kd ed) + h(q, qd)), with D and h from an independent mj_fullM/qfrc path."""
    model = scenario.model
    rng = np.random.default_rng(4)
    B, n = 5, model.nv
    q, qd = rng.uniform(-1, 1, (B, n)), rng.uniform(-1, 1, (B, n))
    e, ed, qdd = rng.normal(0, 0.01, (B, n)), rng.normal(0, 0.1, (B, n)), rng.normal(0, 2, (B, n))
    law = ComputedTorque.for_period(0.02, n)
    out = law(e, ed, np.zeros((B, n)), np.zeros((B, n)), qdd, DynamicsProbe(model).mass_and_bias(q, qd),
              np.full((B, n), 10.0), 0.02)
    w = 2 * np.pi / (20 * 0.02)
    data = mujoco.MjData(model)
    for b in range(B):
        data.qpos[:], data.qvel[:] = q[b], qd[b]
        mujoco.mj_forward(model, data)
        D = np.zeros((n, n))
        mujoco.mj_fullM(model, data, D)
        h = data.qfrc_bias - data.qfrc_passive - data.qfrc_gravcomp
        command = D @ (qdd[b] + w * w * e[b] + 2 * w * ed[b]) + h
        np.testing.assert_allclose(out.dtau[b], np.clip(command, -10, 10), rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(out.saturated[b], np.abs(command) > 10)


def test_batch_equals_single(scenario):
    model = scenario.model
    config = computed_torque(scenario, ff_accel="step_average")
    tasks = [scenario.task, scenario.replace(task={"q0": scenario.task.qg, "qg": scenario.task.q0}).task]
    references = [make(name).plan(task, model) for task in tasks for name in ("cubic", "optimal")]
    batch = ClosedLoop(model, config, nsim=len(references)).run(references)
    for b, reference in enumerate(references):
        single = ClosedLoop(model, config).run([reference])
        for name in ("q", "e", "dtau", "tau_ff", "tau_fb"):
            np.testing.assert_array_equal(getattr(batch, name)[b], getattr(single, name)[0])


@pytest.mark.slow
def test_selectable_from_the_cli_and_recorded_in_sweep_rows(tmp_path, capsys):
    assert main(["compare", "--controller", "computed_torque", "--planners", "cubic", "--no-figures", "--out",
                 str(tmp_path / "c")]) == 0
    out = capsys.readouterr().out
    assert "controller = computed_torque," in out and "identical computed_torque," in out
    config = tmp_path / "ct.toml"
    shipped = default_scenario_path().read_text()
    config.write_text(shipped.replace('anti_windup = "none"', 'anti_windup = "none"\ncontroller = "computed_torque"'))
    assert main(["sweep", "--config", str(config), "--scenarios", "2", "--planners", "cubic", "--out",
                 str(tmp_path / "s.csv"), "--no-progress"]) == 0
    assert {row["controller"] for row in read_rows(tmp_path / "s.csv")} == {"computed_torque"}


def test_the_env_runs_it_and_scores_it_like_the_loop(scenario):
    env = gym.make("UR5Track-v0", controller="computed_torque", action_mode="residual")
    _, info = env.reset(seed=0, options={"q0": scenario.task.q0, "qg": scenario.task.qg, "duration": 2.0})
    total, done = 0.0, False
    while not done:
        _, reward, terminated, truncated, info = env.step(np.zeros(3))
        total += reward
        done = terminated or truncated
    reference = make("cubic").plan(scenario.task, scenario.model)
    rollout = ClosedLoop(scenario.model, computed_torque(scenario)).run([reference])
    assert info["metrics"]["rms_err"] == pytest.approx(float(np.sqrt(np.mean(rollout.e ** 2))), rel=1e-9)
