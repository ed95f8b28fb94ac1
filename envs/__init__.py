"""Gymnasium environments of mjtraj (installed as `mjtraj.envs`): UR5Track-v0, single and natively vectorised."""

from __future__ import annotations

import gymnasium as gym

ENV_ID = "UR5Track-v0"
MAX_EPISODE_STEPS = 100
"""The paper's N = T/dt = 2 s / 0.02 s: the registered episode length."""


def register_envs() -> None:
    """Register UR5Track-v0 with Gymnasium (idempotent)."""
    if ENV_ID in gym.registry:
        return
    gym.register(id=ENV_ID, entry_point="mjtraj.envs.ur5_track:UR5TrackEnv",
                 vector_entry_point="mjtraj.envs.vector:UR5TrackVectorEnv", max_episode_steps=MAX_EPISODE_STEPS)


register_envs()
