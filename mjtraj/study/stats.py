"""Statistics of sweeps: paired ratios with percentile-bootstrap intervals, win rates, CVaR.

Planners are compared on the same scenarios (paired): a scenario enters a comparison when both planners executed
it (status ok). The bootstrap resamples scenarios with a fixed seed, so the same file gives the same intervals;
over more than EXACT_PAIRS pairs a ratio's interval is the delta method's normal one.
"""

from __future__ import annotations

import statistics
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.checks import positive_int
from mjtraj.exceptions import InvalidInputError

BOOTSTRAP_SEED = 20261121
BOOTSTRAP_RESAMPLES = 2000
EXACT_PAIRS = 200_000
"""Above this many pairs a paired ratio's interval is the delta method's normal interval (`delta_interval`), not
the bootstrap's: 2,000 resamples of a million pairs cost about half a minute per comparison, and at that size the
two agree to within the bootstrap's own Monte Carlo error (tested). Every sweep of up to 200,000 scenarios per
condition keeps the bootstrap, bit for bit."""
CHUNK_CELLS = 1 << 22
"""Resampled values drawn at a time (32 MB of indices): a bootstrap over millions of scenarios runs in bounded
memory, drawing the same indices in the same order as one draw of them all (the same intervals, bit for bit)."""


def resample_chunks(rng: np.random.Generator, n: int, resamples: int) -> Iterator[NDArray[np.int64]]:
    """`resamples` bootstrap index rows over n values, shape (k, n) per chunk, at most CHUNK_CELLS indices a chunk,
    in the order `rng.integers(0, n, size=(resamples, n))` draws them."""
    rows = max(1, CHUNK_CELLS // max(n, 1))
    done = 0
    while done < resamples:
        k = min(rows, resamples - done)
        yield rng.integers(0, n, size=(k, n))
        done += k


@dataclass(frozen=True)
class PairedRatio:
    """mean(a) / mean(b) over paired scenarios, its 95 % percentile-bootstrap interval, and how often a < b."""

    ratio: float
    low: float
    high: float
    win_rate: float
    """Fraction of scenarios where b is strictly lower than a (b 'wins')."""
    count: int

    @property
    def reduction(self) -> tuple[float, float, float]:
        """The paper's reduction of b relative to a, 100 (a - b) / a = 100 (1 - 1/ratio), in % (estimate, low,
        high)."""
        return tuple(100.0 * (1.0 - 1.0 / r) for r in (self.ratio, self.low, self.high))  # type: ignore[return-value]


def _pair(a: npt.ArrayLike, b: npt.ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 1:
        raise InvalidInputError(f"a, b: expected paired 1-D samples of one length, got shapes {x.shape}, {y.shape}")
    keep = np.isfinite(x) & np.isfinite(y)
    return x[keep], y[keep]


def ratio_of_means(a: npt.ArrayLike, b: npt.ArrayLike) -> float:
    """mean(a) / mean(b) over the scenarios where both are finite (shape (S,) each); NaN if there are none. The
    point estimate of `paired_ratio`, without its bootstrap."""
    x, y = _pair(a, b)
    return float(x.mean() / y.mean()) if x.size else float("nan")


def paired_ratio(a: npt.ArrayLike, b: npt.ArrayLike, *, resamples: int = BOOTSTRAP_RESAMPLES,
                 seed: int = BOOTSTRAP_SEED, level: float = 0.95, exact_pairs: int = EXACT_PAIRS) -> PairedRatio:
    """mean(a) / mean(b) over the scenarios where both are finite, with a percentile-bootstrap interval (over
    more than `exact_pairs` pairs, the delta method's normal interval instead: see EXACT_PAIRS).

    Args:
      a, b: one value per scenario, shape (S,) each (a planner's metric and the optimal one's).
    """
    x, y = _pair(a, b)
    if x.size == 0:
        nan = float("nan")
        return PairedRatio(nan, nan, nan, nan, 0)
    if x.size > exact_pairs:
        low, high = delta_interval(x, y, level)
        return PairedRatio(ratio_of_means(x, y), low, high, float(np.mean(y < x)), int(x.size))
    rng = np.random.default_rng(seed)
    ratios = np.concatenate([x[picks].mean(axis=1) / y[picks].mean(axis=1)
                             for picks in resample_chunks(rng, x.size, positive_int("resamples", resamples))])
    tail = 100.0 * (1.0 - level) / 2.0
    low, high = np.percentile(ratios, [tail, 100.0 - tail])
    return PairedRatio(ratio_of_means(x, y), float(low), float(high), float(np.mean(y < x)), int(x.size))


def delta_interval(x: NDArray[np.float64], y: NDArray[np.float64], level: float = 0.95) -> tuple[float, float]:
    """The delta method's normal interval of mean(x) / mean(y) over paired samples x, y (S,): r -/+ z se, with
    r = mean(x) / mean(y), se = std(x - r y, ddof=1) / (sqrt(S) |mean(y)|) and z the normal quantile of `level`."""
    ratio = x.mean() / y.mean()
    se = np.std(x - ratio * y, ddof=1) / (np.sqrt(x.size) * abs(y.mean()))
    z = statistics.NormalDist().inv_cdf(0.5 + level / 2.0)
    return float(ratio - z * se), float(ratio + z * se)


def cvar(values: npt.ArrayLike, alpha: float = 0.9) -> float:
    """Conditional value at risk: the mean of the worst (1 - alpha) fraction of the finite `values` (upper tail).

    With n values sorted ascending and m = (1 - alpha) n, the mean of the top floor(m) values and the fraction
    m - floor(m) of the next one (Rockafellar-Uryasev on the empirical distribution).
    """
    x = np.sort(np.asarray(values, dtype=np.float64)[np.isfinite(np.asarray(values, dtype=np.float64))])
    if not 0.0 <= alpha < 1.0:
        raise InvalidInputError(f"alpha: expected a level in [0, 1), got {alpha!r}")
    if x.size == 0:
        return float("nan")
    m = (1.0 - alpha) * x.size
    whole = int(np.floor(m + 1e-9))
    part = m - whole
    top = x[::-1]
    total = top[:whole].sum() + (part * top[whole] if whole < x.size and part > 1e-9 else 0.0)
    return float(total / m)


@dataclass(frozen=True)
class Median:
    """The median of the finite values, its 95 % percentile-bootstrap interval, and how many values it used."""

    value: float
    low: float
    high: float
    count: int


def median_interval(values: npt.ArrayLike, *, resamples: int = BOOTSTRAP_RESAMPLES, seed: int = BOOTSTRAP_SEED,
                    level: float = 0.95) -> Median:
    """Median of the finite `values` (shape (S,)) with a percentile-bootstrap interval over the S values."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        nan = float("nan")
        return Median(nan, nan, nan, 0)
    rng = np.random.default_rng(seed)
    medians = np.concatenate([np.median(x[picks], axis=1)
                              for picks in resample_chunks(rng, x.size, positive_int("resamples", resamples))])
    tail = 100.0 * (1.0 - level) / 2.0
    low, high = np.percentile(medians, [tail, 100.0 - tail])
    return Median(float(np.median(x)), float(low), float(high), int(x.size))
