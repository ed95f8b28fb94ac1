"""Rendering: frames of the arm with its ghost, renderer limits, the render command and the doctor."""


from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import imageio.v3 as iio
import numpy as np
import pytest

from mjtraj.cli import main
from mjtraj.exceptions import InvalidInputError
from mjtraj.media.render import ArmRenderer


def test_env_frame_shows_the_arm(model):
    env = gym.make("UR5Track-v0", render_mode="rgb_array", width=320, height=240)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    with ArmRenderer(model, width=320, height=240) as renderer:
        elsewhere = renderer.frame([np.pi, -1.57, 0], [np.pi, -1.57, 0])  # the arm turned away
    # the arm (with its ghost) covers thousands of pixels: not a blank or floor-only frame
    assert (np.abs(frame.astype(int) - elsewhere).max(axis=2) > 30).sum() > 2000



def test_ghost_arm_is_drawn_where_the_reference_is(model):
    with ArmRenderer(model, width=320, height=240) as renderer:
        alone = renderer.frame([0, -1.57, 0])
        same = renderer.frame([0, -1.57, 0], [0, -1.57, 0])
        apart = renderer.frame([0, -1.57, 0], [1.0, -0.6, 1.0])
    orange = lambda f: ((f[..., 0].astype(int) - f[..., 2].astype(int)) > 60).sum()  # noqa: E731
    assert orange(alone) < 50 and orange(apart) > 500
    assert not np.array_equal(alone, same)  # overlaid, translucent



def test_render_without_mode_returns_none():
    env = gym.make("UR5Track-v0")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.unwrapped.render() is None



def test_renderer_rejects_a_large_image(model):
    with pytest.raises(InvalidInputError, match=r'offwidth="2000"'):
        ArmRenderer(model, width=2000, height=100)



def test_render_command_writes_playable_files(tmp_path, capsys):
    assert main(["render", "--planners", "cubic,optimal", "--format", "mp4,gif", "--width", "160", "--height",
                 "120", "--every", "10", "--out", str(tmp_path)]) == 0
    for name in ("paper_cubic", "paper_optimal", "paper_grid"):
        for fmt in ("mp4", "gif"):
            frames = iio.imread(tmp_path / f"{name}.{fmt}")
            width = 320 if name == "paper_grid" else 160
            assert frames.shape[0] == 11 and frames.shape[1:3] == ((240 if name == "paper_grid" else 120), width)
    strip = iio.imread(tmp_path / "paper_snapshots.png")
    assert strip.shape[:2] == (2 * 120, 5 * 160)
    assert "wrote" in capsys.readouterr().out



def test_render_command_bad_input(capsys):
    assert main(["render", "--camera", "wrist"]) == 2
    assert capsys.readouterr().err == "mjtraj: error: camera: unknown camera 'wrist'; valid: front, side, top\n"
    assert main(["render", "--format", "avi"]) == 2
    assert capsys.readouterr().err == "mjtraj: error: format: unknown format 'avi'; valid: mp4, gif\n"



def test_doctor_reports_a_working_backend(capsys):
    assert main(["doctor"]) == 0
    out = capsys.readouterr().out
    assert "mujoco" in out and "gymnasium" in out and "osqp" in out and "numpy" in out
    assert "works" in out



def test_the_backend_is_chosen_at_the_first_renderer_and_never_overrides_the_user():
    code = ("import os, numpy as np; from mjtraj.core import load_model; from mjtraj.media import ArmRenderer, "
            "active_backend; m = load_model(); r = ArmRenderer(m, width=64, height=48); "
            "print(active_backend(), os.environ.get('MUJOCO_GL'), int(r.frame(np.zeros(3)).max() > 0)); r.close()")
    import os

    clean = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    chosen = subprocess.run([sys.executable, "-c", code], env=clean, capture_output=True, text=True, check=True)
    assert chosen.stdout.split() == ["osmesa", "None", "1"]  # chosen for the renderer; the environment untouched
    user = subprocess.run([sys.executable, "-c", code], env={**clean, "MUJOCO_GL": "egl"}, capture_output=True,
                          text=True)
    assert "egl" in (user.stdout + user.stderr)  # the user's choice is used (it may fail here), never replaced


def test_depth_frames_see_the_arm_at_its_distance():
    """depth_array: the arm is nearer to the camera than the background, and the image has the requested size."""
    import gymnasium as gym

    env = gym.make("UR5Track-v0", render_mode="depth_array", width=96, height=72)
    env.reset(seed=0)
    depth = env.render()
    assert depth.shape == (72, 96) and depth.dtype == np.float32 and np.all(np.isfinite(depth))
    assert depth.min() > 0 and depth.min() < np.median(depth)  # something (the arm) stands in front
    rgb = gym.make("UR5Track-v0", render_mode="rgb_array", width=96, height=72)
    rgb.reset(seed=0)
    assert rgb.render().shape == (72, 96, 3)
    env.close()
    rgb.close()
