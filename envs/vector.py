"""UR5Track-v0 natively vectorised: num_envs episodes on one mujoco.batch.Batch through the same ClosedLoop."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from mjtraj.envs.core import STEP_INFO, TrackCore
from mjtraj.envs.settings import RENDER_MODES, ArgumentsSignature, resolve
from mjtraj.envs.ur5_track import action_space, observation_space
from numpy.typing import NDArray

from mjtraj.checks import positive_int
from mjtraj.core import ClosedLoop
from mjtraj.exceptions import InvalidInputError
from mjtraj.media import ArmRenderer

AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)


class UR5TrackVectorEnv(VectorEnv):
    """`num_envs` copies of UR5TrackEnv (same arguments, documented there) stepped as one batch.

    Autoreset follows Gymnasium 1.x's default, `AutoresetMode.NEXT_STEP`: the step that ends a sub-env's
    episode returns its final observation with terminated (or truncated) set; the next `step` call resets that
    sub-env instead of stepping it (its action is ignored) and returns the new episode's first observation with
    reward 0 and terminated = truncated = False. With `autoreset_mode=AutoresetMode.SAME_STEP` (what
    Stable-Baselines3 expects) the ending step already returns the new episode's first observation, and the final
    one is in `info["final_obs"]` (an object array with the mask `info["_final_obs"]`). In both modes
    `info["metrics"]` (name -> (num_envs,) array, with the mask `info["_metrics"]`) carries the Metrics of the
    episodes that ended in that step, `info["diverged"]` whether they diverged and `info["missed_goal"]` whether
    they missed their goal (the goal rule; masks `_diverged`, `_missed_goal`). With plant randomisation,
    `info["plant"]` (name -> (num_envs,) array, mask `info["_plant"]`) describes the plants of the episodes that
    start in that call (reset, or a step that autoresets).

    Seeding: `reset(seed=s)` seeds sub-env i with s + i (a list gives one seed each), so sub-env i reproduces
    `UR5TrackEnv` reset with seed s + i bit for bit, later episodes included. `max_episode_steps` (set by
    `gym.make_vec` from the registration) truncates like gym.make's TimeLimit.
    """

    metadata = {"render_modes": [m for m in RENDER_MODES if m != "human"], "render_fps": 50,
                "autoreset_mode": AutoresetMode.NEXT_STEP}
    __signature__ = ArgumentsSignature()
    """What `help()` and `inspect.signature` show: every argument with its default (the Arguments table)."""

    def __init__(self, num_envs: int = 1, *, max_episode_steps: int | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, **kwargs: Any) -> None:
        """`kwargs` are UR5TrackEnv's arguments, keyword-only with their defaults
        (`inspect.signature(UR5TrackVectorEnv)` lists them); an unknown one is an InvalidInputError naming the valid
        ones."""
        self.settings = resolve(**kwargs)
        render_mode = self.settings.render_mode
        if render_mode == "human":
            raise InvalidInputError("render_mode: 'human' shows one env in a window; the vector env renders "
                                    "'rgb_array' or 'depth_array' (one frame per sub-env)")
        self.num_envs = positive_int("num_envs", num_envs)
        self.max_episode_steps = None if max_episode_steps is None else positive_int("max_episode_steps",
                                                                                      max_episode_steps)
        modes = {m.value: m for m in AUTORESET_MODES}
        mode = autoreset_mode.value if isinstance(autoreset_mode, AutoresetMode) else autoreset_mode
        if mode not in modes:
            raise InvalidInputError(f"autoreset_mode: expected one of {', '.join(modes)}, got {autoreset_mode!r}")
        self.autoreset_mode = modes[mode]
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.settings.dt),
                         "autoreset_mode": self.autoreset_mode}
        self.single_observation_space = observation_space(self.settings)
        self.single_action_space = action_space(self.settings)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._core = TrackCore(self.settings, self.num_envs)
        self._rngs: list[np.random.Generator] = []
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._renderers: list[ArmRenderer] = []

    @property
    def loop(self) -> ClosedLoop:
        """The ClosedLoop this env runs (read its public queries; do not step it)."""
        return self._core.loop

    @property
    def holding(self) -> NDArray[np.bool_]:
        """(num_envs,): True where a sub-env's motion has ended and it holds the goal (protocol v2's settle window;
        False everywhere without one)."""
        return self._core.holding()

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float64], dict[str, Any]]:
        if isinstance(seed, (list, tuple)):
            if len(seed) != self.num_envs:
                raise InvalidInputError(f"seed: expected {self.num_envs} seeds (one per sub-env), got {len(seed)}")
            seeds: list[int | None] = list(seed)
        else:
            seeds = [None if seed is None else seed + i for i in range(self.num_envs)]
        if seed is not None or not self._rngs:
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        if options:
            unknown = sorted(set(options) - {"scenario"})
            if unknown:
                raise InvalidInputError(f"options: unknown key {unknown[0]!r}; the vector env takes 'scenario' (a "
                                        f"list of {self.num_envs} scenarios, one per sub-env)")
            specs = options["scenario"]
            if not isinstance(specs, (list, tuple)) or len(specs) != self.num_envs:
                raise InvalidInputError(f"options: 'scenario' expects a list of {self.num_envs} scenarios (one per "
                                        f"sub-env), got {specs!r}")
            obs = self._core.begin([self._core.replay(self.settings.scenario(spec)) for spec in specs])
        else:
            obs = self._core.reset(self._rngs)
        self._autoreset[:] = False
        self._elapsed[:] = 0
        info: dict[str, Any] = {}
        self._start_info(np.arange(self.num_envs), info)
        return obs, info

    def step(self, actions: npt.ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_],
                                                    NDArray[np.bool_], dict[str, Any]]:
        if not self._core.loop.started:
            raise InvalidInputError("step: call reset() first")
        restart = np.flatnonzero(self._autoreset)
        obs, reward, terminated, info = self._core.step(actions)
        self._elapsed += 1
        truncated = (np.zeros(self.num_envs, dtype=bool) if self.max_episode_steps is None
                     else (self._elapsed >= self.max_episode_steps) & ~terminated)
        truncated[restart] = False
        done = terminated | truncated
        done[restart] = False
        out: dict[str, Any] = {}
        live = np.ones(self.num_envs, dtype=bool)
        live[restart] = False
        for key in STEP_INFO:
            out[key], out[f"_{key}"] = info[key], live
        if done.any():
            ended = np.flatnonzero(done)
            values = self._core.metrics(ended)
            if self._core.settings.floor:
                values.update(self._core.floors(ended, values["cost"]))
            out["metrics"] = {name: np.full(self.num_envs, np.nan) for name in values}
            for name, value in values.items():
                out["metrics"][name][ended] = value
            out["_metrics"] = done.copy()
            diverged = self._core.loop.diverged
            out["diverged"], out["_diverged"] = diverged & done, done.copy()
            missed = np.zeros(self.num_envs, dtype=bool)
            missed[ended] = self._core.goal_missed(ended, values["terminal_err"])
            out["missed_goal"], out["_missed_goal"] = missed, done.copy()
            if self._core.settings.settle:
                settled = np.zeros(self.num_envs, dtype=bool)
                settled[ended] = [not why for why in self._core.settled(ended, values)]
                # a truncated episode did not reach its window's end: no verdict
                out["settled"], out["_settled"] = settled, terminated.copy()
        if restart.size:
            self._restart(restart, obs, out)
            reward[restart] = 0.0
            terminated[restart] = False
        if self.autoreset_mode is AutoresetMode.SAME_STEP:
            if done.any():
                ended = np.flatnonzero(done)
                final = np.full(self.num_envs, None, dtype=object)
                for i in ended:
                    final[i] = obs[i].copy()
                out["final_obs"], out["_final_obs"] = final, done.copy()
                self._restart(ended, obs, out)
            return obs, reward, terminated, truncated, out
        self._autoreset = done
        return obs, reward, terminated, truncated, out

    def _restart(self, ids: NDArray[np.intp], obs: NDArray[np.float64], info: dict[str, Any]) -> None:
        """Start the next episodes of sub-envs `ids` (their own rngs), writing their first observations into obs
        and their plants into info."""
        obs[ids] = self._core.reset([self._rngs[i] for i in ids], ids)
        self._elapsed[ids] = 0
        self._start_info(ids, info)

    def _start_info(self, ids: NDArray[np.intp], info: dict[str, Any]) -> None:
        """info["task"] (q0, qg: (num_envs, n); duration: (num_envs,); NaN elsewhere) and, on perturbed plants,
        info["plant"] (name -> (num_envs,)), each with its mask ("_task", "_plant"), for the episodes of sub-envs
        `ids` that start now."""
        mask = np.isin(np.arange(self.num_envs), ids)
        for key, values in self._core.start_info(ids).items():
            info[key] = {name: np.full((self.num_envs, *value.shape[1:]), np.nan) for name, value in values.items()}
            for name, value in values.items():
                info[key][name][ids] = value
            info[f"_{key}"] = mask.copy()

    def render(self) -> tuple[NDArray[Any], ...] | None:
        """One frame per sub-env: rgb_array (executed arm and translucent reference), (height, width, 3) uint8;
        depth_array, (height, width) float32, m."""
        if self.render_mode is None:
            return None
        s = self.settings
        if not self._renderers:
            self._renderers = [ArmRenderer(s.model, width=s.width, height=s.height, camera=s.camera,
                                           quality=s.render_quality)]
        positions = self._core.loop.positions
        if self.render_mode == "depth_array":
            return tuple(self._renderers[0].depth(positions[i]) for i in range(self.num_envs))
        return tuple(self._renderers[0].frame(positions[i], self._core.reference_pose(i))
                     for i in range(self.num_envs))

    def __getstate__(self) -> dict[str, Any]:
        """Everything but the renderers (OpenGL contexts): a copy makes its own at its first render()."""
        state = self.__dict__.copy()
        state["_renderers"] = []
        return state

    def close_extras(self, **kwargs: Any) -> None:
        for renderer in getattr(self, "_renderers", ()):  # absent if __init__ refused its arguments
            renderer.close()
        self._renderers = []
