"""render_mode="human": a window under a virtual display (Xvfb, which CI installs), and one-line errors where no
window can open."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from mjtraj.envs.vector import UR5TrackVectorEnv

from mjtraj.exceptions import InvalidInputError, RenderError
from mjtraj.media.window import check_display

SCRIPT = """
import gymnasium as gym, numpy as np, mjtraj
env = gym.make("UR5Track-v0", render_mode="human", width=320, height=240)
env.reset(seed=0)
for _ in range(20):
    env.step(np.zeros(3, np.float32))
env.close()
env = gym.make("UR5Track-v0", render_mode="human", width=320, height=240)
env.reset(seed=1)
env.step(np.zeros(3, np.float32))  # left open: closed at exit, silently
print("shown")
"""


@pytest.mark.slow
def test_a_window_shows_the_episode_and_closes_silently(display):
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env["DISPLAY"] = display
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "shown"
    assert "Traceback" not in done.stderr and "Exception ignored" not in done.stderr


def test_without_a_display_the_error_says_what_to_do(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    if sys.platform.startswith("linux"):
        with pytest.raises(RenderError, match=r"needs a display, and DISPLAY is not set: on a server use "
                                              r"render_mode='rgb_array'"):
            check_display()
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    monkeypatch.setenv("DISPLAY", ":0")
    with pytest.raises(RenderError, match=r"MUJOCO_GL=osmesa selects an off-screen backend; unset MUJOCO_GL"):
        check_display()


def test_the_vector_env_refuses_a_window():
    with pytest.raises(InvalidInputError, match=r"^render_mode: 'human' shows one env in a window"):
        UR5TrackVectorEnv(2, render_mode="human")


GHOST = """
import numpy as np, mujoco
from mjtraj.core import load_model
from mjtraj.media import HumanViewer
from mjtraj.media.render import GHOST_RGBA
model = load_model()
viewer = HumanViewer(model, width=160, height=120)
viewer.show([0.0, -1.57, 0.0])
alone = viewer._viewer.scn.ngeom
viewer.show([0.0, -1.57, 0.0], [1.0, -0.6, 1.0])
scene = viewer._viewer.scn
ghost = mujoco.MjData(model)
ghost.qpos[:] = [1.0, -0.6, 1.0]
mujoco.mj_kinematics(model, ghost)
moving = np.flatnonzero(model.geom_bodyid > 0)
added = [scene.geoms[i] for i in range(alone, scene.ngeom)]
assert len(added) == len(moving), (alone, scene.ngeom, len(moving))
for geom, g in zip(added, moving):
    assert np.allclose(geom.pos, ghost.geom_xpos[g]) and np.allclose(geom.mat.ravel(), ghost.geom_xmat[g])
    assert np.allclose(geom.rgba, GHOST_RGBA) and geom.type == model.geom_type[g]
viewer.close()
print("ghost")
"""


@pytest.mark.slow
def test_the_window_draws_the_ghost_where_the_reference_is(display):
    """The ghost's geoms enter the window's scene through mjv_initGeom, one per moving geom, at the reference pose's
    geom positions and orientations, in the ghost colour (Gymnasium before 1.2 wrote markers in MuJoCo < 3.2's
    layout and crashed a newer MuJoCo)."""
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env["DISPLAY"] = display
    done = subprocess.run([sys.executable, "-c", GHOST], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip() == "ghost"
