"""Seed streams: which random streams train, validate and evaluate a policy, and why they never meet.

Every stream is numpy's `default_rng([seed, stream, index])`. Sweep families (mjtraj.domain.families) use streams 0-2
(their FAMILY_ID); sub-env i of a training run uses TRAIN_STREAM, the learning curve's validation tasks
VALIDATION_STREAM. Gymnasium seeds are single ints, so `stream_seed` packs (seed, stream, index) into the int
whose SeedSequence is that of [seed, stream, index]: SeedSequence reads an int as little-endian 32-bit words and,
for lists too, ignores trailing zero words. (This is also why a plain gym seed s is the list [s, 0, 0], the nominal
family's scenario 0 under seed s: seeding training envs with plain seeds would train on evaluation scenarios.)
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from mjtraj.exceptions import InvalidInputError
from mjtraj.study import FAMILY_ID

TRAIN_STREAM = 16
VALIDATION_STREAM = 17
WORD = 2**32


def check_seed(name: str, seed: int) -> int:
    """A seed of one 32-bit word, 0 <= seed < 2^32 (so that streams stay apart)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < WORD:
        raise InvalidInputError(f"{name}: expected a whole number in [0, 2^32), got {seed!r}")
    return int(seed)


def stream_seed(seed: int, stream: int, index: int) -> int:
    """The gym seed (one int) of `default_rng([seed, stream, index])`."""
    return check_seed("seed", seed) + stream * WORD + index * WORD**2


def fingerprint(entropy: int | Sequence[int]) -> tuple[int, ...]:
    """The state a bit generator seeded with `entropy` starts from: equal fingerprints, equal streams."""
    return tuple(int(x) for x in np.random.SeedSequence(entropy).generate_state(4, np.uint64))


def training_entropies(seed: int, num_envs: int) -> list[int]:
    """The gym seeds of a training run's sub-envs (each continues its stream across episodes)."""
    return [stream_seed(seed, TRAIN_STREAM, i) for i in range(num_envs)]


def family_entropies(family: str, seed: int, indices: Iterable[int]) -> list[list[int]]:
    """The entropy of each scenario of a sweep family (as mjtraj.domain.families.scenario seeds it)."""
    return [[seed, FAMILY_ID[family], i] for i in indices]


def shared_streams(a: Iterable[int | Sequence[int]], b: Iterable[int | Sequence[int]]) -> list[tuple[int, ...]]:
    """Fingerprints that the streams `a` and `b` have in common (empty: disjoint)."""
    return sorted({fingerprint(x) for x in a} & {fingerprint(x) for x in b})
