"""The benchmark's statistics (Agarwal et al., 2021, through rliable): per family and method, against a reference
method on the same held-out scenarios.

Scores: the per-scenario improvement over the reference, d = 1 - J / J_ref (1: no cost at all, 0: the reference's,
negative: worse), one value per (seed, scenario).

FAILURE_RULE (a failed episode: diverged, unstable, plan failed, error) is chosen so that turning any episode into a
failure can never improve any summary: the failed episode's J is +inf. Its improvement is then -inf (0 where the
reference failed too; 1 for a success where only the reference failed); the ratio of means is +inf as soon as one
episode failed where the reference did not; order statistics (IQM, probability of improvement, performance
profiles) rank it below every success. Scenarios where the reference failed leave the ratio of means (it is not
defined there) and are counted in `reference_failures`.

Intervals: 95 % percentile intervals (the order statistics at 2.5 % and 97.5 % of the resampled values, so that a
resample with an infinite value stays infinite) of a seeded stratified bootstrap: rliable's StratifiedBootstrap,
which draws from NumPy's global generator (seeded here, then restored), resampling scenarios and, within each,
seeds (task_bootstrap). The reference is one deterministic run per scenario, resampled with the method's scenario
(pairs stay paired).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

FAILURE_RULE = ("a failed episode scores J = +inf: improvement -inf (0 if the reference failed too), ratio of means "
                "+inf once any episode failed where the reference did not; never better than any success")
CONFIDENCE = 0.95
BOOTSTRAP_SEED = 0


@dataclass(frozen=True)
class Interval:
    """A point estimate and its 95 % bootstrap interval."""

    value: float
    low: float
    high: float

    def as_dict(self) -> dict[str, Any]:
        return _json_ready(asdict(self))  # type: ignore[no-any-return]


@dataclass(frozen=True)
class MethodSummary:
    """One method on one family against the reference (see the module docstring)."""

    seeds: int
    scenarios: int
    failures: int
    """Episodes (seed, scenario) that failed."""
    reference_failures: int
    ratio_of_means: Interval
    iqm: Interval
    """IQM of the per-(seed, scenario) improvement over the reference."""
    probability_of_improvement: Interval
    """P(J < J_ref) over scenarios, seeds paired with the reference's (ties count one half)."""
    wins: float
    """Share of (seed, scenario) pairs with J strictly below the reference's, %."""

    def as_dict(self) -> dict[str, Any]:
        return _json_ready(asdict(self))


def _json_ready(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, float) and not np.isfinite(value):
        return "inf" if value > 0 else "-inf" if value < 0 else "nan"
    return value


def failed_as_inf(cost: NDArray[np.float64]) -> NDArray[np.float64]:
    """Costs with NaN (a failed episode's, as rows record it) replaced by +inf (FAILURE_RULE)."""
    return np.where(np.isnan(cost), np.inf, cost)


def improvement(cost: NDArray[np.float64], ref: NDArray[np.float64]) -> NDArray[np.float64]:
    """d = 1 - J / J_ref per (seed, scenario), shape of `cost` (S, K); `ref` (K,); failures (NaN or inf) by
    FAILURE_RULE."""
    c, r = failed_as_inf(cost), np.broadcast_to(failed_as_inf(ref), cost.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 1.0 - c / r
    d = np.where(np.isinf(c) & np.isfinite(r), -np.inf, d)
    d = np.where(np.isinf(r) & np.isfinite(c), 1.0, d)
    return np.where(np.isinf(r) & np.isinf(c), 0.0, d)


def ratio_of_means(cost: NDArray[np.float64], ref: NDArray[np.float64]) -> NDArray[np.float64]:
    """mean J / mean J_ref over the (seed, scenario) entries whose reference succeeded, as a 1-element array
    (rliable's convention); `cost` and `ref` of one shape (S, K); +inf if any such entry failed."""
    c, r = failed_as_inf(cost), failed_as_inf(ref)
    keep = np.isfinite(r)
    if not keep.any():
        return np.array([np.nan])
    return np.array([np.sum(c[keep]) / np.sum(r[keep])])


def iqm(scores: NDArray[np.float64]) -> NDArray[np.float64]:
    """rliable's interquartile mean of all entries, as a 1-element array."""
    from rliable import metrics

    with np.errstate(invalid="ignore"):
        return np.array([metrics.aggregate_iqm(scores)])


def probability_of_improvement(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """P(X > Y) averaged over tasks (columns), runs (rows) of X against runs of Y, ties one half: rliable's
    `metrics.probability_of_improvement` (its Mann-Whitney U statistic, per task), vectorised over tasks so that
    bootstraps stay fast. A test holds it equal to rliable's."""
    greater = (x[:, None, :] > y[None, :, :]).mean(axis=(0, 1))
    ties = (x[:, None, :] == y[None, :, :]).mean(axis=(0, 1))
    return np.array([np.mean(greater + 0.5 * ties)])


@contextlib.contextmanager
def seeded_global_rng(seed: int) -> Iterator[None]:
    """NumPy's global generator seeded for the block (rliable's bootstraps draw from it), then restored."""
    state = np.random.get_state()  # noqa: NPY002 - rliable draws from the global generator
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def _interval(value: NDArray[np.float64], bootstrap: Any, func: Any, reps: int) -> Interval:
    """The point estimate and its percentile interval; a bound that resamples with +inf make NaN (inf - inf in
    the interpolation) is +inf, -inf likewise."""
    with np.errstate(invalid="ignore", divide="ignore"):
        stats = np.sort(bootstrap.apply(func, reps)[:, 0])
    tail = (1.0 - CONFIDENCE) / 2.0
    low, high = (stats[min(len(stats) - 1, int(np.floor(q * len(stats))))] for q in (tail, 1.0 - tail))
    return Interval(float(value[0]), float(low), float(high))


def summarize(cost: NDArray[np.float64], ref: NDArray[np.float64], *, reps: int = 2000,
              seed: int = BOOTSTRAP_SEED) -> MethodSummary:
    """A method's summary from its costs (S seeds, K scenarios; NaN = failed) and the reference's (K,)."""
    from rliable.library import StratifiedBootstrap

    cost, ref = np.asarray(cost, dtype=np.float64), np.asarray(ref, dtype=np.float64)
    S, K = cost.shape
    refs = np.broadcast_to(ref, cost.shape).copy()
    scores = improvement(cost, ref)
    x, y = -failed_as_inf(cost), -failed_as_inf(ref)[None, :]  # higher is better; a failure is -inf
    with seeded_global_rng(seed):
        ratio = _interval(ratio_of_means(cost, refs), StratifiedBootstrap(cost, refs, task_bootstrap=True),
                          ratio_of_means, reps)
        mid = _interval(iqm(scores), StratifiedBootstrap(scores, task_bootstrap=True), iqm, reps)
        ys = np.broadcast_to(y, x.shape).copy()  # the reference's one run beside each seed: resampled as a pair
        poi = _interval(probability_of_improvement(x, y), StratifiedBootstrap(x, ys, task_bootstrap=True),
                        probability_of_improvement, reps)
    wins = float(100 * np.mean(x > y))
    return MethodSummary(S, K, int(np.sum(np.isinf(x))), int(np.sum(np.isinf(y))), ratio, mid, poi, wins)


LAW_COLORS = {"PID": "black", "CT": "tab:blue", "adaptive CT": "tab:green", "MPC": "tab:red",
              "adaptive MPC": "tab:purple"}
"""The colour of a classical method planner+LAW in every figure, by its law's label (mjtraj.rl.LAW_LABELS)."""
OTHER_COLORS = {"(tuned gains)": "0.55", "oracle": "tab:olive"}
"""The colour of a method whose label contains the key: tuned PID gains, the adaptive law's oracle."""


def classical_color(method: str) -> str | None:
    """The fixed colour of a classical method (LAW_COLORS, OTHER_COLORS), None for any other (a policy)."""
    other = next((c for key, c in OTHER_COLORS.items() if key in method), None)
    return other if other is not None else LAW_COLORS.get(method.split("+", 1)[1] if "+" in method else "")


def method_colors(methods: Sequence[str]) -> dict[str, Any]:
    """One colour per method, the same in every figure of a run: classical methods by LAW_COLORS and OTHER_COLORS
    (fixed across runs); each other method (a policy) a colour of tab20 and Dark2 chosen from its name (crc32) and
    moved to the next free one where two would share it, in the order of `methods`."""
    import zlib

    import matplotlib

    palette = [matplotlib.colors.to_hex(c) for name in ("tab20", "Dark2")
               for c in matplotlib.colormaps[name].colors]  # type: ignore[attr-defined]
    fixed = {matplotlib.colors.to_hex(c) for c in (*LAW_COLORS.values(), *OTHER_COLORS.values())}
    free = [c for c in palette if c not in fixed]
    out: dict[str, str] = {}
    for m in methods:
        color = classical_color(m)
        if color is not None:
            out[m] = color
    taken = {matplotlib.colors.to_hex(c) for c in out.values()}
    for m in methods:
        if m in out:
            continue
        k = zlib.crc32(m.encode()) % len(free)
        for step in range(len(free)):
            if free[(k + step) % len(free)] not in taken:
                k = (k + step) % len(free)
                break
        out[m] = free[k]
        taken.add(free[k])
    return out


def profile_figure(scores: dict[str, dict[str, NDArray[np.float64]]], path: Any, *, reference: str,
                   reps: int = 2000, seed: int = BOOTSTRAP_SEED, formats: Sequence[str] = ("png",)) -> Path:
    """rliable's performance profiles, one panel per family: the share of (seed, scenario) episodes whose
    improvement d = 1 - J / J_ref over `reference` exceeds tau, with 95 % bootstrap bands; `scores` family -> method
    -> (S, K). tau spans where the episodes' d lie (their 1st to 99th percentiles, within [-1, 1]); policies are
    dashed; the legend stands beside the panels. Written in each of `formats`; returns the first path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from rliable import library as rly
    from rliable import plot_utils

    from mjtraj.study import save_figure

    families = list(scores)
    methods = list(dict.fromkeys(m for family in families for m in scores[family]))
    colors = method_colors(methods)
    styles = {m: "-" if classical_color(m) is not None else "--" for m in methods}
    fig, axes = plt.subplots(1, len(families), figsize=(4.2 * len(families), 3.6), squeeze=False)
    for ax, family in zip(axes[0], families, strict=True):
        d = np.concatenate([np.ravel(v) for v in scores[family].values()])
        d = d[np.isfinite(d)]
        low, high = (np.percentile(d, [1, 99]) if d.size else (-1.0, 1.0))
        low, high = max(-1.0, float(low)), min(1.0, float(high))
        pad = 0.05 * max(high - low, 1e-3)
        taus = np.linspace(low - pad, high + pad, 61)
        with seeded_global_rng(seed):
            profiles, bands = rly.create_performance_profile(scores[family], taus, reps=reps)
        plot_utils.plot_performance_profiles(profiles, taus, performance_profile_cis=bands, colors=colors,
                                             linestyles=styles, xlabel=r"$\tau$ (improvement $d = 1 - J / J_{ref}$)",
                                             ylabel=r"share of episodes with $d > \tau$", ax=ax,
                                             labelsize="medium", ticklabelsize="small")
        ax.set_title(f"{family}, against {reference}", fontsize="medium")
    handles = [plt.Line2D([], [], color=colors[m], ls=styles[m], lw=2, label=m) for m in methods]
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize="small", frameon=False)
    fig.tight_layout()
    written = save_figure(fig, Path(path), formats, dpi=130, tight=True)
    plt.close(fig)
    return written[0]


def interval_figure(summaries: Mapping[str, Mapping[str, Any]], path: Any, *, reference: str,
                    formats: Sequence[str] = ("png",)) -> Path | None:
    """Interval estimates in rliable's style, one row of panels per family: the IQM of the improvement over
    `reference` and P(improve), each method's point estimate (black tick) and 95 % interval (bar), in the colours of
    `method_colors`; a method absent from a family, or an interval with an infinite end (a failure), is left blank
    there (its tick drawn where finite). `summaries` family -> method -> MethodSummary. Returns the first path, or
    None (nothing written) when the reference is the only method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mjtraj.study import save_figure

    families = list(summaries)
    methods = [m for m in dict.fromkeys(m for f in families for m in summaries[f]) if m != reference]
    if not methods:
        return None
    colors = method_colors(methods)
    fig, axes = plt.subplots(len(families), 2, figsize=(10.5, 0.9 + len(families) * (0.5 + 0.32 * len(methods))),
                             squeeze=False)
    for row, family in enumerate(families):
        for col, (what, field) in enumerate((("IQM improvement", "iqm"),
                                             (f"P(improve over {reference})", "probability_of_improvement"))):
            ax = axes[row, col]
            for y, method in enumerate(methods):
                summary = summaries[family].get(method)
                if summary is None:
                    continue
                interval = getattr(summary, field)
                if np.isfinite(interval.low) and np.isfinite(interval.high):
                    ax.barh(y, interval.high - interval.low, left=interval.low, height=0.6, color=colors[method],
                            alpha=0.75)
                if np.isfinite(interval.value):
                    ax.plot([interval.value] * 2, [y - 0.3, y + 0.3], color="black", linewidth=1.2)
            ax.set_yticks(range(len(methods)))
            ax.set_yticklabels(methods if col == 0 else [], fontsize="small")
            ax.set_title(f"{family}: {what}", fontsize="medium")
            ax.tick_params(axis="x", labelsize="small")
            ax.grid(axis="x", alpha=0.3)
            ax.spines[["top", "right"]].set_visible(False)
    written = save_figure(fig, Path(path), formats, dpi=130, tight=True)
    plt.close(fig)
    return written[0]


@dataclass(frozen=True)
class FloorSummary:
    """One method on one family read against the clairvoyant floor of the reference's reference (`mjtraj.domain.floor`)
    and against the strongest classical method, each paired on the same scenarios, with 95 % bootstrap intervals.

    Attributes:
      ratio_to_floor: mean J / mean floor (1: as good as possible; seeds pooled).
      headroom_closed: (mean J_ref - mean J) / (mean J_ref - mean floor): 0 is the reference, 1 the floor.
      versus_best: mean J / mean J_best, J_best the strongest classical method's on the family (paired).
      beats_best: P(J < J_best), ties one half.
      best: the strongest classical method's name.
    """

    ratio_to_floor: Interval
    headroom_closed: Interval
    versus_best: Interval
    beats_best: Interval
    best: str

    def as_dict(self) -> dict[str, Any]:
        return _json_ready(asdict(self))


def paired_against(cost: NDArray[np.float64], other: NDArray[np.float64], *, reps: int = 2000,
                   seed: int = BOOTSTRAP_SEED) -> tuple[Interval, Interval]:
    """A method's costs (S, K; NaN = failed) against another method's on the same scenarios ((K,) or (S, K)):
    (mean J / mean J_other, P(J < J_other), ties one half), each with its 95 % interval, the bootstrap as in
    `summarize` (scenarios, then seeds; pairs kept): FloorSummary's versus_best and beats_best for any method."""
    from rliable.library import StratifiedBootstrap

    cost = np.asarray(cost, dtype=np.float64)
    others = np.broadcast_to(np.asarray(other, dtype=np.float64), cost.shape).copy()
    x, y = -failed_as_inf(cost), -failed_as_inf(others)
    with seeded_global_rng(seed):
        versus = _interval(ratio_of_means(cost, others), StratifiedBootstrap(cost, others, task_bootstrap=True),
                           ratio_of_means, reps)
        beats = _interval(probability_of_improvement(x, y), StratifiedBootstrap(x, y, task_bootstrap=True),
                          probability_of_improvement, reps)
    return versus, beats


def headroom_closed(cost: NDArray[np.float64], ref: NDArray[np.float64], floor: NDArray[np.float64]
                    ) -> NDArray[np.float64]:
    """(sum J_ref - sum J) / (sum J_ref - sum floor) over the entries whose reference and floor exist, as a 1-element
    array; arrays of one shape (S, K); -inf if any such entry failed."""
    c, r, f = failed_as_inf(cost), failed_as_inf(ref), failed_as_inf(floor)
    keep = np.isfinite(r) & np.isfinite(f)
    if not keep.any():
        return np.array([np.nan])
    gap = np.sum(r[keep]) - np.sum(f[keep])
    with np.errstate(invalid="ignore"):
        return np.array([(np.sum(r[keep]) - np.sum(c[keep])) / gap])


def summarize_floor(cost: NDArray[np.float64], ref: NDArray[np.float64], floor: NDArray[np.float64],
                    best: NDArray[np.float64], best_name: str, *, reps: int = 2000,
                    seed: int = BOOTSTRAP_SEED) -> FloorSummary:
    """A method's FloorSummary from its costs (S, K; NaN = failed), the reference's, the floors and the strongest
    classical method's (K,) each; the bootstrap as in `summarize` (scenarios, then seeds; pairs kept)."""
    from rliable.library import StratifiedBootstrap

    cost = np.asarray(cost, dtype=np.float64)
    refs, floors, bests = (np.broadcast_to(np.asarray(a, dtype=np.float64), cost.shape).copy()
                           for a in (ref, floor, best))
    x, y = -failed_as_inf(cost), -failed_as_inf(bests)
    with seeded_global_rng(seed):
        to_floor = _interval(ratio_of_means(cost, floors), StratifiedBootstrap(cost, floors, task_bootstrap=True),
                             ratio_of_means, reps)
        closed = _interval(headroom_closed(cost, refs, floors),
                           StratifiedBootstrap(cost, refs, floors, task_bootstrap=True), headroom_closed, reps)
        versus = _interval(ratio_of_means(cost, bests), StratifiedBootstrap(cost, bests, task_bootstrap=True),
                           ratio_of_means, reps)
        beats = _interval(probability_of_improvement(x, y), StratifiedBootstrap(x, y, task_bootstrap=True),
                          probability_of_improvement, reps)
    return FloorSummary(to_floor, closed, versus, beats, best_name)
