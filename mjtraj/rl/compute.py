"""What each method of an evaluation computes per control period, beside its score: a control law's command (its
solve, for the predictive laws) and a policy's inference, each for one simulation on one core.

A law is timed as a teacher of itself (`ClosedLoop.teach`) along its own execution of the first scenario of each
family (cubic reference): the call computes exactly the command the loop applies there. A policy is timed on one
observation at a time (batch 1), its inference alone (with the estimators it observes, e.g. `mpc_filter`, timed
together along the law's execution: what a deployed policy spends per period): the law it acts on is timed as that
law. Times are wall-clock
on a machine that may be busy; they are a record of this run, not a benchmark (`mjtraj bench` measures speed as
ratios within one run).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mjtraj.threads import one_blas_thread

POLICY_CALLS = 200
"""Inference calls timed per policy (after 10 untimed ones)."""


@dataclass(frozen=True)
class StepCompute:
    """Per-period compute of one method: median and 99th percentile, ms, over `samples` periods or calls."""

    what: str
    median_ms: float
    p99_ms: float
    samples: int

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def law_compute(config: Any, family_tasks: Sequence[Any], model: Any, planner: Any, *,
                references: Sequence[Any] | None = None) -> StepCompute:
    """The law of loop `config` timed per period along its own execution of each of `references` (default: the
    cubic plans of `family_tasks`, one simulation each)."""
    from mjtraj.core import ClosedLoop

    law = config.controller
    refs = list(references) if references is not None else [planner.plan(task, model) for task in family_tasks]
    times: list[float] = []
    with one_blas_thread():
        for ref in refs:
            loop = ClosedLoop(model, config, nsim=1, teachers=(law,))
            loop.start([ref])
            while not loop.done.all():
                clock = time.perf_counter()
                loop.teach(law)
                times.append(time.perf_counter() - clock)
                loop.step()
    return _summary(f"{law}'s command", times)


def policy_compute(act: Any, size: int, *, shadows: Sequence[str] = (), config: Any = None, model: Any = None,
                   references: Sequence[Any] = (), observer: Any = None, reset: Any = None) -> StepCompute:
    """A policy's inference `act` timed on one observation of `size` values at a time (batch 1). A policy whose
    observation needs estimators beside the loop (`shadows`, e.g. `mpc_filter`) is timed per period along the law's
    execution of each of `references` (loop `config` on `model`, one simulation): the estimators' update and the
    inference together, as a deployed policy spends them. A policy with episode state (`reset(starts)`) is timed
    there on the observations `observer` (a `mjtraj.envs.Observer` of one simulation) makes of that execution, each
    reference an episode it starts (the observations made untimed, as the zeros of the others are): its first
    period, where it may plan, counts as any other."""
    obs = np.zeros((1, size))
    times: list[float] = []
    with one_blas_thread():
        for k in range(0 if observer is not None else 10 + POLICY_CALLS * (not shadows)):
            clock = time.perf_counter()
            act(obs)
            if k >= 10:
                times.append(time.perf_counter() - clock)
        if not shadows and observer is None:
            return _summary("inference, batch 1", times)
        from mjtraj.core import ClosedLoop

        for ref in references:
            loop = ClosedLoop(model, config, nsim=1, teachers=tuple(shadows))
            loop.start([ref])
            if observer is not None:
                observer.start(np.arange(1), [None], [ref])
                reset(np.ones(1, dtype=bool))
            while not loop.done.all():
                clock = time.perf_counter()
                for name in shadows:
                    loop.teach(name)
                spent = time.perf_counter() - clock
                given = observer(loop) if observer is not None else obs  # made apart, as the zeros are
                clock = time.perf_counter()
                act(given)
                times.append(spent + time.perf_counter() - clock)
                loop.step()
    what = f"inference and {', '.join(shadows)}" if shadows else "inference"
    return _summary(f"{what}, batch 1{', on its episodes' if observer is not None else ''}", times)


def _summary(what: str, seconds: Sequence[float]) -> StepCompute:
    values = np.asarray(seconds) * 1e3
    return StepCompute(what, float(np.median(values)), float(np.percentile(values, 99)), int(values.size))


def compute_table(computes: dict[str, StepCompute]) -> str:
    """Markdown: each method's per-period compute."""
    lines = ["| method | what is timed | median ms | p99 ms | periods or calls |", "|---|---|---|---|---|"]
    lines += [f"| {method} | {c.what} | {c.median_ms:.3g} | {c.p99_ms:.3g} | {c.samples} |"
              for method, c in computes.items()]
    return "\n".join(lines)
