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


@pytest.mark.slow
def test_env_frame_shows_the_arm(model):
    env = gym.make("UR5Track-v0", render_mode="rgb_array", width=320, height=240)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
    with ArmRenderer(model, width=320, height=240) as renderer:
        elsewhere = renderer.frame([np.pi, -1.57, 0], [np.pi, -1.57, 0])  # the arm turned away
    # the arm with its ghost covers about a thousand pixels, in the same scene: neither blank nor floor-only
    changed = (np.abs(frame.astype(int) - elsewhere).max(axis=2) > 30).sum()
    assert 500 < changed < 0.1 * 320 * 240



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



@pytest.mark.slow
def test_render_command_writes_playable_files(tmp_path, capsys):
    assert main(["render", "--planners", "cubic,optimal", "--format", "mp4,gif", "--width", "160", "--height",
                 "120", "--every", "10", "--out", str(tmp_path)]) == 0
    for name in ("paper_cubic", "paper_optimal", "paper_grid"):
        for fmt in ("mp4", "gif"):
            frames = iio.imread(tmp_path / f"{name}.{fmt}")
            width = 320 if name == "paper_grid" else 160  # two planners: side by side
            assert frames.shape[0] == 11 and frames.shape[1:3] == (120, width)
    strip = iio.imread(tmp_path / "paper_snapshots.png")[..., :3]
    from mjtraj.media.videos import STRIP_PANEL, label_size

    caption = 2 * label_size(STRIP_PANEL[1]) + 8
    assert strip.shape[:2] == (STRIP_PANEL[1] + caption, 2 * STRIP_PANEL[0])  # one panel per planner, one caption
    panel = strip[:STRIP_PANEL[1], :STRIP_PANEL[0]].reshape(-1, 3).astype(int)
    white = np.all(panel == 255, axis=1).mean()
    assert 0.4 < white < 0.95  # a light background, the arm filling a good part of it
    orange = (panel[:, 0] > 200) & (panel[:, 1] > 90) & (panel[:, 1] < 170) & (panel[:, 2] < 80)
    assert orange.sum() > 50  # the reference's dashed path and marks are drawn
    assert "wrote" in capsys.readouterr().out



@pytest.mark.slow
def test_one_planner_gets_no_grid_and_four_get_two_by_two(tmp_path):
    assert main(["render", "--planners", "cubic", "--format", "gif", "--width", "64", "--height", "48", "--every",
                 "50", "--out", str(tmp_path / "one")]) == 0
    assert sorted(p.name for p in (tmp_path / "one").iterdir()) == ["paper_cubic.gif", "paper_snapshots.png"]
    assert main(["render", "--planners", "cubic,quintic,trapezoidal", "--format", "gif", "--width", "64", "--height",
                 "48", "--every", "50", "--out", str(tmp_path / "three")]) == 0
    grid = iio.imread(tmp_path / "three" / "paper_grid.gif")
    assert grid.shape[1:3] == (96, 128)
    assert grid[:, 48:, 64:, :3].max() == 0  # the missing fourth tile is black


def mujoco_frame(model, q, off=()):
    """MuJoCo's own 160x120 frame of `model` at q from its front camera, with the render flags `off` cleared."""
    import mujoco

    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    with mujoco.Renderer(model, 120, 160) as plain:
        plain.update_scene(data, "front")
        for flag in off:
            plain.scene.flags[flag] = False
        return plain.render()


@pytest.mark.slow
def test_fast_frames_are_the_scene_without_shadows_reflection_skybox_or_fine_facets(model):
    """The fast scene equals MuJoCo's own renderer with those features off, and the caller's model is untouched."""
    import mujoco

    from mjtraj.core import load_model
    from mjtraj.media.render import FAST_SLICES, FAST_STACKS

    q = np.array([0.3, -1.0, 0.8])
    with ArmRenderer(model, width=160, height=120, quality="fast") as fast:
        got = fast.frame(q)
    with ArmRenderer(model, width=160, height=120, quality="high") as high:
        rich = high.frame(q)
    assert model.vis.quality.numslices == 28 and model.vis.quality.numstacks == 16
    coarse = load_model()
    coarse.vis.quality.numslices, coarse.vis.quality.numstacks = FAST_SLICES, FAST_STACKS
    off = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION, mujoco.mjtRndFlag.mjRND_SKYBOX)
    np.testing.assert_array_equal(got, mujoco_frame(coarse, q, off))
    assert np.abs(rich.astype(int) - got).max() > 50  # high keeps the shadows and the reflection
    assert model.light_castshadow.all()  # high casts one shadow on its own copy


@pytest.mark.slow
def test_high_frames_cast_the_brightest_light_s_shadow_alone(model):
    """High frames equal MuJoCo's renderer on a copy where only the brightest light casts a shadow, at the high
    shadow map's size and clip; a second shadow-casting light changes the image (the setting is not a no-op)."""
    import copy

    from mjtraj.media.render import HIGH_SHADOW_CLIP, HIGH_SHADOW_SIZE

    q = np.array([0.3, -1.0, 0.8])
    with ArmRenderer(model, width=160, height=120, quality="high") as high:
        got = high.frame(q)
    images = []
    for cast in ([True, False], [True, True]):
        plant = copy.copy(model)
        plant.vis.quality.shadowsize, plant.vis.map.shadowclip = HIGH_SHADOW_SIZE, HIGH_SHADOW_CLIP
        assert plant.light_diffuse[0].sum() > plant.light_diffuse[1].sum()  # "key" is the brighter
        plant.light_castshadow[:] = cast
        images.append(mujoco_frame(plant, q))
    np.testing.assert_array_equal(got, images[0])
    assert np.abs(images[1].astype(int) - images[0]).max() > 20


@pytest.mark.slow
def test_gif_is_small_and_true_to_the_frames(tmp_path):
    """A 51-frame 320x240 clip stays under 0.5 MB (0.13 MB with Pillow 11.3; 0.41 MB with Pillow 10.1, the declared
    floor, since the camera frames the workspace), and its shared palette keeps every frame close to the render."""
    from mjtraj.media.render import ArmRenderer as Renderer
    from mjtraj.media.videos import _write, frames
    from mjtraj.study import load_scenario
    from mjtraj.study.comparison import compare

    scenario = load_scenario()
    result = compare(scenario, ("optimal",))
    with Renderer(scenario.model, width=320, height=240) as renderer:
        images = frames(result, "optimal", renderer, every=2)
    assert len(images) == 51
    _write(tmp_path / "clip.gif", images, 25.0)
    assert (tmp_path / "clip.gif").stat().st_size < 0.5e6
    decoded = iio.imread(tmp_path / "clip.gif")[..., :3]
    errors = np.abs(decoded.astype(int) - np.stack(images)).mean(axis=(1, 2, 3))
    assert decoded.shape == (51, 240, 320, 3) and errors.max() < 3.0


def test_labels_scale_with_the_image():
    from mjtraj.media.videos import label

    for height in (120, 240, 480):
        image = np.full((height, 4 * height // 3, 3), 255, dtype=np.uint8)
        band = (label(image, ["cubic", "t = 0.40 s  max|e| = 2.82 mrad"]).max(axis=(1, 2)) < 30).sum()
        assert band / height < 0.25


def test_render_command_bad_input(capsys):
    assert main(["render", "--camera", "wrist"]) == 2
    assert capsys.readouterr().err == ("mjtraj: error: camera: unknown camera 'wrist'; valid: front, side, top, free "
                                          "(the model's cameras, and 'free', a free camera framed on the model)\n")
    assert main(["render", "--quality", "best"]) == 2
    assert capsys.readouterr().err == "mjtraj: error: quality: unknown value 'best'; valid: fast, high\n"
    assert main(["render", "--format", "avi"]) == 2
    assert capsys.readouterr().err == "mjtraj: error: format: unknown format 'avi'; valid: mp4, gif\n"



@pytest.mark.slow
def test_doctor_reports_a_working_backend(capsys):
    assert main(["doctor"]) == 0
    out = capsys.readouterr().out
    assert "mujoco" in out and "gymnasium" in out and "osqp" in out and "numpy" in out
    assert "works" in out



@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_a_script_that_renders_and_never_closes_exits_quietly():
    script = ("from mjtraj.envs import UR5TrackEnv\n"
              "env = UR5TrackEnv(render_mode='rgb_array', width=32, height=24)\n"
              "env.reset(seed=0)\n"
              "print(env.render().shape)\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout == "(24, 32, 3)\n"
    assert done.stderr == ""


@pytest.mark.slow
def test_gymnasiums_record_video_records_an_episode(tmp_path):
    """RecordVideo works after the documented install (the video extra: moviepy)."""
    import mjtraj.envs  # noqa: F401
    from gymnasium.wrappers import RecordVideo

    env = RecordVideo(gym.make("UR5Track-v1", render_mode="rgb_array", width=96, height=72),
                      video_folder=str(tmp_path), episode_trigger=lambda episode: True, disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(3))
        done = terminated or truncated
    env.close()
    (video,) = tmp_path.glob("*.mp4")
    frames = iio.imread(video)
    assert frames.shape[0] >= 100 and frames.shape[1:3] == (72, 96)


def test_an_arm_without_geoms_is_framed_by_its_bodies():
    """A URDF of inertias only has no geoms; its frame is its bodies' origins, where forward kinematics puts them."""
    import mujoco

    xml = ('<mujoco><worldbody><body name="a" pos="0 0 0.1"><joint name="j0" axis="0 0 1"/>'
           '<inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/><body name="b" pos="0.4 0 0">'
           '<joint name="j1" axis="0 1 0"/><inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>'
           '</body></body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    with ArmRenderer(model, width=64, height=48) as renderer:
        points = renderer.body_positions([np.pi / 2, 0.0])
        assert np.allclose(points, [[0, 0, 0.1], [0, 0.4, 0.1]], atol=1e-12)
        image = renderer.strobe([[0.0, 0.0], [np.pi / 2, 0.0]], points, points, points)
    assert image.shape == (48, 64, 3)


@pytest.mark.slow
def test_the_strobe_paths_are_drawn_whatever_the_scene_memory_held(model):
    """The flange paths and marks are decor geoms appended after the model's. mjv_initGeom leaves their object type,
    object id, category and transparency as the scene's memory had them, and a fresh scene's memory is whatever the
    allocator hands out: left like that, a slot that held (-1, -1) there was painted as background (a CI run lost
    every orange pixel so). With every unused slot set to such values first, the strobe equals a clean scene's."""
    poses = [[0.0, -1.2, 1.0], [0.6, -1.0, 0.6]]
    ref = np.array([[0.3, 0.1, 0.6], [0.35, 0.2, 0.55], [0.4, 0.3, 0.5], [0.42, 0.35, 0.45]])
    executed = ref + 0.01

    def strobe(renderer, poison):
        scene = renderer._renderer.scene
        for i in range(scene.maxgeom) if poison else ():
            geom = scene.geoms[i]
            geom.objtype, geom.objid, geom.category, geom.segid, geom.transparent = -1, -1, 0, -1, 1
        return renderer.strobe(poses, executed, ref, ref[[0, -1]], frame=np.vstack([ref, executed]))

    with ArmRenderer(model, width=160, height=120) as renderer:
        clean = strobe(renderer, poison=False)
    with ArmRenderer(model, width=160, height=120) as renderer:
        poisoned = strobe(renderer, poison=True)
    orange = lambda f: ((f[..., 0] > 200) & (f[..., 1] > 90) & (f[..., 1] < 170) & (f[..., 2] < 80)).sum()  # noqa
    blue = lambda f: ((f[..., 2].astype(int) - f[..., 0] > 80) & (f[..., 2] > 120)).sum()  # noqa: E731
    assert orange(clean) > 20 and blue(clean) > 5, (orange(clean), blue(clean))
    np.testing.assert_array_equal(poisoned, clean)


def test_strobe_draws_earlier_poses_paler(model):
    """Where only pose a is drawn, a two-pose strobe that starts at a is lighter than one that ends at a (the
    caption's "earlier poses paler"), on a white background."""
    from mjtraj.media.render import ArmRenderer as Renderer

    a, b = np.array([0.0, -1.57, 0.0]), np.array([0.5, -0.5, 1.0])
    with Renderer(model, width=240, height=200) as renderer:
        path = np.array([renderer.flange_position(a), renderer.flange_position(b)])
        frame = np.vstack([renderer.body_positions(a), renderer.body_positions(b), path])

        def strobe(*poses: np.ndarray) -> np.ndarray:
            return renderer.strobe(list(poses), path[:1], path[:1], path[:0], frame=frame).astype(int).sum(axis=2)

        alone_a, alone_b, first_a, last_a = strobe(a), strobe(b), strobe(a, b), strobe(b, a)
    only_a = (alone_a < 3 * 255) & (alone_b == 3 * 255)
    assert only_a.sum() > 500
    assert np.median(first_a[only_a]) > np.median(last_a[only_a]) + 60
    assert np.mean(last_a[only_a] == alone_a[only_a]) > 0.9  # the last pose is drawn as it is (bar edges)


def test_the_free_camera_frames_the_motion_and_every_pose_of_it_stays_in_view(tmp_path):
    """An arm without cameras in a scene wider than its reach: framed on its motion (as the videos are), the arm's
    pixels (its geoms', not the floor's or a shelf's) never touch the image's border at any pose of the motion and
    span at least a third of it at some pose; framed on the model at rest they filled less."""
    from arm_suite import THREE, chain

    from mjtraj.media.videos import motion_poses
    from mjtraj.study import compare, scenario_for_model

    path = tmp_path / "swing.xml"  # a scene's wide floor makes the model's extent, and the rest framing, large
    path.write_text(chain("swing", THREE, extra_world='<geom name="floor" type="plane" size="6 6 0.1"/>'
                                                      '<body name="shelf" pos="3 3 0"><geom type="box" '
                                                      'size="0.2 0.2 0.5"/></body>'))
    scenario = scenario_for_model(path, q0=[0.0, -1.5, 0.0], qg=[1.0, 1.5, 1.0])
    result = compare(scenario, planners=("cubic",))
    shelf = scenario.model.body("shelf").id
    poses = motion_poses(result)

    def spans(renderer: ArmRenderer) -> tuple[bool, float]:
        touched, widest = False, 0.0
        for q in poses:
            seen = renderer.geoms(q)
            arm = (seen >= 0) & (scenario.model.geom_bodyid[np.maximum(seen, 0)] > 0)
            arm &= scenario.model.geom_bodyid[np.maximum(seen, 0)] != shelf
            touched |= bool(arm[0].any() or arm[-1].any() or arm[:, 0].any() or arm[:, -1].any())
            rows, cols = np.flatnonzero(arm.any(axis=1)), np.flatnonzero(arm.any(axis=0))
            widest = max(widest, (np.ptp(rows) + 1) / arm.shape[0], (np.ptp(cols) + 1) / arm.shape[1])
        return touched, widest

    with ArmRenderer(scenario.model, width=96, height=72, camera="free") as renderer:
        at_rest = spans(renderer)
        renderer.frame_motion(poses)
        framed = spans(renderer)
    assert not framed[0] and framed[1] >= 1 / 3
    assert framed[1] > 2 * at_rest[1]  # at rest, framed with the scene: 0.15 here, against 0.75
