"""Statistics: CVaR closed forms and the paired bootstrap ratio's exact cases and coverage."""


from __future__ import annotations

import numpy as np
import pytest

from mjtraj.exceptions import InvalidInputError
from mjtraj.study.stats import cvar, paired_ratio


def test_cvar_closed_forms():
    assert cvar(np.arange(1, 101), 0.9) == pytest.approx(95.5)
    assert cvar([5.0] * 7, 0.9) == pytest.approx(5.0)
    x = np.random.default_rng(0).exponential(size=400_000)  # CVaR_0.9 = ln 10 + 1
    assert cvar(x, 0.9) == pytest.approx(np.log(10) + 1, rel=5e-3)
    with pytest.raises(InvalidInputError, match=r"^alpha: expected a level in \[0, 1\), got 1.0$"):
        cvar(x, 1.0)


def test_paired_ratio_exact_cases_and_coverage():
    b = np.random.default_rng(1).uniform(1, 2, 300)
    r = paired_ratio(2 * b, b)
    assert (r.ratio, r.low, r.high, r.win_rate) == (pytest.approx(2), pytest.approx(2), pytest.approx(2), 1.0)
    assert r.reduction[0] == pytest.approx(50.0)
    rng = np.random.default_rng(2)
    covered = 0
    for _ in range(40):  # true ratio of means 1.5
        y = rng.exponential(size=200)
        x = 1.5 * rng.exponential(size=200)
        ci = paired_ratio(x, y, resamples=500)
        covered += ci.low <= 1.5 <= ci.high
    assert covered >= 34  # nominal 95 %: 38 of 40 expected



@pytest.mark.slow
def test_chunked_bootstrap_draws_what_one_draw_does(monkeypatch):
    """The bootstrap in chunks (bounded memory) gives the intervals of one draw of every index, bit for bit."""
    import mjtraj.study.stats as stats

    rng = np.random.default_rng(5)
    a, b = rng.lognormal(0, 1, 3001), rng.lognormal(0, 1, 3001)
    monkeypatch.setattr(stats, "CHUNK_CELLS", 10**12)  # one draw of all 2000 x 3001 indices
    whole = stats.paired_ratio(a, b), stats.median_interval(a)
    monkeypatch.setattr(stats, "CHUNK_CELLS", 3001 * 7 + 5)  # 7 resamples a chunk, the last one shorter
    chunked = stats.paired_ratio(a, b), stats.median_interval(a)
    assert chunked == whole
    picks = np.vstack(list(stats.resample_chunks(np.random.default_rng(1), 10, 23)))
    np.testing.assert_array_equal(picks, np.random.default_rng(1).integers(0, 10, size=(23, 10)))


def test_over_exact_pairs_the_ratios_interval_is_the_delta_methods_and_agrees_with_the_bootstrap():
    """Above EXACT_PAIRS the interval is r -/+ z se (delta method); on 20,000 skewed pairs it lies within 5 % of the
    bootstrap interval's width of the bootstrap's ends, and below the threshold nothing changes."""
    import statistics

    from mjtraj.study.stats import EXACT_PAIRS, delta_interval, paired_ratio

    rng = np.random.default_rng(3)
    y = rng.lognormal(0.0, 1.0, 20_000)
    x = y * rng.lognormal(0.1, 0.3, y.size) + rng.normal(0.0, 0.2, y.size)
    boot = paired_ratio(x, y)
    delta = paired_ratio(x, y, exact_pairs=10_000)
    width = boot.high - boot.low
    assert abs(delta.low - boot.low) < 0.05 * width and abs(delta.high - boot.high) < 0.05 * width
    assert (delta.ratio, delta.win_rate, delta.count) == (boot.ratio, boot.win_rate, boot.count)
    r = x.mean() / y.mean()  # the closed form, written out
    se = np.sqrt(np.sum((x - r * y) ** 2) / (x.size - 1)) / np.sqrt(x.size) / y.mean()
    z = statistics.NormalDist().inv_cdf(0.975)
    assert np.allclose(delta_interval(x, y), (r - z * se, r + z * se), rtol=1e-12)
    assert x.size <= EXACT_PAIRS  # boot above was the bootstrap's
