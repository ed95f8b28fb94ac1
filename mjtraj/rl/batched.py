"""Batched on-policy training at the field's scale: skrl's PPO on mjtraj's native vector env, hundreds of sub-envs
stepped as one batch, on a mixture of the benchmark's families.

The recipe (every setting in BatchedSettings, recorded in run.json):
- the action is a residual on the configured control law (the adaptive law by default), `residual_scale` N m per
  unit; the policy's mean starts at exactly zero (its last layer zeroed), so the untrained policy is the law alone,
  and its exploration starts at `initial_std` units (0.1: 0.6 N m), far below what SB3's defaults started at;
- observations are standardised by running statistics (skrl's RunningStandardScaler), the value target too;
- the reward is the advantage over the law alone on the same episode (`reward_baseline="controller"`): its sum is
  J_law - J_exec, so the learner sees only what it can change; validation and evaluation score J_exec;
- sub-envs are split evenly over `families` (nominal, aggressive and mismatch by default); sub-env i draws its
  episodes from the training stream [seed, 16, i] (mjtraj.rl.streams), never an evaluation scenario;
- every `steps / evaluations` steps the deterministic policy runs `validation` tasks per family from the validation
  stream [seed, 17, i]; the curve records each family's mean J_exec over the law alone's on the same tasks, and the
  best point by the worst family's ratio is kept as best.pt;
- with a settle window (`settle`, 0.5 s: protocol v2's episodes) training and validation episodes go on after the
  motion with the goal held, the policy observes the measured state, and validation scores J_settle paired with
  the law alone (`_paired`: `<family>_missed` counts the episodes the policy failed where the law came to rest,
  `<family>_ratio` is J_settle over the episodes both came to rest on); best.pt is then the point with the fewest
  missed episodes, the worst family's ratio breaking ties (`selection_key`);
- `init` starts the policy from a distilled (mjtraj.rl.distill) or earlier batched policy (`start_from`): PPO then
  fine-tunes it, and the untrained policy is that policy, not the law alone.

The deployable policy is exported as a `BatchedPolicy` (a torch.nn.Module: the standardisation and the mean
network, actions clipped to [-1, 1]) in policy.pt and best.pt, which `mjtraj rl eval --policy RUN/best.pt` scores
(`load_batched`). Training runs PyTorch on `threads` threads (1 by default: small networks run fastest on one).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.exceptions import InvalidInputError
from mjtraj.files import write_text_atomic
from mjtraj.rl.batched_policy import (
    BATCHED_RUN,
    BatchedSettings,
    batched_policy_class,
    mlp,
    policy_settings,
    save_policy,
)
from mjtraj.rl.streams import TRAIN_STREAM, VALIDATION_STREAM, training_entropies

CURVE_COLUMNS = ("timesteps", "wall_s", "steps_per_s", "train_episodes", "train_advantage_mean")
"""The learning curve's columns, then per family `<family>_ratio` (validation mean J_exec over the law alone's) and
`<family>_cost` (the policy's mean J_exec, +inf if it failed any episode), then `worst_ratio`; with a settle window
(protocol v2) both score J_settle, the ratio over the episodes both came to rest on, each family's `<family>_missed`
follows its cost and the row ends with their sum, `missed` (`_validated`)."""


VARIABLE_LENGTH = ("aggressive",)
"""Families whose episodes differ in length (the aggressive family's T is drawn). The closed loop runs them side by
side in one vector env, except under a law that previews the reference (`ClosedLoop.previews`: mpc and
adaptive_mpc), which runs episodes of one length per batch: there each of their sub-envs is a vector env of its own
(a step of one costs about what a sub-env's share of a batched step does; the aggressive third of a batch stepped so
had taken 82 % of the vector env's time)."""


class MixedFamilies:
    """Sub-envs of several families side by side as one batch of `num_envs` (numpy in, numpy out, Gymnasium's
    SAME_STEP autoreset: an ending step returns the next episode's first observation). The summed rewards of ended
    episodes are kept in `finished` until read."""

    def __init__(self, settings: BatchedSettings) -> None:
        from mjtraj.envs import UR5TrackVectorEnv

        self.settings = settings
        self.envs = []
        for family, count in zip(settings.families, settings.split(), strict=True):
            env = UR5TrackVectorEnv(count, autoreset_mode="SameStep", **settings.env_kwargs(family))
            if family in VARIABLE_LENGTH and env.loop.previews:
                self.envs += [UR5TrackVectorEnv(1, autoreset_mode="SameStep", **settings.env_kwargs(family))
                              for _ in range(count)]
            else:
                self.envs.append(env)
        self.num_envs = settings.num_envs
        self.single_observation_space = self.envs[0].single_observation_space
        self.single_action_space = self.envs[0].single_action_space
        self._bounds = np.cumsum([0, *(env.num_envs for env in self.envs)])
        self._returns = np.zeros(self.num_envs)
        self.finished: list[float] = []

    def reset(self) -> NDArray[np.float64]:
        """Every sub-env from its training stream (mjtraj.rl.streams.training_entropies)."""
        seeds: list[int | None] = list(training_entropies(self.settings.seed, self.num_envs))
        parts = [env.reset(seed=seeds[a:b])[0] for env, a, b in zip(self.envs, self._bounds, self._bounds[1:],
                                                                   strict=False)]
        self._returns[:] = 0.0
        return np.concatenate(parts)

    def step(self, actions: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                          NDArray[np.bool_], NDArray[np.bool_]]:
        obs, rewards, terminated, truncated = [], [], [], []
        for env, a, b in zip(self.envs, self._bounds, self._bounds[1:], strict=False):
            o, r, te, tr, _ = env.step(actions[a:b])
            obs.append(o)
            rewards.append(r)
            terminated.append(te)
            truncated.append(tr)
        reward = np.concatenate(rewards)
        done = np.concatenate(terminated) | np.concatenate(truncated)
        self._returns += reward
        self.finished.extend(self._returns[done].tolist())
        self._returns[done] = 0.0
        return np.concatenate(obs), reward, np.concatenate(terminated), np.concatenate(truncated)


def _models(settings: BatchedSettings, observation_space: Any, action_space: Any) -> dict[str, Any]:
    """skrl's policy (Gaussian, its mean's last layer zeroed, log std at log(initial_std)) and value models."""
    import torch
    from skrl.models.torch import DeterministicMixin, GaussianMixin, Model

    d, n = observation_space.shape[0], action_space.shape[0]

    class Policy(GaussianMixin, Model):
        def __init__(self) -> None:
            Model.__init__(self, observation_space=observation_space, action_space=action_space, device="cpu")
            GaussianMixin.__init__(self, clip_actions=False)
            self.net = mlp(d, n, settings.hidden)
            torch.nn.init.zeros_(self.net[-1].weight)
            torch.nn.init.zeros_(self.net[-1].bias)
            self.log_std = torch.nn.Parameter(torch.full((n,), float(np.log(settings.initial_std))))

        def compute(self, inputs: dict[str, Any], role: str = "") -> tuple[Any, dict[str, Any]]:
            return self.net(inputs["observations"]), {"log_std": self.log_std}

    class Value(DeterministicMixin, Model):
        def __init__(self) -> None:
            Model.__init__(self, observation_space=observation_space, action_space=action_space, device="cpu")
            DeterministicMixin.__init__(self)
            self.net = mlp(d, 1, settings.hidden)

        def compute(self, inputs: dict[str, Any], role: str = "") -> tuple[Any, dict[str, Any]]:
            return self.net(inputs["observations"]), {}

    return {"policy": Policy(), "value": Value()}


def _agent(settings: BatchedSettings, env: MixedFamilies, out: Path) -> Any:
    """skrl's PPO with the recipe's settings, its memory one rollout of every sub-env."""
    from skrl.agents.torch.ppo import PPO, PPO_CFG
    from skrl.memories.torch import RandomMemory
    from skrl.resources.preprocessors.torch import RunningStandardScaler

    o, a = env.single_observation_space, env.single_action_space
    cfg = PPO_CFG(rollouts=settings.rollouts, learning_epochs=settings.epochs, mini_batches=settings.minibatches,
                  discount_factor=settings.discount, gae_lambda=settings.gae_lambda,
                  learning_rate=settings.learning_rate, observation_preprocessor=RunningStandardScaler,
                  observation_preprocessor_kwargs={"size": o, "device": "cpu"},
                  value_preprocessor=RunningStandardScaler, value_preprocessor_kwargs={"size": 1, "device": "cpu"})
    cfg.experiment.directory = str(out)
    cfg.experiment.experiment_name = "skrl"
    cfg.experiment.write_interval = 0
    cfg.experiment.checkpoint_interval = 0
    memory = RandomMemory(memory_size=settings.rollouts, num_envs=env.num_envs, device="cpu")
    agent = PPO(models=_models(settings, o, a), memory=memory, observation_space=o, action_space=a, device="cpu",
                cfg=cfg)
    return agent


def export_policy(agent: Any, settings: BatchedSettings) -> Any:
    """The deployable BatchedPolicy of a skrl agent: its policy's mean network and observation standardiser."""
    policy, scaler = agent.models["policy"], agent._observation_preprocessor
    first, last = policy.net[0], policy.net[-1]
    module = batched_policy_class()(first.in_features, last.out_features, settings)
    module.net.load_state_dict(policy.net.state_dict())
    module.mean.copy_(scaler.running_mean.float())
    module.std.copy_(scaler.running_variance.float().sqrt())
    module.epsilon.fill_(float(scaler.epsilon))
    module.clip.fill_(float(scaler.clip_threshold))
    return module


def validation_sets(settings: BatchedSettings) -> list[tuple[str, Any, list[Any], list[Any], list[Any] | None,
                                                             list[Any] | None]]:
    """Per family: (family, its env settings, references, weights, plants or None, settle windows or None),
    `validation` episodes drawn by the family's rules (the env's `sample_episode`, as its own episodes are) from the
    validation stream [seed, 17, k x validation + i] (k the family's position); with a settle window each reference
    ends with it, as the env's episodes do."""
    from mjtraj.core import with_window
    from mjtraj.envs import resolve

    out = []
    for k, family in enumerate(settings.families):
        env = resolve(**settings.env_kwargs(family))
        rngs = [np.random.default_rng([settings.seed, VALIDATION_STREAM, k * settings.validation + i])
                for i in range(settings.validation)]
        episodes = [env.sample_episode(rng) for rng in rngs]
        tasks = [task for task, _ in episodes]
        plants = [plant for _, plant in episodes]
        references = [env.planner.plan(task, env.model) for task in tasks]
        window = env.settle_steps
        held_episodes = [with_window(task, ref, window) for task, ref in zip(tasks, references, strict=True)]
        references = [ref for ref, _ in held_episodes]
        out.append((family, env, references, [env.weights(task) for task in tasks], plants if env.perturbs else None,
                    [settle for _, settle in held_episodes] if window else None))
    return out


def _paired(mine: Sequence[Any], alone: Sequence[Any]) -> tuple[int, float]:
    """Protocol v2's validation of a policy's outcomes beside the law alone's on the same episodes: (missed, ratio).
    `missed` counts the episodes the policy failed where the law came to rest; `ratio` is the policy's mean J_settle
    over the episodes both came to rest on over the law's there (1 where there are none). Episodes the law failed do
    not count against the policy."""
    ok = [a.status == "ok" for a in alone]
    missed = sum(o.status != "ok" and fine for o, fine in zip(mine, ok, strict=True))
    both = [(o.metrics["cost"], a.metrics["cost"]) for o, a in zip(mine, alone, strict=True) if o.status == "ok"
            and a.status == "ok"]
    return int(missed), (float(sum(c for c, _ in both) / sum(c for _, c in both)) if both else 1.0)


def selection_key(point: dict[str, Any]) -> tuple[float, float]:
    """How validation points are ranked (the smaller the better): the missed episodes (protocol v2's points; 0 for
    v1's, which have none), then the worst family's ratio."""
    return float(point.get("missed", 0)), float(point["worst_ratio"])


MISSED_WEIGHT = 1e6
"""What one missed episode adds to a validation point's `selection_value`: more than any ratio, so that the value
ranks points as `selection_key` does."""


def selection_value(point: dict[str, Any]) -> float:
    """A validation point as one number, for a search to minimise, in `selection_key`'s order: the worst family's
    ratio, plus MISSED_WEIGHT for each episode the policy missed where the law came to rest."""
    missed, worst = selection_key(point)
    return worst + MISSED_WEIGHT * missed


class Validation:
    """A run's validation: its sets (`validation_sets`) and the outcomes of the law alone there (or of the law
    `versus`, e.g. a distillation's teacher), run once; `row` scores a policy on them as the learning curve records
    it, its ratios and missed episodes then over `versus`'s."""

    def __init__(self, settings: BatchedSettings, versus: str = "") -> None:
        from mjtraj.rl.episodes import run_episodes

        self.settings = settings
        self.versus = versus
        self.sets = validation_sets(settings)
        self.alone = {family: run_episodes(None, self._reference(s), refs, w, p, settle)
                      for family, s, refs, w, p, settle in self.sets}

    def _reference(self, env: Any) -> Any:
        """The env settings the reference law runs in: `env`'s, its controller `versus` if one is given."""
        return dataclasses.replace(env, loop=dataclasses.replace(env.loop, controller=self.versus)) if self.versus \
            else env

    def reference(self) -> str:
        """What the ratios are over, for a progress line: "the law alone's" or "mpc's"."""
        return f"{self.versus}'s" if self.versus else "the law alone's"

    def law_alone(self) -> dict[str, Any]:
        """The run record's account of the reference on the validation sets: its mean cost and failures per family
        (`law_alone_...`, or `versus_...` beside `versus`, the law's name)."""
        prefix = "versus" if self.versus else "law_alone"
        return {**({"versus": self.versus} if self.versus else {}),
                f"{prefix}_validation_cost": {f: _mean_cost(o) for f, o in self.alone.items()},
                f"{prefix}_validation_failures": {f: sum(x.status != "ok" for x in o) for f, o in self.alone.items()}}

    def columns(self) -> list[str]:
        """The validation columns of a learning curve, in `row`'s order."""
        measured = ("ratio", "cost", "missed") if self.settings.settle else ("ratio", "cost")
        return [*(f"{f}_{what}" for f in self.settings.families for what in measured), "worst_ratio",
                *(("missed",) if self.settings.settle else ())]

    def row(self, module: Any) -> dict[str, float]:
        """The validation columns of the deployable policy `module` (`_validated`)."""
        from mjtraj.rl.adapters import from_object

        return _validated(from_object(module, label="batched"), self.sets, self.alone, self.settings)


def _validated(policy: Any, validation: list[Any], alone: dict[str, list[Any]], settings: BatchedSettings
               ) -> dict[str, float]:
    """The learning curve's validation columns of `policy` on the `validation` sets (`validation_sets`), beside the
    law alone's outcomes there: `<family>_cost` and `<family>_ratio` (J_exec over the law's mean), then
    `worst_ratio`; with a settle window the ratio is `_paired`'s, each family's `<family>_missed` follows its cost
    and their sum `missed` closes the row."""
    from mjtraj.rl.episodes import run_episodes

    row: dict[str, float] = {}
    for family, s, refs, w, p, settle in validation:
        outcomes = run_episodes(policy, s, refs, w, p, settle)
        row[f"{family}_cost"] = _mean_cost(outcomes)
        if settings.settle:
            row[f"{family}_missed"], row[f"{family}_ratio"] = _paired(outcomes, alone[family])
        else:
            row[f"{family}_ratio"] = row[f"{family}_cost"] / _mean_cost(alone[family])
    row["worst_ratio"] = max(row[f"{family}_ratio"] for family in settings.families)
    if settings.settle:
        row["missed"] = sum(row[f"{family}_missed"] for family in settings.families)
    return row


def _mean_cost(outcomes: Sequence[Any]) -> float:
    """Mean cost (J_exec, or J_settle with a settle window), +inf if any episode failed (the protocol's rule)."""
    if any(o.status != "ok" for o in outcomes):
        return float("inf")
    return float(np.mean([o.metrics["cost"] for o in outcomes]))


@dataclass
class BatchedReport:
    """What a batched run wrote and how it ended."""

    out: Path
    policy: Path
    best: Path
    curve: Path
    timesteps: int
    wall: float
    best_point: dict[str, float]
    stopped: str = ""
    """Why training stopped before its steps ('' where it ran them all)."""
    episodes: int = 0
    """Training episodes the sub-envs finished."""
    score: str = "J_exec"
    """What validation scored: J_exec, or J_settle with a settle window."""


def interact(agent: Any, env: MixedFamilies, obs: NDArray[np.float64], t: int, total: int) -> NDArray[np.float64]:
    """One step of every sub-env under skrl's PPO at timestep `t` of `total`: act, step, record the transition,
    and update once a rollout is full (skrl's post-interaction); returns the next observations."""
    import torch

    agent.pre_interaction(timestep=t, timesteps=total)
    with torch.no_grad():
        x = torch.as_tensor(obs, dtype=torch.float32)
        actions, _ = agent.act(x, None, timestep=t, timesteps=total)
        next_obs, reward, terminated, truncated = env.step(actions.numpy().astype(np.float64))
        agent.record_transition(observations=x, states=None, actions=actions,
                                rewards=torch.as_tensor(reward, dtype=torch.float32).view(-1, 1),
                                next_observations=torch.as_tensor(next_obs, dtype=torch.float32), next_states=None,
                                terminated=torch.as_tensor(terminated).view(-1, 1),
                                truncated=torch.as_tensor(truncated).view(-1, 1), infos={}, timestep=t,
                                timesteps=total)
    agent.post_interaction(timestep=t, timesteps=total)
    return next_obs


def new_agent(settings: BatchedSettings, env: MixedFamilies, out: Path) -> Any:
    """skrl's PPO of the recipe, initialised and in training mode, PyTorch on `settings.threads` threads."""
    import torch
    from skrl.utils import set_seed

    torch.set_num_threads(settings.threads)
    set_seed(settings.seed)
    agent = _agent(settings, env, out)
    agent.init()
    if settings.init:
        start_from(agent, settings)
    agent.enable_training_mode(True)
    return agent


INIT_SHARED = ("controller", "action_mode", "residual_scale", "hidden", "preview", "preview_frame", "observe_control",
               "observe_task", "observe_plant", "observe_disturbance", "history", "output", "features", "anchor",
               "structure")
"""The settings a policy that starts a run (`BatchedSettings.init`) must share with it: what it observes, how its
action acts, its network."""


def init_defaults(path: str | Path) -> dict[str, Any]:
    """What a run started from the policy file `path` takes from it unless given: its INIT_SHARED settings and its
    settle window."""
    from mjtraj.rl.batched_policy import load_batched

    theirs = dataclasses.asdict(policy_settings(load_batched(path).record))
    return {k: theirs[k] for k in (*INIT_SHARED, "settle")}


def file_sha256(path: str | Path) -> str:
    """The sha256 of a file's bytes (a run records its init policy's, and a resumed run checks it)."""
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def start_from(agent: Any, settings: BatchedSettings) -> None:
    """Start the agent's policy from the policy file `settings.init`: its mean network, and the observation
    standardiser at its mean and standard deviation (counted as the states they came from, its clip and epsilon),
    so that the untrained policy acts as that policy does; the value network and the exploration start afresh.

    Raises:
      InvalidInputError: not a policy file, or one trained with other INIT_SHARED settings.
    """
    import torch

    from mjtraj.rl.batched_policy import load_batched

    module = load_batched(settings.init)
    theirs, mine = dataclasses.asdict(policy_settings(module.record)), dataclasses.asdict(settings)
    differ = [f"{k} {theirs[k]!r} (this run: {mine[k]!r})" for k in INIT_SHARED if theirs[k] != mine[k]]
    if differ:
        raise InvalidInputError(f"init: {settings.init} was trained with other settings: {'; '.join(differ)}")
    policy, scaler = agent.models["policy"], agent._observation_preprocessor
    with torch.no_grad():
        policy.net.load_state_dict(module.net.state_dict())
        scaler.running_mean.copy_(module.mean.double())
        scaler.running_variance.copy_(module.std.double() ** 2)
        scaler.current_count.fill_(float(module.record.get("timesteps", 1)))
    scaler.clip_threshold, scaler.epsilon = float(module.clip), float(module.epsilon)


RESUME_FILE = "resume.pt"
"""A batched run's resume point (`save_resume_point`), written at every validation point and removed when the run
completes."""


def save_resume_point(path: Path, agent: Any, env: MixedFamilies, obs: NDArray[np.float64],
                      progress: dict[str, Any]) -> None:
    """Everything an interrupted run needs to go on bit for bit from the end of a rollout (its update done, the
    memory to be refilled): the agent's models, optimiser and standardisers, its rollout count, the sub-envs (their
    loops, plants and generators, pickled), the next observations, the global generators PyTorch, NumPy and Python
    draw from, and the training's bookkeeping `progress`. Written atomically."""
    import pickle
    import random

    import torch

    from mjtraj.files import atomic_path

    modules = {name: agent._get_internal_value(module) for name, module in agent.checkpoint_modules.items()}
    state = {"agent": modules, "rollout": agent._rollout, "env": pickle.dumps(env), "obs": obs,
             "rng": {"torch": torch.get_rng_state(), "numpy": np.random.get_state(),  # noqa: NPY002 (skrl seeds it)
                     "python": random.getstate()},
             "progress": progress}
    with atomic_path(path) as temporary:
        torch.save(state, temporary)


def load_resume_point(path: Path, agent: Any) -> tuple[MixedFamilies, NDArray[np.float64], dict[str, Any]]:
    """Restore `save_resume_point`'s state into a new `agent` of the same settings; (env, obs, progress)."""
    import pickle
    import random

    import torch

    state = torch.load(path, weights_only=False)
    for name, data in state["agent"].items():
        agent.checkpoint_modules[name].load_state_dict(data)
    agent._rollout = state["rollout"]
    torch.set_rng_state(state["rng"]["torch"])
    np.random.set_state(state["rng"]["numpy"])  # noqa: NPY002 (the global state skrl's set_seed seeds)
    random.setstate(state["rng"]["python"])
    return pickle.loads(state["env"]), state["obs"], state["progress"]


def resume_batched(out: str | Path, *, progress: bool = True) -> BatchedReport:
    """Continue the interrupted batched run in `out` from its last resume point (RESUME_FILE), with the settings it
    recorded: on the same machine and thread count it ends with the files an uninterrupted run writes, bit for bit
    (but the wall-clock columns).

    Raises:
      InvalidInputError: `out` holds no resume point (a complete run, or one stopped before its first validation
        point).
    """
    import torch

    path = Path(out) / RESUME_FILE
    if not path.is_file():
        raise InvalidInputError(f"resume: {out} holds no resume point of a batched run ({RESUME_FILE}: written at "
                                "every validation point, removed when the run completes); start it again in a new "
                                "folder")
    record = torch.load(path, weights_only=False)["progress"]["record"]
    settings = policy_settings(record)
    if settings.init and record.get("init_sha256") != file_sha256(settings.init):
        raise InvalidInputError(f"init: {settings.init} is not the policy file the run started from (its sha256 "
                                f"changed); resume it with that file in place")
    return train_batched(settings, out, progress=progress, command=record["command"], resume=True)


def train_batched(settings: BatchedSettings, out: str | Path, *, progress: bool = True,
                  command: str = "", on_validation: Callable[[int, float], bool] | None = None,
                  resume: bool = False) -> BatchedReport:
    """Train by the recipe of the module docstring into `out`: run.json, learning_curve.csv and .png, policy.pt (the
    last policy), best.pt (the best validation point by `selection_key`) and skrl/ (the agent, for inspection);
    RESUME_FILE while it runs (`resume=True` goes on from it: `resume_batched`).

    Training stops early once `settings.patience` validation points in a row have not improved the best point, or
    when `on_validation(timesteps, selection_value(point))`, called at every validation point, returns True (a search's
    pruner); run.json records where and why ("stopped").

    Raises:
      InvalidInputError: a cubic `output` (PPO's actions are Gaussian around the network's output itself), or
        `features`, an `anchor` or a `structure` (its networks act on the observation alone).
    """
    from mjtraj.rl.extra import rl_versions

    if settings.output != "linear":
        raise InvalidInputError(f"output: PPO explores around the network's output itself, expected linear, got "
                                f"{settings.output!r} (a cubic output is a distillation's)")
    shaped = [k for k in ("features", "anchor", "structure") if getattr(settings, k) != "none"]
    if shaped:
        name = shaped[0]
        raise InvalidInputError(f"{name}: batched PPO's networks act on the observation alone, expected none, got "
                                f"{getattr(settings, name)!r} (a distillation's)")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env = MixedFamilies(settings)
    agent = new_agent(settings, env, out)
    validation = Validation(settings)
    record: dict[str, Any] = {
        "format": BATCHED_RUN, "settings": dataclasses.asdict(settings), "command": command,
        "library": "skrl PPO", "versions": {**rl_versions(), "skrl": _skrl_version()},
        "streams": {"train": {"stream": TRAIN_STREAM,
                              "gym_seeds": training_entropies(settings.seed, settings.num_envs)},
                    "validation": {"stream": VALIDATION_STREAM,
                                   "count": settings.validation * len(settings.families)}},
        **validation.law_alone()}
    if settings.init:
        record["init_sha256"] = file_sha256(settings.init)
    columns = [*CURVE_COLUMNS, *validation.columns()]
    curve_path = out / "learning_curve.csv"
    rows: list[dict[str, Any]] = []
    total = settings.iterations * settings.rollouts
    points = sorted({round(k * settings.iterations / settings.evaluations) * settings.rollouts
                     for k in range(1, settings.evaluations + 1)})
    best: dict[str, float] = {"worst_ratio": float("inf"), **({"missed": float("inf")} if settings.settle else {})}
    first, before, wall_steps, since_best, episodes = 0, 0.0, 0, 0, 0
    if resume:
        env, obs, saved = load_resume_point(out / RESUME_FILE, agent)
        first, before, wall_steps = saved["t"], saved["wall_s"], saved["wall_steps"]
        rows, best, since_best, episodes = saved["rows"], saved["best"], saved["since_best"], saved["episodes"]
        if settings.settle:  # a v2 resume point from before missed episodes were counted: its ratio said them
            best.setdefault("missed", 0.0 if np.isfinite(best["worst_ratio"]) else float("inf"))
        record["resumed"] = [*saved["record"].get("resumed", []), {"timesteps": first * settings.num_envs}]
    else:
        obs = env.reset()
    start = time.perf_counter()
    from tqdm import tqdm

    bar = tqdm(total=total * settings.num_envs, initial=first * settings.num_envs, unit="step",
               desc="rl train --batched", disable=not progress, dynamic_ncols=True)
    stopped = ""
    for t in range(first, total):
        obs = interact(agent, env, obs, t, total)
        wall_steps += settings.num_envs
        bar.update(settings.num_envs)
        if t + 1 in points:
            elapsed = before + time.perf_counter() - start
            module = export_policy(agent, settings)
            module.eval()
            advantage = float(np.mean(env.finished)) if env.finished else float("nan")
            row: dict[str, Any] = {"timesteps": (t + 1) * settings.num_envs, "wall_s": elapsed,
                                   "steps_per_s": wall_steps / elapsed, "train_episodes": len(env.finished),
                                   "train_advantage_mean": advantage}
            episodes += len(env.finished)
            env.finished.clear()
            row.update(validation.row(module))
            rows.append(row)
            _write_curve(curve_path, columns, rows)
            since_best += 1
            if selection_key(row) < selection_key(best):
                best, since_best = {k: float(v) for k, v in row.items()}, 0
                save_policy(module, out / "best.pt", {**record, "timesteps": row["timesteps"], "point": best})
            bar.set_postfix_str(f"worst family {row['worst_ratio']:.4f} of the law"
                                + (f", {row['missed']:.0f} missed" if "missed" in row else ""))
            stopped = _stop_reason(row, since_best, settings.patience, on_validation)
            if stopped:
                break
            save_resume_point(out / RESUME_FILE, agent, env, obs,
                              {"t": t + 1, "wall_s": elapsed, "wall_steps": wall_steps, "rows": rows, "best": best,
                               "since_best": since_best, "episodes": episodes, "record": record})
    bar.close()
    wall = before + time.perf_counter() - start
    final = export_policy(agent, settings)
    done, episodes = wall_steps, episodes + len(env.finished)
    record.update(timesteps=done, wall_s=wall, steps_per_s=done / wall, best=best, stopped=stopped,
                  train_episodes=episodes)
    save_policy(final, out / "policy.pt", record)
    write_text_atomic(out / "run.json", json.dumps(record, indent=1, default=float) + "\n")
    if rows:
        from mjtraj.rl.batched_policy import label
        from mjtraj.rl.curve import plot_batched_curve

        plot_batched_curve(curve_path, out / "learning_curve.png", title=f"{label(record)}, seed {settings.seed}")
    if not (out / "best.pt").is_file():  # no validation point finished: the last policy stands
        save_policy(final, out / "best.pt", record)
    (out / RESUME_FILE).unlink(missing_ok=True)
    return BatchedReport(out, out / "policy.pt", out / "best.pt", curve_path, done, wall, best, stopped, episodes,
                         "J_settle" if settings.settle else "J_exec")


def _stop_reason(row: dict[str, Any], since_best: int, patience: int,
                 on_validation: Callable[[int, float], bool] | None) -> str:
    """Why training stops at the validation point `row` ('' to go on): `patience` points in a row without a better
    one, or the search's pruner (`on_validation`) says so."""
    if patience and since_best >= patience:
        return f"patience: {since_best} validation points without a better worst family"
    if on_validation is not None and on_validation(row["timesteps"], selection_value(row)):
        return "pruned by the search"
    return ""


def _write_curve(path: Path, columns: Sequence[str], rows: Sequence[dict[str, Any]]) -> None:
    import io

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: repr(v) if isinstance(v, float) else v for k, v in r.items()} for r in rows)
    write_text_atomic(path, buffer.getvalue())


def _skrl_version() -> str:
    import importlib.metadata

    return importlib.metadata.version("skrl")
