"""Every arm of the suite (tests/arm_suite.py) through every command: compare (with figures on the first arm of each
number of joints, whose layout they follow), render, sweep (nominal and mismatch; on one worker but for the arms of
several files), frontier, tune and ArmTrack-v0 (make, reset, step, render, pickle, check_env). Oracles: no NaN where
a row is ok, its peak corrective torque within the saturation and its terminal error within the goal rule (0.2 of the
move); every planner of every nominal compare reaches its goal under the default gains; on the nominal plant the
cubic reaches the goal of every nominal task, within 2 % of its move (RMS error within 5 %) on arms without dry
friction; the files that must be refused are refused in one line matching what is unsupported. `python -m pytest
tests/test_arm_suite.py -m slow -s` prints the table of arms x commands."""

from __future__ import annotations

import pickle
import re
import warnings

import gymnasium as gym
import mjtraj.envs  # noqa: F401
import numpy as np
import pytest
from arm_suite import write_suite

from mjtraj.cli import main
from mjtraj.core.arm import prepare_arm
from mjtraj.study.store import read_rows

COMMANDS = ("compare", "render", "sweep", "frontier", "tune", "env")
RESULTS: dict[str, dict[str, str]] = {}


@pytest.fixture(scope="module")
def suite(tmp_path_factory):
    return write_suite(tmp_path_factory.mktemp("arms"))


def run(argv, capsys) -> tuple[int, str, str]:
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def check_env(path) -> None:
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = gym.make("ArmTrack-v0", xml_file=str(path), task="random", action_mode="residual",
                   render_mode="rgb_array", width=48, height=32)
    obs, info = env.reset(seed=0)
    assert np.isfinite(obs).all() and "task" in info
    for _ in range(3):
        obs, reward, *_ = env.step(env.action_space.sample() * 0.0)
        assert np.isfinite(obs).all() and np.isfinite(reward)
    frame = env.render()
    assert frame.shape == (32, 48, 3)
    clone = pickle.loads(pickle.dumps(env.unwrapped))
    np.testing.assert_array_equal(clone.step(np.zeros(env.action_space.shape))[0],
                                  env.unwrapped.step(np.zeros(env.action_space.shape))[0])
    env.close()
    clone.close()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sb3_check(gym.make("ArmTrack-v0", xml_file=str(path), task="random", action_mode="residual").unwrapped)


@pytest.mark.slow
def test_every_arm_through_every_command(suite, tmp_path, capsys):
    figured: set[int] = set()
    for name, path, refusal in suite:
        out = tmp_path / name
        row = RESULTS.setdefault(name, {})
        if refusal is not None:
            code, _, err = run(["compare", "--model", str(path), "--no-figures", "--out", str(out)], capsys)
            assert code == 2 and err.count("\n") == 1 and re.search(refusal, err), (name, err)
            row.update({c: "refused" for c in COMMANDS})
            continue
        joints = prepare_arm(path).nu  # one motor per planned joint
        drawn = joints not in figured  # the figures on the first arm of each number of joints (their layout)
        figured.add(joints)
        code, text, err = run(["compare", "--model", str(path), "--out", str(out),
                               *(() if drawn else ("--no-figures",))], capsys)
        assert code == 0, (name, err)
        assert (len(list(out.glob("*.png"))) >= 4) == drawn, name
        assert "nan" not in text.split("Table I")[1].split("\n\n")[0]
        assert "every planner reached its goal" in text, (name, text)  # the default gains move every arm
        row["compare"] = "ok"
        code, _, err = run(["render", "--model", str(path), "--planners", "cubic", "--width", "64", "--height",
                            "48", "--every", "25", "--format", "gif", "--out", str(out / "videos")], capsys)
        assert code == 0 and list((out / "videos").glob("*.gif")), (name, err)
        row["render"] = "ok"
        store = out / "sweep.csv"
        pool = () if name in ("include", "meshes", "urdf") else ("--workers", "1")  # files the workers resolve
        code, _, err = run(["sweep", "--model", str(path), "--family", "nominal,mismatch", "--scenarios", "6",
                            "--planners", "cubic,optimal", *pool, "--out", str(store), "--no-progress"], capsys)
        assert code == 0, (name, err)
        rows = read_rows(store)
        limit = max(float(v) for v in re.findall(r"\|dtau\| <= \[?([0-9., ]+)", text)[0].split(",") if v.strip())
        for r in rows:
            move = float(r["max_displacement"])
            if r["status"] == "ok":  # the sanity oracle of every row: finite, within the saturation, at its goal
                assert all(np.isfinite(float(r[m])) for m in ("cost", "rms_err", "rms_dtau")), (name, r)
                assert float(r["peak_dtau"]) <= limit * (1 + 1e-9), (name, r["peak_dtau"], limit)
                assert float(r["terminal_err"]) <= 0.2 * move, (name, r)
            else:
                assert r["reason"], (name, r)
            if r["family"] == "nominal" and r["planner"] == "cubic":
                assert r["status"] == "ok", (name, r["reason"])  # friction arms too: the goal rule holds
                if "frictionloss" not in path.read_text():  # and without dry friction, close to the goal
                    assert float(r["terminal_err"]) < 0.02 * move and float(r["rms_err"]) < 0.05 * move, name
        row["sweep"] = "ok" if all(r["status"] == "ok" for r in rows) else \
            ", ".join(sorted({r["status"] for r in rows}))
        code, _, err = run(["frontier", "--model", str(path), "--alphas", "0,1", "--splits", "0.5", "--out",
                            str(out / "frontier"), "--no-progress"], capsys)
        assert code == 0 and (out / "frontier" / "frontier.png").exists(), (name, err)
        row["frontier"] = "ok"
        code, _, err = run(["tune", "--model", str(path), "--planners", "trapezoidal", "--scenarios", "3",
                            "--budget", "2", "--out", str(out / "tuned.toml"), "--no-progress"], capsys)
        assert code == 0, (name, err)
        assert main(["compare", "--config", str(out / "tuned.toml"), "--no-figures", "--out", str(out / "t")]) == 0
        capsys.readouterr()
        row["tune"] = "ok"
        check_env(path)
        row["env"] = "ok"
    with capsys.disabled():
        print("\n| arm | " + " | ".join(COMMANDS) + " |\n|---|" + "---|" * len(COMMANDS))
        for name, row in RESULTS.items():
            print(f"| {name} | " + " | ".join(row.get(c, "-") for c in COMMANDS) + " |")
        sane = sum(all(v != "refused" for v in r.values()) for r in RESULTS.values())
        print(f"\n{sane} arms ran every command; {len(RESULTS) - sane} files refused in one line")
