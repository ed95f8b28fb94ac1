"""Whole episodes of a policy on given references, through the env's own engine (TrackCore on a ClosedLoop).

Validation during training and `mjtraj rl eval` both run here, on the nominal plant or, for mismatch scenarios,
on per-simulation perturbed plants, exactly as sweeps run the planners.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.closed_loop import ClosedLoop
from mjtraj.envs.core import TrackCore
from mjtraj.envs.settings import TrackSettings
from mjtraj.metrics import metrics_arrays
from mjtraj.reference import Reference
from mjtraj.rl.policy import for_duration
from mjtraj.rollout import Rollout

Actor = Callable[[NDArray[np.float64]], NDArray[np.float32]]
"""Observations (B, d) -> actions (B, n) in [-1, 1]."""


@dataclass
class Episodes:
    """B finished episodes: what the loop recorded, every metric (name -> (B,)), and MuJoCo's instability flags."""

    rollout: Rollout
    metrics: dict[str, NDArray[np.float64]]
    unstable: NDArray[np.bool_]


def run_episodes(actor: Actor | None, settings: TrackSettings, references: Sequence[Reference],
                 weights: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]], *,
                 plant: mujoco.MjModel | None = None, plant_fields: dict[str, NDArray[np.float64]] | None = None
                 ) -> Episodes:
    """Run one episode per reference (all of one length) with `actor` choosing the actions (None: pid mode, no
    actions), scored with per-episode diagonal `weights` ((2n,), (n,)) as sweeps score them."""
    duration = references[0].steps * settings.dt
    settings = for_duration(settings, duration)
    if actor is None:
        settings = dataclasses.replace(settings, action_mode="pid")
    B = len(references)
    loop = ClosedLoop(settings.model, settings.loop, nsim=B, plant=plant, plant_fields=plant_fields, nthread=1)
    core = TrackCore(settings, B, loop=loop)
    obs = core.begin(references, weights)
    zeros = np.zeros((B, settings.n), dtype=np.float32)
    for _ in range(settings.steps):
        obs, *_ = core.step(zeros if actor is None else actor(obs))
    rollout = loop.rollout()
    q_diag = np.array([w[0] for w in weights])
    r_diag = np.array([w[1] for w in weights])
    return Episodes(rollout, metrics_arrays(rollout, q_diag, r_diag, per_scenario=True), loop.plant.unstable())

