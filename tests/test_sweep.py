"""Sweeps, their statistics and the audit: oracles (mj_inverse, OSQP, closed forms), determinism, resume, bad input."""

from __future__ import annotations

import csv
import signal
import subprocess
import sys
import time

import mujoco
import numpy as np
import pytest

from mjtraj.closed_loop import ClosedLoop, LoopConfig
from mjtraj.dynamics import DynamicsProbe
from mjtraj.exceptions import BackendError, InvalidInputError
from mjtraj.families import Perturbation, perturbed_plant, plant_fields, scenario
from mjtraj.planners import make
from mjtraj.stats import cvar, paired_ratio
from mjtraj.sweep import SweepSettings, run_unit
from mjtraj.sweep_runner import run_sweep
from mjtraj.task import random_task

SMALL = dict(scenarios=6, batch=3, planners=("optimal", "cubic"))


def test_probe_matches_mj_inverse_and_mj_forward(model, rng):
    q, qd, qdd = rng.uniform(-3, 3, (50, 3)), rng.uniform(-2, 2, (50, 3)), rng.uniform(-5, 5, (50, 3))
    probe = DynamicsProbe(model, size=7)  # several chunks
    ff, acc = probe.inverse(q, qd, qdd), probe.accelerations(q, qd, qdd)
    data = mujoco.MjData(model)
    for k in range(50):
        data.qpos[:], data.qvel[:], data.qacc[:] = q[k], qd[k], qdd[k]
        mujoco.mj_inverse(model, data)
        np.testing.assert_allclose(ff[k], data.qfrc_inverse - data.qfrc_gravcomp, rtol=1e-12, atol=1e-11)
        data.ctrl[:] = qdd[k]
        mujoco.mj_forward(model, data)
        assert np.array_equal(acc[k], data.qacc)


def test_active_set_riccati_equals_osqp(model, rng):
    """The exact solver and OSQP agree on random tasks, with and without active torque bounds."""
    tasks = [random_task(rng, model, max_displacement=1.5, duration=T, dt=0.02) for T in (2.0, 0.6, 0.8) * 4]
    auto, osqp = make("optimal"), make("optimal", solver="osqp")
    plans = auto.plan_many(tasks, model)
    active = 0
    for task, ref in zip(tasks, plans, strict=True):
        try:
            expected = osqp.plan(task, model)
        except Exception as e:  # noqa: BLE001
            assert type(ref) is type(e)
            continue
        assert ref.info["solver"] == "riccati-active-set"
        active += ref.info["active_bounds"] > 0
        np.testing.assert_allclose(ref.u_plan, expected.u_plan, atol=1e-6)
        assert ref.info["objective"] <= expected.info["objective"] * (1 + 1e-9)
        assert ref.info["terminal_residual"] < 1e-9
    assert active >= 2  # the bounds bind in some of them


def test_cvar_closed_forms():
    assert cvar(np.arange(1, 101), 0.9) == pytest.approx(95.5)
    assert cvar([5.0] * 7, 0.9) == pytest.approx(5.0)
    x = np.random.default_rng(0).exponential(size=400_000)  # CVaR_0.9 = ln 10 + 1
    assert cvar(x, 0.9) == pytest.approx(np.log(10) + 1, rel=5e-3)
    with pytest.raises(InvalidInputError, match=r"^alpha: expected a level in \[0, 1\), got 1.0$"):
        cvar(x, 1.0)


def test_paired_ratio_exact_cases_and_coverage():
    b = np.random.default_rng(1).uniform(1, 2, 300)
    r = paired_ratio(2 * b, b)
    assert (r.ratio, r.low, r.high, r.win_rate) == (pytest.approx(2), pytest.approx(2), pytest.approx(2), 1.0)
    assert r.reduction[0] == pytest.approx(50.0)
    rng = np.random.default_rng(2)
    covered = 0
    for _ in range(40):  # true ratio of means 1.5
        y = rng.exponential(size=200)
        x = 1.5 * rng.exponential(size=200)
        ci = paired_ratio(x, y, resamples=500)
        covered += ci.low <= 1.5 <= ci.high
    assert covered >= 34  # nominal 95 %: 38 of 40 expected


def test_unit_rows_are_deterministic_and_backend_independent(tmp_path):
    settings = SweepSettings(**SMALL)
    one, two = run_unit(settings, ("nominal", 1)), run_unit(settings, ("nominal", 1))
    assert one.rows == two.rows or all(
        all((a[k] == b[k]) or (a[k] != a[k] and b[k] != b[k]) for k in a) for a, b in zip(one.rows, two.rows, strict=True))
    run_sweep(settings, tmp_path / "a.csv", workers=1, progress=False)
    run_sweep(settings, tmp_path / "b.csv", workers=2, progress=False)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    rows = list(csv.DictReader(open(tmp_path / "a.csv")))
    assert len(rows) == 12 and {r["status"] for r in rows} == {"ok"}
    assert {r["mjtraj"] for r in rows} and rows[0]["sweep_seed"] == "0"


def test_a_failed_scenario_is_recorded_and_the_sweep_goes_on(tmp_path):
    settings = SweepSettings(families=("aggressive",), scenarios=60, batch=30, planners=("optimal", "cubic"))
    report = run_sweep(settings, tmp_path / "s.csv", workers=1, progress=False)  # scenario 49 is infeasible
    rows = list(csv.DictReader(open(tmp_path / "s.csv")))
    assert len(rows) == 120 and report.statuses["infeasible"] >= 1 and report.statuses["ok"] >= 100
    bad = [r for r in rows if r["status"] == "infeasible"]
    assert all(r["planner"] == "optimal" and r["reason"].startswith("InfeasibleError: optimal: x_N = 0 cannot") and
               r["rms_err"] == "nan" for r in bad)


def test_resume_after_kill_gives_the_uninterrupted_file(tmp_path):
    args = ["--scenarios", "40", "--batch", "4", "--planners", "optimal,cubic", "--workers", "1", "--no-progress"]
    whole, cut = tmp_path / "whole.csv", tmp_path / "cut.csv"
    subprocess.run([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(whole)], check=True,
                   capture_output=True)
    proc = subprocess.Popen([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(cut)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and (not cut.exists() or cut.read_text().count("\n") < 1 + 3 * 8):
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    written = cut.read_bytes()
    assert 0 < len(written) < len(whole.read_bytes())
    with open(cut, "ab") as f:
        f.write(b"nominal,39,9,opt")  # a torn unit at the end
    out = subprocess.run([sys.executable, "-m", "mjtraj", "sweep", *args, "--out", str(cut), "--resume"],
                         check=True, capture_output=True, text=True)
    assert "units were already done" in out.stdout
    assert cut.read_bytes() == whole.read_bytes()


def test_resume_refuses_other_settings_and_versions(tmp_path):
    path = tmp_path / "s.csv"
    run_sweep(SweepSettings(**SMALL), path, workers=1, progress=False)
    with pytest.raises(InvalidInputError, match=r"exists; pass --resume"):
        run_sweep(SweepSettings(**SMALL), path, workers=1, progress=False)
    with pytest.raises(InvalidInputError, match=r"^out: cannot resume .*: setting 'sweep_seed' differs \(file: '0', "
                                                r"now: '1'\)"):
        run_sweep(SweepSettings(**{**SMALL, "seed": 1}), path, resume=True, workers=1, progress=False)
    text = path.read_text().splitlines()
    header = text[0].split(",")
    i = header.index("mujoco")
    cells = text[1].split(",")
    cells[i] = "3.0.0"
    path.write_text("\n".join([text[0], ",".join(cells), *text[2:]]) + "\n")
    with pytest.raises(InvalidInputError, match=r"it was written by mujoco 3.0.0, this is mujoco "):
        run_sweep(SweepSettings(**SMALL), path, resume=True, workers=1, progress=False)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"families": ("nominl",)}, "family: unknown value 'nominl'; valid: nominal, aggressive, mismatch"),
    ({"planners": ("splines",)}, "planner: unknown value 'splines'; valid: cubic, optimal, quintic, trapezoidal, "
                                 "optimal_start, min_effort"),
    ({"ff_accel": ("mean",)}, "ff_accel: unknown value 'mean'; valid: sample, step_average"),
    ({"delay": 2}, "delay: expected 0 or 1 control periods, got 2"),
    ({"scenarios": 0}, "scenarios: expected a whole number >= 1, got 0"),
])
def test_bad_settings(kwargs, message):
    with pytest.raises(InvalidInputError) as info:
        SweepSettings(**kwargs)
    assert str(info.value) == message


def test_bad_backend_and_unreachable_ray(tmp_path):
    with pytest.raises(InvalidInputError, match=r"^backend: unknown value 'dask'; valid: local, ray$"):
        run_sweep(SweepSettings(**SMALL), tmp_path / "a.csv", backend="dask", progress=False)
    pytest.importorskip("ray")
    with pytest.raises(BackendError, match=r"^ray_address: cannot reach a Ray cluster at 127.0.0.1:9 \("):
        run_sweep(SweepSettings(**SMALL), tmp_path / "b.csv", backend="ray", ray_address="127.0.0.1:9",
                  progress=False)
    assert not (tmp_path / "b.csv").exists()


def test_cli_reports_bad_family(capsys):
    from mjtraj.cli import main

    assert main(["sweep", "--family", "wild", "--out", "x.csv"]) == 2
    assert capsys.readouterr().err == ("mjtraj: error: family: unknown value 'wild'; valid: nominal, aggressive, "
                                       "mismatch\n")


def test_unperturbed_plant_reproduces_the_nominal_one(model, scenario):
    """The payload body and per-simulation fields change nothing when the perturbation is the identity."""
    ref = make("cubic").plan(scenario.task, model)
    identity = Perturbation(0.0, np.ones(3), np.ones(3), np.zeros(3), np.zeros(3))
    plant = perturbed_plant(model)
    nominal = ClosedLoop(model, scenario.loop, nsim=2).run([ref, ref])
    perturbed = ClosedLoop(model, scenario.loop, nsim=2, plant=plant,
                           plant_fields=plant_fields(plant, [identity, identity])).run([ref, ref])
    np.testing.assert_allclose(perturbed.q, nominal.q, atol=1e-12)
    heavy = Perturbation(5.0, np.ones(3), np.ones(3), np.zeros(3), np.zeros(3))
    sagging = ClosedLoop(model, scenario.loop, nsim=1, plant=plant,
                         plant_fields=plant_fields(plant, [heavy])).run([ref])
    assert np.abs(sagging.e).max() > 10 * np.abs(nominal.e).max()
    assert model.nbody == 4  # the nominal model is untouched


def test_delay_and_noise(model, scenario):
    ref = make("cubic").plan(scenario.task, model)
    plain = ClosedLoop(model, scenario.loop).run([ref])
    silent = ClosedLoop(model, scenario.loop).run([ref], noise=np.zeros((100, 1, 6)))
    assert np.array_equal(plain.q, silent.q)
    delayed_cfg = LoopConfig(scenario.loop.gains, delay=1)
    delayed = ClosedLoop(model, delayed_cfg).run([ref])
    command = np.clip(delayed.tau_ff + delayed.tau_fb, -60, 60)
    assert np.all(delayed.dtau[0, 0] == 0.0)
    np.testing.assert_array_equal(delayed.dtau[0, 1:], command[0, :-1])


def test_mismatch_scenarios_are_seeded(model):
    a, b = scenario("mismatch", 3, 17, model, 0.02), scenario("mismatch", 3, 17, model, 0.02)
    assert np.array_equal(a.task.q0, b.task.q0) and a.perturbation.payload == b.perturbation.payload
    assert 0 <= a.perturbation.payload <= 5 and np.all(np.abs(a.task.displacement) <= 1.5)
    c = scenario("aggressive", 3, 17, model, 0.02)
    assert 0.5 <= c.task.duration <= 1.0


def test_ray_backend_gives_the_local_rows(tmp_path):
    pytest.importorskip("ray")
    settings = SweepSettings(**SMALL)
    run_sweep(settings, tmp_path / "local.csv", workers=1, progress=False)
    run_sweep(settings, tmp_path / "ray.csv", backend="ray", workers=2, progress=False)
    assert (tmp_path / "ray.csv").read_bytes() == (tmp_path / "local.csv").read_bytes()


def test_audit_from_a_sweep_file(tmp_path):
    from mjtraj.audit import audit

    path = tmp_path / "s.csv"
    run_sweep(SweepSettings(scenarios=8, batch=8, planners=("optimal", "cubic", "quintic", "trapezoidal",
                                                              "optimal_start", "min_effort"), model_error=True),
              path, workers=1, progress=False)
    text = audit([path], tmp_path / "AUDIT.md")
    assert (tmp_path / "AUDIT.md").read_text() == text
    for k in range(1, 7):
        assert f"## Claim {k}:" in text
    assert "(not measured)" not in text
    assert (tmp_path / "AUDIT_figures" / "ratios_nominal_sample_native.png").is_file()
