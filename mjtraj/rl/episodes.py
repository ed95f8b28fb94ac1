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
from mjtraj.reference import Reference
from mjtraj.rl.policy import for_duration

Actor = Callable[[NDArray[np.float64]], NDArray[np.float32]]
"""Observations (B, d) -> actions (B, n) in [-1, 1]."""


@dataclass
class Episodes:
    """B finished episodes: every metric (name -> (B,), NaN where diverged), the period each diverged in (-1:
    never), and MuJoCo's instability flags; shapes (B,)."""

    metrics: dict[str, NDArray[np.float64]]
    diverged_step: NDArray[np.int64]
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
    assert loop.state is not None
    return Episodes(core.metrics(np.arange(B)), loop.state.diverged_step.copy(), loop.plant.unstable())

