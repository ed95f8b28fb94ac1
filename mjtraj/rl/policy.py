"""A saved policy: SB3's zip plus its mjtraj record (`<name>.json`: how it was trained, and the observation
normalisation it acts through), and its deterministic actions.

Actions are those of training's VecNormalize + `model.predict(deterministic=True)`, bit for bit: the record keeps
the normalisation statistics as exact floats and `act` applies SB3's own formula.
"""

from __future__ import annotations

import collections
import functools
import hashlib
import json
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.envs import TrackSettings, action_space, observation_space, resolve
from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path, write_text_atomic
from mjtraj.rl import ALGORITHM_NAMES, ALGORITHMS, RECURRENT, law_label
from mjtraj.rl.extra import algorithm

FORMAT = "mjtraj-policy/1"
LEGACY_RESIDUAL_SCALE = 60.0
"""N m: the residual scale of records written before it was an argument (the saturation)."""


@dataclass(frozen=True)
class Normalization:
    """VecNormalize's observation transform: clip((obs - mean) / sqrt(var + epsilon), -clip, clip); shapes (d,)."""

    mean: NDArray[np.float64]
    var: NDArray[np.float64]
    epsilon: float
    clip: float

    @classmethod
    def of(cls, vec_normalize: Any) -> Normalization:
        """The current statistics of an SB3 VecNormalize (copied)."""
        rms = vec_normalize.obs_rms
        return cls(np.array(rms.mean, dtype=np.float64), np.array(rms.var, dtype=np.float64),
                   float(vec_normalize.epsilon), float(vec_normalize.clip_obs))

    def __call__(self, obs: NDArray[np.float64]) -> NDArray[np.float32]:
        return np.clip((obs - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip, self.clip).astype(np.float32)

    def as_dict(self) -> dict[str, Any]:
        return {"mean": self.mean.tolist(), "var": self.var.tolist(), "epsilon": self.epsilon, "clip": self.clip}


def record_path(path: Path) -> Path:
    """The record beside a policy zip: policy.zip -> policy.json."""
    return path.with_suffix(".json")


def env_kwargs(record: dict[str, Any]) -> dict[str, Any]:
    """The UR5Track-v0 arguments of a training run's `record` (a record from before residual_scale: the 60 N m then
    used)."""
    kwargs = dict(record["env"])
    kwargs.setdefault("residual_scale", LEGACY_RESIDUAL_SCALE)
    return kwargs


def trained_observation_space(record: dict[str, Any], clip: float) -> Any:
    """The observation space a run's model was built with: the env's under running statistics (VecNormalize keeps
    it), the fixed scales' clipped box, float32, otherwise (mjtraj.rl.train)."""
    from gymnasium import spaces

    settings = resolve(**env_kwargs(record))
    if record["settings"].get("observation_scaling", "running") != "fixed":
        return observation_space(settings)
    return spaces.Box(-clip, clip, observation_space(settings).shape, np.float32)


TRAINING_STATE = ("_last_obs", "_last_original_obs", "_last_episode_starts", "ep_info_buffer", "ep_success_buffer")
"""What an SB3 zip keeps of the training in progress; never read to act, so never unpickled on loading."""


@functools.cache
def inert_optimizer() -> type:
    """The class that stands in for every optimiser of a policy loaded to act: a torch.optim.Optimizer (as SB3
    expects) that holds no state and cannot step. Building PyTorch's Adam is the one part of loading that acting never
    needs, and with PyTorch's CUDA build it imports Triton, whose LLVM crashed the process beside Mesa's
    (MUJOCO_GL=osmesa) before a single action. Made on first use: plain callables are scored without PyTorch."""
    import torch

    class InertOptimizer(torch.optim.Optimizer):
        def __init__(self, params: Any = (), *args: Any, **kwargs: Any) -> None:  # no Optimizer.__init__: inert
            self.param_groups = []
            self.state = collections.defaultdict(dict)
            self.defaults = {}

        def state_dict(self) -> dict[str, Any]:
            return {"state": {}, "param_groups": []}

        def load_state_dict(self, state_dict: Any) -> None:
            """An optimiser's saved state is for training on; a policy loaded to act ignores it."""

        def zero_grad(self, set_to_none: bool = True) -> None:
            """Nothing to clear."""

        def step(self, closure: Any = None) -> None:  # type: ignore[override]
            raise InvalidInputError("policy: loaded to act (mjtraj.rl.policy.load_policy), it has no optimiser to "
                                    "train with; resume a run with mjtraj rl train --resume")

    return InertOptimizer


@contextmanager
def _inert_optimizers() -> Iterator[None]:
    """While an SB3 zip loads: every optimiser SB3 builds by name (torch.optim.Adam, as SAC's entropy coefficient
    is) is inert (`inert_optimizer`); the policies' own optimiser class is set through their policy_kwargs."""
    import torch

    real = torch.optim.Adam
    torch.optim.Adam = inert_optimizer()  # type: ignore[misc,assignment]
    try:
        yield
    finally:
        torch.optim.Adam = real  # type: ignore[misc]


def _acting_objects(zip_path: Path) -> dict[str, Any]:
    """SB3's custom_objects that load a zip to act: its training state left unread, its policy_kwargs with the
    inert optimiser as the optimiser class (`inert_optimizer`)."""
    from stable_baselines3.common.save_util import load_from_zip_file

    unread = dict.fromkeys((*TRAINING_STATE, "observation_space", "action_space"))  # what a newer numpy pickled
    data, _, _ = load_from_zip_file(zip_path, device="cpu", load_data=True, custom_objects=unread)
    kwargs = dict((data or {}).get("policy_kwargs") or {})
    return {**dict.fromkeys(TRAINING_STATE), "policy_kwargs": {**kwargs, "optimizer_class": inert_optimizer()}}


class Policy:
    """A trained tracking policy: `act(obs)` for a batch of UR5Track-v0 observations.

    Attributes:
      model: the SB3 algorithm (SAC, PPO or TD3).
      record: the training run's record (settings, hyperparameters, versions, seeds), see `mjtraj.rl.train`.
      normalization: the observation transform the model was trained behind.
      timesteps: environment steps it had trained for when saved.
    """

    def __init__(self, model: Any, record: dict[str, Any], normalization: Normalization, timesteps: int,
                 path: Path | None = None, sha256: str = "") -> None:
        self.model = model
        self.record = record
        self.normalization = normalization
        self.timesteps = timesteps
        self.path = path
        self.sha256 = sha256
        """Of the zip at `path` ('' until saved or loaded)."""
        self._settings: TrackSettings | None = None
        self._memory: Any = None
        """A recurrent policy's LSTM states for the current batch (None: fresh)."""
        self._starts = np.zeros(0, dtype=bool)

    @property
    def recurrent(self) -> bool:
        """Whether it carries memory across an episode (RecurrentPPO): tell it where episodes start (`start`)."""
        return self.algo in RECURRENT

    def start(self, starts: npt.ArrayLike) -> None:
        """Episodes begin in rows `starts` (bool (B,)): a recurrent policy clears their memory before its next
        action; a B other than the last one's starts every row afresh. Others ignore it."""
        flags = np.asarray(starts, dtype=bool).reshape(-1)
        if flags.size != self._starts.size:
            self._memory, self._starts = None, np.ones(flags.size, dtype=bool)
        self._starts = self._starts | flags

    @property
    def algo(self) -> str:
        return str(self.record["settings"]["algo"])

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """The UR5Track-v0 arguments it trained with (a record from before residual_scale: the 60 N m then used)."""
        return env_kwargs(self.record)

    def settings(self) -> TrackSettings:
        """The env settings it acts in (resolved from `env_kwargs` once)."""
        if self._settings is None:
            self._settings = resolve(**self.env_kwargs)
        return self._settings

    @property
    def label(self) -> str:
        """How results tables name its configuration: planner+LAW+residual SAC (its scale in N m; LAW is PID, or CT
        for computed torque), or planner+SAC torque; then ', mismatch-trained', ', sees PID' (or CT),
        ', LAW-advantage reward' and ', fixed scales' when it trained under plant randomisation, observed the
        controller's state, was rewarded relative to PID alone or saw fixed observation scales. Runs that differ
        only in their seed share a label."""
        env = self.env_kwargs
        algo = ALGORITHM_NAMES.get(self.algo, self.algo.upper())
        law = law_label(env.get("controller", "pid"))
        fixed = self.record["settings"].get("observation_scaling", "running") == "fixed"
        notes = "".join([", mismatch-trained" if env.get("plant_randomization", "none") != "none" else "",
                         f", sees {law}" if env.get("observe_control", False) else "",
                         f", {law}-advantage reward" if env.get("reward_baseline", "none") != "none" else "",
                         ", fixed scales" if fixed else "",
                         {"true": ", sees the true plant (privileged)", "estimate": ", sees the adaptive estimate"}
                         .get(env.get("observe_plant", "none"), ""),
                         f", history {env['history']}" if env.get("history") else "",
                         ", the teacher's weights" if "student" in self.record else ""])
        if env["action_mode"] == "residual":
            return f"{env['planner']}+{law}+residual {algo} ({env['residual_scale']:g} N m{notes})"
        return f"{env['planner']}+{algo} torque{f' ({notes[2:]})' if notes else ''}"

    def act(self, obs: npt.ArrayLike) -> NDArray[np.float32]:
        """Deterministic actions in [-1, 1], shape (B, n), for observations of shape (B, d)."""
        x = np.asarray(obs, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != self.normalization.mean.size:
            raise InvalidInputError(f"obs: expected shape (B, {self.normalization.mean.size}), got {x.shape}")
        if not self.recurrent:
            actions, _ = self.model.predict(self.normalization(x), deterministic=True)
            return np.asarray(actions, dtype=np.float32)
        if x.shape[0] != self._starts.size:  # a new batch: every row starts
            self._memory, self._starts = None, np.ones(x.shape[0], dtype=bool)
        actions, self._memory = self.model.predict(self.normalization(x), state=self._memory,
                                                   episode_start=self._starts, deterministic=True)
        self._starts = np.zeros(x.shape[0], dtype=bool)
        return np.asarray(actions, dtype=np.float32)

    def save(self, path: str | Path) -> Path:
        """Write the SB3 zip at `path` (.zip) and its record beside it; returns the zip's path."""
        path = Path(path).with_suffix(".zip")
        with atomic_path(path) as tmp:
            self.model.save(tmp)
        self.path, self.sha256 = path, hashlib.sha256(path.read_bytes()).hexdigest()
        body = {"format": FORMAT, "timesteps": self.timesteps, "zip_sha256": self.sha256, "run": self.record,
                "normalization": self.normalization.as_dict()}
        write_text_atomic(record_path(path), json.dumps(body, indent=1) + "\n")
        return path


def load_policy(path: str | Path) -> Policy:
    """Load a policy saved by `mjtraj rl train` (its zip; the record is read from beside it).

    Raises:
      InvalidInputError: no such file, no record, a record that does not belong to the zip, or a zip whose
        observation or action space is not the env's its record describes (the message says which).
      MissingExtraError: the rl extra is not installed.
    """
    zip_path = Path(path)
    if zip_path.suffix != ".zip":
        raise InvalidInputError(f"policy: expected a policy .zip saved by mjtraj rl train, got {str(path)!r}")
    if not zip_path.is_file():
        raise InvalidInputError(f"policy: file not found: {zip_path}")
    meta_path = record_path(zip_path)
    if not meta_path.is_file():
        raise InvalidInputError(f"policy: no record {meta_path.name} beside {zip_path.name}; mjtraj rl train writes "
                                "the two together")
    try:
        body = json.loads(meta_path.read_text())
    except json.JSONDecodeError as e:
        raise InvalidInputError(f"policy: {meta_path} is not valid JSON ({e})") from e
    if not isinstance(body, dict) or body.get("format") != FORMAT:
        raise InvalidInputError(f"policy: {meta_path} is not an mjtraj policy record (expected format {FORMAT})")
    missing = [key for key in ("zip_sha256", "timesteps", "run", "normalization") if key not in body] + [
        f"run.{key}" for key in ("settings", "env", "streams") if key not in body.get("run", {})]
    if missing:
        raise InvalidInputError(f"policy: {meta_path} lacks {', '.join(missing)}")
    sha = hashlib.sha256(zip_path.read_bytes()).hexdigest()
    if body["zip_sha256"] != sha:
        raise InvalidInputError(f"policy: {meta_path.name} records a different zip than {zip_path.name} "
                                f"(sha256 {body['zip_sha256'][:12]} vs {sha[:12]})")
    record = body["run"]
    algo = record["settings"]["algo"]
    if algo not in ALGORITHMS:
        raise InvalidInputError(f"policy: unknown algorithm {algo!r} in {meta_path.name}; valid: "
                                f"{', '.join(ALGORITHMS)}")
    n = body["normalization"]
    cls = algorithm(algo)
    with _inert_optimizers():
        objects = _acting_objects(zip_path)
        try:
            model = cls.load(zip_path, device="cpu", custom_objects=objects)
        except ImportError:  # spaces pickled by a newer numpy (numpy._core) than this one: rebuilt from the record
            settings = resolve(**env_kwargs(record))
            model = cls.load(zip_path, device="cpu", custom_objects={
                **objects, "observation_space": trained_observation_space(record, float(n["clip"])),
                "action_space": action_space(settings)})  # the weights' shapes still have to fit (torch checks)
    normalization = Normalization(np.array(n["mean"], dtype=np.float64), np.array(n["var"], dtype=np.float64),
                                  float(n["epsilon"]), float(n["clip"]))
    policy = Policy(model, record, normalization, int(body["timesteps"]), zip_path, sha)
    check_spaces(policy, policy.settings(), where=zip_path.name)
    return policy


def check_spaces(policy: Policy, settings: TrackSettings, *, where: str) -> None:
    """InvalidInputError unless the policy's observation and action spaces are those of the env `settings`."""
    obs, act = observation_space(settings), action_space(settings)
    env = f"UR5Track-v0 (action_mode={settings.action_mode}, preview={settings.preview})"
    got_obs = policy.model.observation_space
    if getattr(got_obs, "shape", None) != obs.shape or policy.normalization.mean.shape != obs.shape:
        raise InvalidInputError(f"policy: {where} takes observations of shape {getattr(got_obs, 'shape', got_obs)} "
                                f"but {env} gives shape {obs.shape}")
    got_act = policy.model.action_space
    if getattr(got_act, "shape", None) != act.shape or not (
            np.all(got_act.low == act.low) and np.all(got_act.high == act.high)):
        raise InvalidInputError(f"policy: {where} acts in {got_act} but {env} takes {act}")
