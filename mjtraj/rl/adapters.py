"""Any policy as the benchmark scores it: an SB3 zip from `mjtraj rl train`, a shipped baseline, a plain callable
or a `torch.nn.Module`, behind one batched interface that knows the env settings it acts in.

The protocol a user's policy follows (every part optional but the call):
- `policy(obs) -> action`: one observation (d,) to one action (n,) in [-1, 1], Gymnasium's convention; with
  `policy.batched = True` a batch (B, d) to (B, n) instead (a torch module is always batched);
- `policy.reset(starts)`: called before the first action of a batch of episodes, `starts` a bool array (B,) of the
  episodes that start (a recurrent policy clears its state there);
- `policy.privileged = True`: the policy also receives each episode's plant, the dict the env reports as
  `info["plant"]` (payload_kg, mass_scale_j, inertia_scale_j, damping_j, friction_j; the nominal plant's values on
  a nominal scenario): `policy(obs, plant)`, batched `policy(obs, plants)` with a list of dicts; a torch module gets
  a float32 tensor (B, 1 + 4n) in that order;
- `policy.env = {...}`: the env settings it acts in (ENV_KEYS); missing ones come from the caller's settings, then
  BENCHMARK_ENV (UR5Track-v1's defaults);
- `policy.files = [...]`: files its actions depend on beyond its source (weights it loads), relative to the source
  file's folder: every row's policy_sha256 covers them (`fingerprint`), as it covers a torch module's weights;
- `policy.streams = [...]`: the seeds of the episodes it trained or was validated on (what each env's `reset(seed=)`
  got: ints or entropy lists, `mjtraj.rl.streams`): `rl eval` refuses to score it on any scenario drawn from one of
  them, as it refuses a run of `mjtraj rl train` on its recorded streams.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import json
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.envs import RESIDUAL_SCALE, TrackSettings, resolve
from mjtraj.exceptions import InvalidInputError, PolicyError, UnnamedPolicyEnvError
from mjtraj.rl import ALGORITHM_NAMES

BENCHMARK_ENV: dict[str, Any] = {"planner": "cubic", "controller": "pid", "action_mode": "residual",
                                 "residual_scale": RESIDUAL_SCALE, "observe_control": False, "preview": 0,
                                 "preview_frame": "absolute",
                                 "observe_plant": "none", "history": 0, "observe_task": False,
                                 "observe_measured": False, "observe_disturbance": False}
"""The env settings of a policy that declares none: UR5Track-v1's (UR5Track-v2's observation adds observe_task and
observe_measured)."""
ENV_KEYS = tuple(BENCHMARK_ENV)
"""The env settings a policy acts in (a zip's come from its training record)."""
RECORDED_WHERE_SET = ("observe_disturbance",)
"""Settings added after evaluations were published: a row's `policy_env` names them only where they differ from
BENCHMARK_ENV, so that earlier rows read as they did."""
KINDS = ("sb3-zip", "callable", "torch")


class _FailedOn(Exception):
    """A callable policy raised on observation `row` of a batch (its exception `cause`)."""

    def __init__(self, row: int, cause: Exception) -> None:
        super().__init__(row, cause)
        self.row, self.cause = row, cause


@dataclass
class ScoredPolicy:
    """A policy ready to be scored: batched actions, episode starts, plants if privileged, and its env settings.

    Attributes:
      label: how tables name it.
      source: what the user gave (a path, MODULE:ATTR, baseline:NAME or the object's repr).
      kind: sb3-zip, callable or torch.
      env: the ENV_KEYS settings it acts in (a zip: plus everything else its training env set).
      privileged: it receives the plants.
      sha256: of the zip, or the callable's `fingerprint` ('' if none).
      timesteps: training steps (a zip), else ''.
      record: a zip's training record (None otherwise).
      streams: the seeds a policy without a record declares it trained or validated on (`policy.streams`).
    """

    label: str
    source: str
    kind: str
    env: dict[str, Any]
    act_batch: Callable[..., Any] = field(repr=False)
    reset_hook: Callable[[NDArray[np.bool_]], Any] | None = field(default=None, repr=False)
    privileged: bool = False
    sha256: str = ""
    timesteps: int | str = ""
    record: dict[str, Any] | None = field(default=None, repr=False)
    path: Path | None = None
    streams: list[Any] | None = field(default=None, repr=False)
    configuration: str | None = None
    """A policy without a record that names its configuration (a plan policy: its fit's settings but the seed):
    policies of one configuration pool as seeds in `rl eval`; None: a configuration of its own."""
    _settings: TrackSettings | None = field(default=None, repr=False)
    _given: int = field(default=0, repr=False)
    """Observations given so far (where a failing call's first observation is)."""

    def settings(self) -> TrackSettings:
        """The env settings it acts in (resolved once)."""
        if self._settings is None:
            self._settings = resolve(**self.env)
        return self._settings

    @property
    def controller(self) -> str:
        return str(self.env.get("controller", "pid"))

    @property
    def planner(self) -> str:
        return str(self.env["planner"])

    @property
    def sees_plant(self) -> bool:
        """Privileged at evaluation: it receives the plants, or observes their true parameters (observe_plant)."""
        return self.privileged or self.env.get("observe_plant") == "true"

    def start(self, starts: NDArray[np.bool_]) -> None:
        """Episodes `starts` (bool (B,)) begin: the policy's reset hook, if it has one."""
        if self.reset_hook is not None:
            self.reset_hook(starts)

    def act(self, obs: NDArray[np.float64], plants: Sequence[dict[str, float]] | None = None) -> NDArray[np.float64]:
        """Actions (B, n) for observations (B, d); `plants` one dict per row for a privileged policy.

        Raises:
          PolicyError: the policy raised, or returned actions of another shape than one action (n,) per observation,
            or non-finite ones; the message names the policy, what went wrong and the index, among the observations
            this policy was given (0 the first), of the one it failed on (a callable's, called per observation, or
            a non-finite action's) or else of the failing batch call's first.
        """
        first = self._given
        self._given += obs.shape[0]
        n = self.settings().n
        where = f"policy {self.label}: on observation {first} (shape {obs.shape[1:]})"
        try:
            out = self.act_batch(obs, plants) if self.privileged else self.act_batch(obs)
            actions = np.asarray(out, dtype=np.float64)
        except _FailedOn as e:  # a callable, called once per observation: the one it failed on
            raise PolicyError(f"policy {self.label}: on observation {first + e.row} (shape {obs.shape[1:]}) it raised "
                              f"{type(e.cause).__name__}: {' '.join(str(e.cause).split())}") from e.cause
        except Exception as e:  # noqa: BLE001 - a bug in the user's policy: said in one line, with where
            raise PolicyError(f"{where} it raised {type(e).__name__}: {' '.join(str(e).split())}") from e
        single = self.kind == "callable" and actions.ndim >= 1 and actions.shape[0] == obs.shape[0]
        if actions.shape != (obs.shape[0], n):
            got = actions.shape[1:] if single else actions.shape
            want = f"({n},) per observation" if single else f"({obs.shape[0]}, {n}) for {obs.shape[0]} observations"
            raise PolicyError(f"{where} it returned actions of shape {got}; expected {want}")
        bad = ~np.isfinite(actions).all(axis=1)
        if bad.any():
            row = int(np.argmax(bad))
            raise PolicyError(f"policy {self.label}: on observation {first + row} it returned the action "
                              f"{actions[row].tolist()}; expected finite values (values outside [-1, 1] are "
                              "clipped)")
        return actions

    def columns(self) -> dict[str, Any]:
        """What every evaluation row of this policy records about it."""
        return {"method": self.label, "policy": self.source, "policy_kind": self.kind,
                "policy_sha256": self.sha256[:16], "policy_timesteps": self.timesteps,
                "policy_privileged": int(self.sees_plant),
                "policy_env": json.dumps({k: self.env.get(k) for k in ENV_KEYS
                                          if k not in RECORDED_WHERE_SET
                                          or self.env.get(k, BENCHMARK_ENV[k]) != BENCHMARK_ENV[k]},
                                         sort_keys=True)}


def _env_of(declared: Any, settings: Mapping[str, Any] | None) -> dict[str, Any]:
    """BENCHMARK_ENV, then the caller's settings, then the policy's own declaration (its `env` attribute)."""
    if declared is not None and not isinstance(declared, Mapping):
        raise InvalidInputError(f"policy: its env attribute must be a dict of env settings, got {declared!r}")
    out = {**BENCHMARK_ENV, **(settings or {}), **(declared or {})}
    unknown = sorted(set(out) - set(ENV_KEYS))
    if unknown:
        raise InvalidInputError(f"policy: unknown env setting {unknown[0]!r}; valid: {', '.join(ENV_KEYS)}")
    return out


def check_settings(settings: Mapping[str, Any] | None) -> None:
    """InvalidInputError unless `settings` are env settings (ENV_KEYS) with valid values, whether or not a policy
    ends up using them."""
    if settings:
        resolve(**_env_of(None, settings))


def source_file(obj: Any) -> Path | None:
    """The file that defines the function, class or instance `obj` (None for a built-in or an interactive one)."""
    target = obj if inspect.isfunction(obj) or inspect.isclass(obj) else type(obj)
    file = getattr(sys.modules.get(getattr(target, "__module__", ""), None), "__file__", None)
    try:
        file = inspect.getsourcefile(target) or file
    except TypeError:
        pass
    return Path(file) if file and Path(file).is_file() else None


def fingerprint(obj: Any, file: Path | None = None) -> str:
    """sha256 of what decides a user's policy's actions, '' when none of it can be read: its source file (`file`,
    else the file that defines it), then a torch module's weights (every state_dict entry, by name), then each file
    its `files` attribute names (paths relative to the source file's folder: weights it loads, say)."""
    file = file if file is not None else source_file(obj)
    digest, parts = hashlib.sha256(), 0
    if file is not None:
        digest.update(file.read_bytes())
        parts += 1
    if _is_torch_module(obj):
        for name, tensor in sorted(obj.state_dict().items()):
            digest.update(name.encode())
            digest.update(tensor.detach().cpu().contiguous().numpy().tobytes())
            parts += 1
    for declared in getattr(obj, "files", ()) or ():
        path = Path(declared) if Path(declared).is_absolute() or file is None else file.parent / declared
        if not path.is_file():
            raise InvalidInputError(f"policy: its files attribute names {str(declared)!r}, which is not a file "
                                    f"({path})")
        digest.update(path.read_bytes())
        parts += 1
    return digest.hexdigest() if parts else ""


def _is_torch_module(obj: Any) -> bool:
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(obj, torch.nn.Module)


def plant_vector(plants: Sequence[dict[str, float]]) -> NDArray[np.float32]:
    """The plants' dicts as rows (B, 1 + 4n) in the dicts' order (payload_kg, mass_scale_j, ...)."""
    return np.array([list(p.values()) for p in plants], dtype=np.float32)


def from_object(obj: Any, *, label: str | None = None, source: str | None = None,
                settings: Mapping[str, Any] | None = None, file: Path | None = None) -> ScoredPolicy:
    """A user's callable or torch module (see the module docstring for what it may declare); `file`: the source
    file it was loaded from (FILE.py:ATTR), hashed with it (`fingerprint`).

    Raises:
      InvalidInputError: not callable, or a bad declaration.
    """
    if isinstance(obj, ScoredPolicy):
        return obj
    from mjtraj.rl.policy import Policy

    if isinstance(obj, Policy):
        return from_zip_policy(obj, label=label)
    if not callable(obj):
        raise InvalidInputError(f"policy: expected a callable, a torch.nn.Module, an SB3 zip or baseline:NAME, got "
                                f"{obj!r}")
    privileged = bool(getattr(obj, "privileged", False))
    env = _env_of(getattr(obj, "env", None), settings)
    reset = getattr(obj, "reset", None)
    if reset is not None and not callable(reset):
        raise InvalidInputError(f"policy: its reset attribute must be callable(starts), got {reset!r}")
    streams = _declared_streams(getattr(obj, "streams", None))
    name = label or getattr(obj, "name", None) or source or getattr(obj, "__qualname__", type(obj).__name__)
    if _is_torch_module(obj):
        import torch

        def act_torch(obs: NDArray[np.float64], plants: Sequence[dict[str, float]] | None = None) -> Any:
            with torch.no_grad():
                x = torch.as_tensor(np.asarray(obs, dtype=np.float32))
                y = obj(x, torch.as_tensor(plant_vector(plants))) if plants is not None else obj(x)
            return y.numpy()

        return ScoredPolicy(str(name), source or repr(type(obj).__name__), "torch", env, act_torch, reset,
                            privileged, fingerprint(obj, file), streams=streams)
    if getattr(obj, "batched", False):
        act = obj
    else:
        def act(obs: NDArray[np.float64], plants: Sequence[dict[str, float]] | None = None) -> Any:
            out = []
            for row, o in enumerate(obs):
                try:
                    out.append(np.asarray(obj(o) if plants is None else obj(o, plants[row]), dtype=np.float64))
                except Exception as e:  # noqa: BLE001 - the user's policy: which observation it failed on
                    raise _FailedOn(row, e) from e
            return np.stack(out)

    return ScoredPolicy(str(name), source or str(name), "callable", env, act, reset, privileged,
                        fingerprint(obj, file), streams=streams)


def _declared_streams(streams: Any) -> list[Any] | None:
    """A policy's `streams` declaration checked: a list of seeds (ints >= 0 or lists of them), or None.

    Raises:
      InvalidInputError: anything else."""
    if streams is None:
        return None

    def seed(x: Any) -> bool:
        if isinstance(x, (list, tuple)):
            return len(x) > 0 and all(seed(v) for v in x)
        return isinstance(x, (int, np.integer)) and not isinstance(x, bool) and bool(x >= 0)

    if not isinstance(streams, (list, tuple)) or not all(seed(x) for x in streams):
        raise InvalidInputError(f"policy: its streams attribute must be a list of seeds (ints >= 0 or lists of them, "
                                f"what its envs' reset(seed=) got), got {streams!r}")
    return list(streams)


SB3_POLICY_MODULES = {"sb3_contrib.common.recurrent.policies": "recurrent_ppo",
                      "stable_baselines3.sac.policies": "sac", "stable_baselines3.td3.policies": "td3",
                      "stable_baselines3.common.policies": "ppo", "stable_baselines3.ppo.policies": "ppo"}
"""How a plain SB3 zip's algorithm is read from the module of its pickled policy class: sb3-contrib's recurrent
policies, SAC's, TD3's, and the actor-critic policies PPO trains (A2C's are the same classes: an A2C zip loads as
PPO and acts alike, deterministically). Any other module is refused."""


def sb3_algorithm(path: Path) -> str:
    """The algorithm (mjtraj.rl.ALGORITHMS) of an SB3 zip, from the policy class its `data` records."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
        module = str(data["policy_class"]["__module__"])
    except (zipfile.BadZipFile, KeyError, TypeError, json.JSONDecodeError) as e:
        raise InvalidInputError(f"policy: {path} is not a stable-baselines3 zip ({type(e).__name__}: {e})") from e
    if module not in SB3_POLICY_MODULES:
        raise InvalidInputError(f"policy: {path} holds a policy of {module}; expected one of "
                                f"{', '.join(ALGORITHM_NAMES.values())} (stable-baselines3 or sb3-contrib)")
    return SB3_POLICY_MODULES[module]


def suggested_settings(size: int, n: int = 3) -> dict[str, Any] | None:
    """Env settings (beyond UR5Track-v1's) whose observation has `size` entries: preview, observe_control and
    observe_task chosen so (the fewest extras first; with observe_task, UR5Track-v2's observe_measured too); None if
    none fits."""
    for task in (False, True):
        for control in (False, True):
            rest = size - (6 * n + 1) - 2 * n * control - 2 * task
            if rest >= 0 and rest % (2 * n) == 0:
                return {"preview": rest // (2 * n), "observe_control": control, "observe_task": task,
                        "observe_measured": task}
    return None


def from_plain_zip(path: Path, settings: Mapping[str, Any] | None) -> ScoredPolicy:
    """A zip saved by stable-baselines3 itself (`model.save`, no mjtraj record beside it), acting in the env
    `settings` (ENV_KEYS, from `--policy-env`): its deterministic actions on the raw observations (no
    normalisation: a plain SB3 model has none of its own).

    Raises:
      InvalidInputError: no settings (the message gives the command that scores it), or the zip's observation or
        action space is not the env's.
    """
    from mjtraj.rl.extra import algorithm

    algo = sb3_algorithm(path)
    model = algorithm(algo).load(path, device="cpu")
    size, actions = int(np.prod(model.observation_space.shape)), tuple(model.action_space.shape)
    if not settings:
        guess = suggested_settings(size) or {}
        flags = [f"--policy-env {k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in guess.items()
                 if v != BENCHMARK_ENV.get(k, False)] or ["--policy-env action_mode=residual"]
        raise UnnamedPolicyEnvError(f"policy: {path} has no mjtraj record beside it (a zip saved by "
                                    f"stable-baselines3 itself); say which env it acts in (UR5Track-v1's settings "
                                    f"unless named)", [word for flag in flags for word in flag.split(" ", 1)],
                                    f"mjtraj rl eval --policy {path} {' '.join(flags)}")
    env = _env_of(None, settings)
    track = resolve(**env)
    if size != track.obs_size or actions != (track.n,):
        raise InvalidInputError(f"policy: {path} acts on observations of {size} entries and actions of shape "
                                f"{actions}; the env {env} gives {track.obs_size} and takes ({track.n},)")
    recurrent = algo == "recurrent_ppo"
    state: dict[str, Any] = {"lstm": None, "starts": None}

    def act(obs: NDArray[np.float64]) -> Any:
        if not recurrent:
            return model.predict(np.asarray(obs, dtype=np.float32), deterministic=True)[0]
        out, state["lstm"] = model.predict(np.asarray(obs, dtype=np.float32), state=state["lstm"],
                                           episode_start=state["starts"], deterministic=True)
        state["starts"] = np.zeros(obs.shape[0], dtype=bool)
        return out

    def reset(starts: NDArray[np.bool_]) -> None:
        state["starts"] = np.asarray(starts, dtype=bool).copy()

    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    return ScoredPolicy(f"{path.name} ({ALGORITHM_NAMES[algo]})", str(path), "sb3-zip", env, act,
                        reset if recurrent else None, False, sha, int(getattr(model, "num_timesteps", 0)))


def from_zip_policy(policy: Any, *, label: str | None = None, source: str | None = None) -> ScoredPolicy:
    """A Policy loaded from a zip (mjtraj.rl.policy): its recorded env, batched, not privileged."""
    return ScoredPolicy(label or policy.label, source or str(policy.path), "sb3-zip", dict(policy.env_kwargs),
                        policy.act, policy.start, False, policy.sha256, policy.timesteps, policy.record, policy.path,
                        policy.settings())


def import_attribute(spec: str) -> Any:
    """MODULE:ATTR (an importable module, or a .py file) -> the attribute.

    Raises:
      InvalidInputError: the module or the attribute cannot be found (the message says which).
    """
    module_name, _, attr = spec.rpartition(":")
    if not module_name or not attr:
        raise InvalidInputError(f"policy: expected PATH.zip, baseline:NAME or MODULE:ATTR, got {spec!r}")
    if module_name.endswith(".py"):
        path = Path(module_name)
        if not path.is_file():
            raise InvalidInputError(f"policy: file not found: {path}")
        loader = importlib.util.spec_from_file_location(f"mjtraj_user_policy_{path.stem}", path)
        assert loader is not None and loader.loader is not None
        module = importlib.util.module_from_spec(loader)
        loader.loader.exec_module(module)
    else:
        try:
            module = importlib.import_module(module_name)
        except ImportError as e:
            raise InvalidInputError(f"policy: cannot import module {module_name!r} ({e})") from e
    try:
        return getattr(module, attr)
    except AttributeError as e:
        raise InvalidInputError(f"policy: module {module_name!r} has no attribute {attr!r}") from e


def _batched(path: Path, *, source: str) -> ScoredPolicy:
    """A batched run's policy file (mjtraj.rl.batched) as the benchmark scores it, named `source`."""
    from mjtraj.rl.batched_policy import label, load_batched
    from mjtraj.rl.ensemble import is_ensemble, load_ensemble
    from mjtraj.rl.naming import distilled_label

    module = load_ensemble(path) if is_ensemble(path) else load_batched(path)
    named = distilled_label(module.record) if "distill" in module.record else label(module.record)
    if "members" in module.record:
        named += f", ensemble of {len(module.record['members'])}"
    policy = from_object(module, label=named, source=source)
    policy.record, policy.path = module.record, path
    policy.timesteps = int(module.record.get("timesteps", 0))
    return policy


def _plan(path: Path, *, source: str) -> ScoredPolicy:
    """A plan policy file (mjtraj.rl.plan_policy) as the benchmark scores it, named `source`; its sha256 covers
    the file."""
    from mjtraj.rl.plan_policy import load_plan

    module = load_plan(path)
    policy = from_object(module, label=module.name, source=source)
    policy.path = path  # its record declares its streams as a callable does (`streams`), checked as theirs
    policy.configuration = module.name  # the fit's settings but its seed: fits of other seeds pool
    return policy


def load_any(source: Any, *, settings: Mapping[str, Any] | None = None) -> ScoredPolicy:
    """A policy from what a user names: PATH.zip (rl train's), PATH.pt (rl train --batched's), PATH.npz (rl
    plan's), baseline:NAME (shipped), MODULE:ATTR or FILE.py:ATTR (a callable or torch module), or the object
    itself. `settings` (ENV_KEYS) apply to policies that are not zips where they do not declare their own.

    Raises:
      InvalidInputError: nothing loadable by that name (the message says why).
      MissingExtraError: a zip without the rl extra installed.
    """
    from mjtraj.rl.policy import load_policy

    if not isinstance(source, (str, Path)):
        return from_object(source, settings=settings)
    text = str(source)
    if text.startswith("baseline:"):
        from mjtraj.rl.baselines import baseline_path

        path = baseline_path(text.split(":", 1)[1])
        if path.suffix == ".npz":
            return _plan(path, source=text)
        if path.suffix == ".pt":
            return _batched(path, source=text)
        return from_zip_policy(load_policy(path), source=text)
    if text.endswith(".py") and ":" not in text:
        raise InvalidInputError(f"policy: expected FILE.py:ATTR (the file and the name of the policy in it, e.g. "
                                f"{text}:policy), got {text!r}")
    if text.endswith(".npz") and ":" not in text:  # a plan policy (mjtraj.rl.plan_policy)
        return _plan(Path(text), source=text)
    if text.endswith(".pt") and ":" not in text:  # a batched run's policy (mjtraj.rl.batched)
        return _batched(Path(text), source=text)
    if text.endswith(".zip") or ":" not in text or Path(text).exists():
        from mjtraj.rl.policy import record_path

        if text.endswith(".zip") and Path(text).is_file() and not record_path(Path(text)).is_file():
            return from_plain_zip(Path(text), settings)
        return from_zip_policy(load_policy(text), source=text)
    module, _, attr = text.rpartition(":")
    short = f"{Path(module).name if module.endswith('.py') else module}:{attr}"  # a file by its name, not its folder
    obj = import_attribute(text)
    file = Path(module) if module.endswith(".py") else None
    return from_object(obj, label=None if getattr(obj, "name", None) else short, source=text, settings=settings,
                       file=file)
