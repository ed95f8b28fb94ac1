"""The env's batched engine: B episodes on one ClosedLoop, with their observations, rewards and infos.

UR5TrackEnv is this with B = 1, UR5TrackVectorEnv with B = num_envs: one implementation for both.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.closed_loop import ClosedLoop
from mjtraj.envs.settings import TrackSettings
from mjtraj.exceptions import InvalidInputError
from mjtraj.metrics import METRIC_NAMES, metrics_arrays
from mjtraj.reference import Reference

STEP_INFO = ("tau_ff", "tau_fb", "dtau", "saturated", "e", "reward_tracking", "reward_effort")
"""Keys of every step's info (arrays of shape (B, n), or (B,) for the reward terms)."""


class TrackCore:
    """B tracking episodes advanced together: task sampling, planning, control, observation, reward."""

    def __init__(self, settings: TrackSettings, num: int, loop: ClosedLoop | None = None) -> None:
        """`loop`: a ClosedLoop of `num` simulations to drive instead of a new one on the nominal plant with
        settings.loop (evaluation on perturbed plants builds its own)."""
        self.settings = settings
        self.num = num
        self.model = settings.model
        if loop is not None and loop.nsim != num:
            raise InvalidInputError(f"loop: expected a ClosedLoop of {num} simulations, got {loop.nsim}")
        self.loop = loop if loop is not None else ClosedLoop(self.model, settings.loop, nsim=num)
        n = settings.n
        self.limit = np.tile(self.loop.limit, (num, 1))
        task = settings.fixed_task
        self.fixed = (settings.planner.plan(task, self.model), settings.weights(task)) if task is not None else None
        self.references: list[Reference | None] = [None] * num
        # weighted squares of [e, ed, dtau], summed row by row (a matrix product would round differently for
        # different B, and the vector env must equal single envs bit for bit)
        self._weights = np.zeros((num, 3 * n))
        self._split = 2 * n
        self._preview = np.arange(1, settings.preview + 1)
        N = settings.steps
        self._phase = np.repeat((np.arange(N + 1) / N)[:, None, None], num, axis=1)  # (N+1, B, 1)

    def plan(self, rng: np.random.Generator) -> tuple[Reference, tuple[NDArray[np.float64], NDArray[np.float64]]]:
        """The next episode's reference, planned for a task drawn from `rng` (fixed tasks: planned once), and the
        diagonal weights (Q_exec (2n,), R_exec (n,)) that score it."""
        if self.fixed is not None:
            return self.fixed
        task = self.settings.sample_task(rng)
        return self.settings.planner.plan(task, self.model), self.settings.weights(task)

    def reset(self, rngs: Sequence[np.random.Generator], ids: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """Start new episodes on simulations `ids` (all if None), one rng each; their observations (len, d)."""
        planned = [self.plan(rng) for rng in rngs]
        return self.begin([ref for ref, _ in planned], [w for _, w in planned], ids)

    def begin(self, references: Sequence[Reference],
              weights: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
              ids: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """Start episodes tracking `references` on simulations `ids` (all if None), scored with `weights`
        ((2n,), (n,) diagonals, one pair each); their observations (len, d)."""
        rows = np.arange(self.num) if ids is None else ids
        for row, reference, (q_diag, r_diag) in zip(rows, references, weights, strict=True):
            self.references[row] = reference
            self._weights[row] = np.concatenate([q_diag, r_diag])
        self.loop.start(references, ids)
        return self.observe()[rows]

    def action(self, action: npt.ArrayLike) -> NDArray[np.float64] | None:
        """Validate a (B, n) action in [-1, 1] (clipped outside) and scale it to torque, N m; None in pid mode."""
        if self.settings.action_mode == "pid":
            return None
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.limit.shape:
            if a.size != self.limit.size:
                expected = self.limit.shape[1:] if self.num == 1 else self.limit.shape
                raise InvalidInputError(f"action: expected shape {expected}, got {np.shape(action)}")
            a = a.reshape(self.limit.shape)
        if not np.isfinite(a).all():
            raise InvalidInputError(f"action: expected finite values in [-1, 1], got {np.asarray(action).tolist()}")
        return np.minimum(np.maximum(a, -1.0), 1.0) * self.limit

    def step(self, action: npt.ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                   NDArray[np.bool_], dict[str, Any]]:
        """One control period for every simulation: (observation (B, d), reward (B,), terminated (B,), info)."""
        torque = self.action(action)
        mode = self.settings.action_mode
        step = self.loop.step(residual=torque if mode == "residual" else None,
                              override=torque if mode == "torque" else None)
        c = step.control
        x = np.concatenate([step.e, step.ed, c.dtau], axis=1)
        weighted = x * x * self._weights
        tracking = -weighted[:, :self._split].sum(axis=1)
        effort = -weighted[:, self._split:].sum(axis=1)
        s = self.loop.state
        assert s is not None
        if s.sync is not None:
            terminated = np.zeros(self.num, dtype=bool) if s.sync < s.steps else np.ones(self.num, dtype=bool)
        else:
            terminated = step.diverged | (s.k >= s.steps)
        info = {"tau_ff": c.tau_ff.copy(), "tau_fb": c.tau_fb, "dtau": c.dtau, "saturated": c.saturated,
                "e": step.e.copy(), "reward_tracking": tracking, "reward_effort": effort}
        return self.observe(), tracking + effort, terminated, info

    def observe(self) -> NDArray[np.float64]:
        """Observations of every simulation, shape (B, 6n + 1 + 2n preview); layout in UR5TrackEnv's docstring."""
        s = self.loop.state
        assert s is not None
        N = s.steps
        q, qd = self.loop.plant.qpos, self.loop.plant.qvel
        if s.sync is not None:
            k = min(s.sync, N)
            q_ref, qd_ref = s.q_ref[k], s.qd_ref[k]
            parts = [q, qd, q_ref, qd_ref, q_ref - q, qd_ref - qd, self._phase[k]]
            if self._preview.size:
                ahead = np.minimum(k + self._preview, N)
                future = np.concatenate([s.q_ref[ahead], s.qd_ref[ahead]], axis=-1)  # (p, B, 2n)
                parts.append(future.swapaxes(0, 1).reshape(self.num, -1))
            return np.concatenate(parts, axis=1)
        k = s.periods
        q_ref, qd_ref = s.q_ref[k, s.rows], s.qd_ref[k, s.rows]
        parts = [q, qd, q_ref, qd_ref, q_ref - q, qd_ref - qd, self._phase[k, s.rows]]
        if self._preview.size:
            ahead = np.minimum(k[None, :] + self._preview[:, None], N)
            future = np.concatenate([s.q_ref[ahead, s.rows], s.qd_ref[ahead, s.rows]], axis=-1)
            parts.append(future.swapaxes(0, 1).reshape(self.num, -1))
        return np.concatenate(parts, axis=1)

    def metrics(self, ids: NDArray[np.intp]) -> dict[str, NDArray[np.float64]]:
        """The episode Metrics of simulations `ids` (NaN for a diverged one): name -> shape (len(ids),)."""
        rollout = self.loop.rollout(ids)
        weights = self._weights[ids]
        arrays = metrics_arrays(rollout, weights[:, :self._split], weights[:, self._split:], per_scenario=True)
        return {name: np.where(rollout.diverged, np.nan, arrays[name]) for name in METRIC_NAMES}

    def reference_pose(self, row: int) -> NDArray[np.float64]:
        """The reference sample simulation `row` tracks next (the ghost arm), rad."""
        s = self.loop.state
        assert s is not None
        return s.q_ref[min(int(s.periods[row]), s.steps), row]
