"""Ensembles of trained policies (`mjtraj rl ensemble`): one deployable policy whose action is the mean of its
members' actions, inferred in NumPy.

Members are policies saved by `mjtraj rl distill` or `mjtraj rl train --batched` (policy.pt, best.pt) that act in
one env (the same observation, action and law) with one architecture (`SHAPING`). Each member computes its action
as its torch module does (`mjtraj.rl.batched_policy`: standardise, the network (with the gain structure, k + K
[e; ed]), clip to [-1, 1], cube where its output is cubic, add its anchor and clip again), in float32 from the
float32 observation, as `rl eval` feeds a torch module; the ensemble acts with the mean of the members' actions.
Students trained on other seeds err apart where their data was thin, and their mean can err less than each
(measured in docs/benchmark.md, "Ensembles").

The NumPy path is the ensemble's definition, what `rl eval` scores and times, not a stand-in for the torch modules:
it agrees with the members' modules within float32 rounding (a test holds it to 1e-5, 2e-5 with a gain structure),
and at batch 1 it spends a fraction of PyTorch's per-call time on the same arithmetic (docs/benchmark.md,
"Ensembles").
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.batched_policy import ENSEMBLE_FORMAT, GAIN_RANGE, read_saved, save_payload

SHAPING = ("hidden", "output", "features", "anchor", "structure")
"""The settings that shape a member's module besides its env: members share them, so that their arithmetic stacks."""


@dataclass(frozen=True)
class _Stacked:
    """K members' arithmetic stacked, float32: their standardisations, layers, and where features and anchor read."""

    mean: NDArray[np.float32]
    """(K, 1, D) each member's standardisation mean (D: the observation and its features)."""
    scale: NDArray[np.float32]
    """(K, 1, D) std + epsilon: the standardisation's divisor."""
    clip: NDArray[np.float32]
    """(K, 1, 1) the standardised observation's bound."""
    layers: tuple[tuple[NDArray[np.float32], NDArray[np.float32]], ...]
    """(weight transposed (K, in, out), bias (K, 1, out)) per linear layer; tanh between them."""
    scaled: tuple[int, int, int] | None
    anchored: tuple[int, int] | None
    cubic: bool
    context: NDArray[np.intp]
    """The standardised inputs the network reads (all of them, or the gain structure's context)."""
    fast: tuple[int, int] | None
    """The gain structure's [e; ed] entries, or None."""
    beyond: bool
    """The network also reads the excess of e and ed beyond GAIN_RANGE (gain_beyond)."""

    @classmethod
    def of(cls, modules: Sequence[Any]) -> _Stacked:
        """The stacked arithmetic of BatchedPolicy `modules` (one architecture)."""
        import torch

        def stack(get: Any) -> NDArray[np.float32]:
            return np.ascontiguousarray(np.stack([get(m).detach().cpu().numpy() for m in modules]), dtype=np.float32)

        count = sum(isinstance(layer, torch.nn.Linear) for layer in modules[0].net)

        def linear(m: Any, k: int) -> Any:
            return [layer for layer in m.net if isinstance(layer, torch.nn.Linear)][k]

        layers = tuple((stack(lambda m, k=k: linear(m, k).weight.T), stack(lambda m, k=k: linear(m, k).bias[None]))
                       for k in range(count))
        first = modules[0]
        return cls(stack(lambda m: m.mean[None]), stack(lambda m: (m.std + m.epsilon)[None]),
                   stack(lambda m: m.clip.reshape(1, 1)), layers, first.scaled, first.anchored, bool(first.cubic),
                   first.context.cpu().numpy(), first.fast, bool(first.beyond))

    def __call__(self, obs: NDArray[np.float32]) -> NDArray[np.float32]:
        """Each member's actions (K, B, n) for float32 observations (B, d), as its torch module computes them."""
        x = obs
        if self.scaled is not None:
            start, stop, move = self.scaled
            x = np.concatenate([obs, obs[:, start:stop] / np.maximum(obs[:, move:move + 1], np.float32(1e-6))], axis=1)
        standard = np.clip((x - self.mean) / self.scale, -self.clip, self.clip)
        h, errors = standard, None
        if self.fast is not None:  # k + K [e; ed], e and ed within GAIN_RANGE
            start, stop = self.fast
            errors = np.clip(standard[:, :, start:stop], np.float32(-GAIN_RANGE), np.float32(GAIN_RANGE))
            h = standard[:, :, self.context]
            if self.beyond:
                h = np.concatenate([h, standard[:, :, start:stop] - errors], axis=2)
        last = len(self.layers) - 1
        for k, (weight, bias) in enumerate(self.layers):
            h = h @ weight + bias
            if k < last:
                h = np.tanh(h)
        if errors is not None:
            n = errors.shape[2] // 2
            gain = h[:, :, n:].reshape(h.shape[0], h.shape[1], n, 2 * n)
            h = h[:, :, :n] + np.einsum("kbij,kbj->kbi", gain, errors)
        action = np.clip(h, np.float32(-1.0), np.float32(1.0))
        action = action**3 if self.cubic else action
        if self.anchored is None:
            return action
        return np.clip(action - obs[:, self.anchored[0]:self.anchored[1]], np.float32(-1.0), np.float32(1.0))


class EnsemblePolicy:
    """The deployable ensemble: a batched callable (B, d) -> (B, n) in the members' env (`env`), with the
    ensemble's `record` (its members' records under "members") and its file as `files` (every row's
    policy_sha256 covers the weights)."""

    batched = True

    def __init__(self, members: Sequence[Any], record: dict[str, Any], path: Path) -> None:
        self._stacked = _Stacked.of(members)
        self.env = dict(members[0].env)
        self.record = record
        self.files = [str(path.resolve())]

    def __call__(self, obs: Any) -> NDArray[np.float32]:
        actions = self._stacked(np.asarray(obs, dtype=np.float32))
        return np.sum(actions, axis=0) / np.float32(actions.shape[0])


def write_ensemble(paths: Sequence[str | Path], out: str | Path) -> Path:
    """Combine the policies at `paths` (batched runs' policy.pt or best.pt) into one ensemble at `out`.

    Raises:
      InvalidInputError: no member, a file that is not such a policy, one file twice, members that act in
        different envs or have different architectures (naming the setting), or an `out` that is a member's file or
        does not end in .pt.
    """
    from mjtraj.rl.batched_policy import load_batched, policy_settings

    files = [Path(p) for p in paths]
    target = Path(out)
    if not files:
        raise InvalidInputError("members: expected at least one policy file, got none")
    for f in files:
        if not f.is_file():
            raise InvalidInputError(f"members: expected policy files, got {f}, which is not a file")
        if f.resolve() == target.resolve():
            raise InvalidInputError(f"out: expected a file other than the members', got {target}, which is one of "
                                    f"them")
    if target.suffix != ".pt":
        raise InvalidInputError(f"out: expected a file name ending in .pt (how rl eval --policy knows a policy "
                                f"file), got {target}")
    hashes = [hashlib.sha256(f.read_bytes()).hexdigest() for f in files]
    for k, h in enumerate(hashes):
        if hashes.index(h) != k:
            raise InvalidInputError(f"members: {files[k]} is {files[hashes.index(h)]} again; expected distinct "
                                    f"policies")
    modules = [load_batched(f) for f in files]
    first = modules[0]
    for f, module in zip(files[1:], modules[1:], strict=True):
        differ = sorted(k for k in set(first.env) | set(module.env) if first.env.get(k) != module.env.get(k))
        if differ:
            key = differ[0]
            raise InvalidInputError(f"members: {f} acts with {key}={_shown(module.env, key)} where {files[0]} "
                                    f"acts with {key}={_shown(first.env, key)}; expected members that act in one env")
        mine, theirs = (dataclasses.asdict(policy_settings(m.record)) for m in (first, module))
        for key in SHAPING:
            if mine.get(key) != theirs.get(key):
                raise InvalidInputError(f"members: {f} has {key}={theirs.get(key)!r} where {files[0]} has "
                                        f"{key}={mine.get(key)!r}; expected members of one architecture")
    members = [{"path": str(f), "sha256": h, "record": m.record} for f, h, m in zip(files, hashes, modules,
                                                                                    strict=True)]
    record = {"format": ENSEMBLE_FORMAT, "settings": first.record["settings"], "members": members,
              **({"distill": first.record["distill"]} if "distill" in first.record else {})}
    save_payload({"format": ENSEMBLE_FORMAT, "states": [m.state_dict() for m in modules], "record": record}, target)
    return target


def is_ensemble(path: str | Path) -> bool:
    """Whether `path` is a file `write_ensemble` wrote."""
    return read_saved(Path(path)).get("format") == ENSEMBLE_FORMAT


def load_ensemble(path: str | Path) -> EnsemblePolicy:
    """The ensemble `write_ensemble` wrote at `path`.

    Raises:
      InvalidInputError: not such a file.
    """
    from mjtraj.rl.batched_policy import module_from_state

    file = Path(path)
    saved = read_saved(file)
    if saved.get("format") != ENSEMBLE_FORMAT:
        raise InvalidInputError(f"policy: expected an ensemble written by mjtraj rl ensemble (format "
                                f"{ENSEMBLE_FORMAT}), got {file} of format {saved.get('format')!r}")
    record = saved["record"]
    modules = [module_from_state(state, member["record"])
               for state, member in zip(saved["states"], record["members"], strict=True)]
    return EnsemblePolicy(modules, record, file)


def member_records(record: dict[str, Any]) -> list[dict[str, Any]]:
    """The run records behind a policy's `record`: an ensemble's members', else the record itself."""
    return [m["record"] for m in record["members"]] if record.get("format") == ENSEMBLE_FORMAT else [record]


def _shown(env: dict[str, Any], key: str) -> str:
    """An env setting as a refusal names it: its value, or the default where the policy leaves it unset."""
    return repr(env[key]) if key in env else "its default"
