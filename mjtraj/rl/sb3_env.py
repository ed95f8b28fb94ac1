"""UR5TrackVectorEnv behind Stable-Baselines3's VecEnv API (SB3 does not take Gymnasium vector envs).

The vector env runs with SAME_STEP autoreset, the semantics SB3 expects: an ending step returns the next
episode's first observation and puts the final one in `info["terminal_observation"]`. `seed(s)` seeds sub-env i
with the TRAIN_STREAM seed of (s, i) (`mjtraj.rl.streams`), never with s + i.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from mjtraj.envs import UR5TrackVectorEnv
from mjtraj.rl.extra import require_sb3
from mjtraj.rl.streams import training_entropies

require_sb3()
from stable_baselines3.common.vec_env import VecEnv  # noqa: E402


class SB3TrackVecEnv(VecEnv):
    """`num_envs` UR5Track-v0 episodes on one batch, as an SB3 VecEnv; keyword arguments are the env's.

    With `observe`, the agent sees `observe(obs)` (the final observations in the infos too) in the space
    `observation_space`, instead of the env's observations: fixed scaling (`mjtraj.rl.scaling`)."""

    def __init__(self, num_envs: int, *, observe: Callable[[NDArray[np.float64]], NDArray[np.float32]] | None = None,
                 observation_space: spaces.Box | None = None, **env_kwargs: Any) -> None:
        self.env = UR5TrackVectorEnv(num_envs=num_envs, autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
        self._actions: NDArray[np.float32] | None = None
        self._observe = observe
        super().__init__(num_envs, observation_space or self.env.single_observation_space,
                         self.env.single_action_space)

    def _seen(self, obs: NDArray[np.float64]) -> NDArray[Any]:
        return obs if self._observe is None else self._observe(obs)

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        if seed is None:
            seed = int(np.random.default_rng().integers(2**32))
        self._seeds = list(training_entropies(seed, self.num_envs))
        return self._seeds

    def reset(self) -> NDArray[Any]:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        obs, _ = self.env.reset(seed=seeds)
        self._reset_seeds()
        self._reset_options()
        return self._seen(obs)

    def step_async(self, actions: NDArray[np.float32]) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[NDArray[Any], NDArray[np.float32], NDArray[np.bool_], list[dict[str, Any]]]:
        assert self._actions is not None, "step_async first"
        obs, reward, terminated, truncated, info = self.env.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(dones):
            infos[i] = {"terminal_observation": self._seen(info["final_obs"][i]),
                        "TimeLimit.truncated": bool(truncated[i] and not terminated[i]),
                        "metrics": {name: float(v[i]) for name, v in info["metrics"].items()},
                        "diverged": bool(info["diverged"][i])}
        return self._seen(obs), reward.astype(np.float32), dones, infos

    def close(self) -> None:
        self.env.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self.env, attr_name)] * len(list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        raise AttributeError(f"{attr_name}: the sub-envs of a batched env share their attributes; not settable")

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any) -> list[Any]:
        raise AttributeError(f"{method_name}: the sub-envs of a batched env have no methods of their own")

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))


def benchmark_vec_env(num_envs: int, env_id: str = "UR5Track-v2", **overrides: Any) -> SB3TrackVecEnv:
    """`num_envs` episodes of the registered benchmark env `env_id` (default UR5Track-v2, protocol v2: a residual
    on cubic + feedforward + PID, nominal tasks, the settle window) as an SB3 VecEnv: the env's registered arguments,
    then `overrides`. What to train a plain stable-baselines3 agent on; `mjtraj rl eval --policy ZIP --policy-env
    ...` scores the zip it saves.

    Raises:
      InvalidInputError: `env_id` is not a registered mjtraj env (the valid ones are named), or a bad argument.
    """
    import gymnasium as gym

    from mjtraj.envs import BENCHMARK_VARIANTS
    from mjtraj.exceptions import InvalidInputError

    if env_id not in BENCHMARK_VARIANTS:
        raise InvalidInputError(f"env_id: expected one of {', '.join(BENCHMARK_VARIANTS)}, got {env_id!r}")
    return SB3TrackVecEnv(num_envs, **{**gym.spec(env_id).kwargs, **overrides})
