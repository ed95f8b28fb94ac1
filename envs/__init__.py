"""Gymnasium environments of mjtraj (installed as `mjtraj.envs`): UR5Track-v0, single and natively vectorised.

Importing this package registers the envs (it imports Gymnasium, nothing of MuJoCo); the names below load on
first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import gymnasium as gym

from mjtraj._lazy import lazy_exports

ENV_ID = "UR5Track-v0"
ARM_ENV_ID = "ArmTrack-v0"
"""The same env for any MJCF arm: gym.make("ArmTrack-v0", xml_file=PATH); without xml_file, the UR5."""


def register_envs() -> None:
    """Register UR5Track-v0 and ArmTrack-v0 with Gymnasium (idempotent)."""
    for env_id in (ENV_ID, ARM_ENV_ID):
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="mjtraj.envs.ur5_track:UR5TrackEnv",
                         vector_entry_point="mjtraj.envs.vector:UR5TrackVectorEnv")
    # no max_episode_steps: an episode ends by itself after N = duration/dt steps, whatever the duration


register_envs()

_EXPORTS = {
    "UR5TrackEnv": "mjtraj.envs.ur5_track",
    "action_space": "mjtraj.envs.ur5_track",
    "observation_space": "mjtraj.envs.ur5_track",
    "UR5TrackVectorEnv": "mjtraj.envs.vector",
    "TrackCore": "mjtraj.envs.core",
    "observe": "mjtraj.envs.core",
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
    from mjtraj.envs.core import STEP_INFO, TrackCore, observe, scale_action
    from mjtraj.envs.settings import (
        ACTION_MODES,
        PLANT_RANDOMIZATIONS,
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
    "ACTION_MODES", "ENV_ID", "EnvOptions", "PLANT_RANDOMIZATIONS", "RESIDUAL_SCALE", "REWARD_BASELINES", "STEP_INFO",
    "TASKS", "TrackCore", "TrackSettings", "UR5TrackEnv", "UR5TrackVectorEnv", "action_space", "argument_defaults",
    "observation_space", "observe", "register_envs", "resolve", "scale_action",
]
