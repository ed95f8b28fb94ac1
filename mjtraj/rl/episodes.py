"""Whole episodes of a policy on given references, through the study's evaluation pipeline: the policy is an
Actor that observes the loop as the env does and adds its torque inside the one closed loop.

Validation during training runs here, and `mjtraj rl eval` runs the same actor through the sweep's units: on the
nominal plant or, for mismatch scenarios, on per-simulation perturbed plants, exactly as sweeps run the planners.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from mjtraj.core import ClosedLoop, Reference, Settle
from mjtraj.envs import Observer, TrackSettings, scale_action
from mjtraj.rl.adapters import ScoredPolicy
from mjtraj.study import Job, Outcome, Perturbation, execute, no_perturbation, perturbed_plant

Policy = Callable[[NDArray[np.float64]], NDArray[np.float32]]
"""Observations (B, d) -> actions (B, n) in [-1, 1]."""


class PolicyActor:
    """A policy acting in the env's `settings` (action mode, residual scale, preview): observations as the env
    builds them, actions scaled to torque as the env scales them. `policy` is a batched callable or a
    ScoredPolicy (mjtraj.rl.adapters), which is told when episodes start and, if privileged, their plants."""

    def __init__(self, policy: Policy | ScoredPolicy, settings: TrackSettings) -> None:
        self.policy = policy
        self.settings = settings
        self.action_mode = settings.action_mode
        self.shadows = settings.shadows()
        """What the loop runs in its shadow for the observation (`Actor.shadows`; `mpc_filter` where the policy
        observes the disturbance)."""
        self._limit = np.zeros((0, settings.n))
        self._plants: list[dict[str, float]] | None = None
        self._observer = Observer(settings, 0)

    def begin(self, loop: ClosedLoop, references: Sequence[Reference],
              plants: Sequence[Perturbation | None] = ()) -> None:
        self._limit = np.tile(self.settings.action_scale, (loop.nsim, 1))
        self._observer = Observer(self.settings, loop.nsim)
        self._observer.start(np.arange(loop.nsim), list(plants) or [None] * loop.nsim, references)
        if isinstance(self.policy, ScoredPolicy):
            if self.policy.privileged:  # the plants as the env reports them (the nominal one where none)
                nominal = no_perturbation(self.settings.n)
                given = list(plants) or [None] * loop.nsim
                self._plants = [(p if p is not None else nominal).as_dict() for p in given]
            self.policy.start(np.ones(loop.nsim, dtype=bool))

    def act(self, loop: ClosedLoop) -> NDArray[np.float64]:
        obs = self._observer(loop)
        if isinstance(self.policy, ScoredPolicy):
            return scale_action(self.policy.act(obs, self._plants), self._limit)
        return scale_action(self.policy(obs), self._limit)


def run_episodes(policy: Policy | ScoredPolicy | None, settings: TrackSettings, references: Sequence[Reference],
                 weights: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
                 plants: Sequence[Perturbation | None] | None = None,
                 settles: Sequence[Settle | None] | None = None) -> list[Outcome]:
    """One episode per reference with `policy` acting (None: the controller alone), on the nominal plant or on
    one perturbed plant each (`plants`), scored with per-episode diagonal `weights` ((2n,), (n,)) as sweeps score
    them; with `settles` (protocol v2), each reference ends with its settle window (`mjtraj.core.settle.held`) and
    its episode is scored over it and held to the at-rest rule (an episode whose entry is None has none); an
    Outcome each."""
    actor = None if policy is None or settings.action_mode == "pid" else PolicyActor(policy, settings)
    perturbations = [None] * len(references) if plants is None else list(plants)
    windows = [None] * len(references) if settles is None else list(settles)
    jobs = [Job(ref, w, p, settle=settle)
            for ref, w, p, settle in zip(references, weights, perturbations, windows, strict=True)]
    plant = perturbed_plant(settings.model) if plants is not None else None
    return execute(settings.model, settings.loop, jobs, actor=actor, plant=plant)
