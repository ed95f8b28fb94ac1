"""Gymnasium environments of mjtraj (installed as `mjtraj.envs`): UR5Track-v0, single and natively vectorised.

Importing this package registers the envs (it imports Gymnasium, nothing of MuJoCo); the names below load on
first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import gymnasium as gym

from mjtraj._lazy import lazy_exports

ENV_ID = "UR5Track-v0"
ARM_ENV_ID = "ArmTrack-v0"
"""The same env for any MJCF arm: gym.make("ArmTrack-v0", xml_file=PATH); without xml_file, the UR5."""


BENCHMARK_ID = "UR5Track-v1"
BENCHMARK_DEFAULTS = {"action_mode": "residual", "task": "random", "family": "nominal"}
"""UR5Track-v1's arguments beyond v0's defaults: it acts (a residual of residual_scale, default 6 N m, on cubic +
feedforward + PID) and each seed draws a new task by the nominal family's rules."""
BENCHMARK_V2_ID = "UR5Track-v2"
BENCHMARK_V2_DEFAULTS: dict[str, Any] = {**BENCHMARK_DEFAULTS, "settle": 0.5, "observe_measured": True,
                                         "observe_task": True}
"""UR5Track-v2's arguments beyond v1's (protocol v2, docs/benchmark.md): each episode goes on for a 0.5 s settle window
after its motion (the reference holding the goal, every period scored, info['settled'] at the end); the observation
carries the state the control law measures (noisy under measurement_noise) and ends with the move and the time to the
motion's end (v1's layout as its prefix)."""
BENCHMARK_VARIANTS: dict[str, dict[str, Any]] = {BENCHMARK_ID: BENCHMARK_DEFAULTS,
                      "UR5TrackAggressive-v1": {**BENCHMARK_DEFAULTS, "family": "aggressive"},
                      "UR5TrackMismatch-v1": {**BENCHMARK_DEFAULTS, "family": "mismatch"},
                      BENCHMARK_V2_ID: BENCHMARK_V2_DEFAULTS,
                      "UR5TrackAggressive-v2": {**BENCHMARK_V2_DEFAULTS, "family": "aggressive"},
                      "UR5TrackMismatch-v2": {**BENCHMARK_V2_DEFAULTS, "family": "mismatch"},
                      "UR5TrackNoisy-v2": {**BENCHMARK_V2_DEFAULTS, "family": "mismatch", "measurement_noise": 1e-3}}
"""The benchmark's registered envs (docs/benchmark.md): v1 and v2 with their aggressive and mismatch variants, and
v2's noisy one (mismatched plants measured with 1 mrad of noise, protocol v2's noisy family)."""


def register_envs() -> None:
    """Register UR5Track-v0, ArmTrack-v0 and the v1 and v2 benchmark envs with Gymnasium (idempotent)."""
    for env_id, kwargs in ((ENV_ID, {}), (ARM_ENV_ID, {}), *BENCHMARK_VARIANTS.items()):
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="mjtraj.envs.ur5_track:UR5TrackEnv",
                         vector_entry_point="mjtraj.envs.vector:UR5TrackVectorEnv", kwargs=dict(kwargs))
    # no max_episode_steps: an episode ends by itself after N = duration/dt steps, whatever the duration


register_envs()

_EXPORTS = {
    "UR5TrackEnv": "mjtraj.envs.ur5_track",
    "action_space": "mjtraj.envs.ur5_track",
    "observation_space": "mjtraj.envs.ur5_track",
    "UR5TrackVectorEnv": "mjtraj.envs.vector",
    "TrackCore": "mjtraj.envs.core",
    "observe": "mjtraj.envs.core",
    "Observer": "mjtraj.envs.core",
    "OBSERVE_PLANT": "mjtraj.envs.settings",
    "PREVIEW_FRAMES": "mjtraj.envs.settings",
    "scale_action": "mjtraj.envs.core",
    "STEP_INFO": "mjtraj.envs.core",
    "ACTION_MODES": "mjtraj.envs.settings",
    "RESIDUAL_SCALE": "mjtraj.envs.settings",
    "PLANT_RANDOMIZATIONS": "mjtraj.envs.settings",
    "REWARD_BASELINES": "mjtraj.envs.settings",
    "TASKS": "mjtraj.envs.settings",
    "EnvOptions": "mjtraj.envs.settings",
    "TrackSettings": "mjtraj.envs.settings",
    "argument_defaults": "mjtraj.envs.settings",
    "resolve": "mjtraj.envs.settings",
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from mjtraj.envs.core import STEP_INFO, Observer, TrackCore, observe, scale_action
    from mjtraj.envs.settings import (
        ACTION_MODES,
        PLANT_RANDOMIZATIONS,
        PREVIEW_FRAMES,
        RESIDUAL_SCALE,
        REWARD_BASELINES,
        TASKS,
        EnvOptions,
        TrackSettings,
        argument_defaults,
        resolve,
    )
    from mjtraj.envs.ur5_track import UR5TrackEnv, action_space, observation_space
    from mjtraj.envs.vector import UR5TrackVectorEnv

__all__ = [
    "ACTION_MODES", "BENCHMARK_DEFAULTS", "BENCHMARK_ID", "BENCHMARK_V2_DEFAULTS", "BENCHMARK_V2_ID",
    "BENCHMARK_VARIANTS", "ENV_ID", "EnvOptions",
    "PLANT_RANDOMIZATIONS", "PREVIEW_FRAMES", "RESIDUAL_SCALE", "REWARD_BASELINES", "STEP_INFO",
    "TASKS", "TrackCore", "TrackSettings", "UR5TrackEnv", "UR5TrackVectorEnv", "action_space", "argument_defaults",
    "observation_space", "observe", "Observer", "OBSERVE_PLANT", "register_envs", "resolve", "scale_action",
]
