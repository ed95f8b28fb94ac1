"""The paper's figures 2-7 from a Comparison, as PNG files (matplotlib, imported here only)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mjtraj.core.scoring import step_cost
from mjtraj.domain.comparison import Comparison
from mjtraj.study.frontier import Frontier, FrontierRow

FIGURES = {
    "fig2_planned_acceleration.png": "Planned joint accelerations",
    "fig3_tracking_error.png": "Tracking error",
    "fig4_corrective_torque.png": "Corrective torque",
    "fig5_cumulative_activity.png": "Cumulative corrective activity",
    "fig6_cumulative_cost.png": "Cumulative executed cost",
    "fig7_metrics.png": "Quantitative comparison",
}


def _variant(result: Comparison) -> str:
    """The configuration in plain words, for every figure's caption line: the control law, its feedforward and
    gravity compensation, the score."""
    loop = result.scenario.loop
    accel = "sampled" if loop.ff_accel == "sample" else "step-averaged"
    feedforward = {"inverse": f"inverse-dynamics feedforward at the {accel} reference acceleration",
                   "planned": "the planner's own feedforward", "none": "no feedforward"}.get(loop.feedforward,
                                                                                          loop.feedforward)
    law = {"pid": f"PID with {feedforward}", "computed_torque": "computed torque on the nominal model",
           "adaptive_computed_torque": "adaptive computed torque"}.get(loop.controller, loop.controller)
    gravity = ("gravity compensated in every integrator stage" if loop.gravity_comp == "native"
               else "gravity compensation held over each period")
    weights = "Bryson weights per task" if result.scenario.scoring.rule == "bryson" else "the scenario's weights"
    return (f"Scenario {result.scenario.name!r}; controller, the same for every planner: {law}, {gravity}; score: "
            f"J_exec with {weights}.")


def _caption(fig: object, text: str) -> None:
    """`text` as a caption line under the figure (its axes laid out above it)."""
    import textwrap

    width = int(fig.get_figwidth() * 17)  # type: ignore[attr-defined]  # characters of 7 pt text per inch
    fig.tight_layout(rect=(0, 0.03 + 0.025 * textwrap.fill(text, width).count("\n"), 1, 1))  # type: ignore
    fig.text(0.01, 0.008, textwrap.fill(text, width), fontsize=7, color="0.3", va="bottom")  # type: ignore


def _dwarfed(series: dict[str, np.ndarray]) -> bool:
    """One planner's peak is over 3 times the next largest: the others need a zoomed panel."""
    peaks = sorted((float(np.nanmax(np.abs(v))) for v in series.values()), reverse=True)
    return len(peaks) > 1 and peaks[1] > 0 and peaks[0] > 3 * peaks[1]


PLANNER_ORDER = ("optimal", "cubic", "quintic", "trapezoidal", "scurve", "nonlinear_min_effort",
                 "nonlinear_optimal", "optimal_start", "min_effort")
"""Planners in the order of matplotlib's default colour cycle: one colour per planner in every figure."""


def planner_color(name: str) -> str:
    """The colour of planner `name` in every figure (compare, frontier, audit): C0..C9 by PLANNER_ORDER; another
    planner (a plug-in) gets a colour from its name that does not change between figures."""
    if name in PLANNER_ORDER:
        return f"C{PLANNER_ORDER.index(name)}"
    import zlib

    return f"C{zlib.crc32(name.encode()) % 10}"


FIGURE_FORMATS = ("png", "pdf", "svg")
"""The file formats figures are written in (png by default; pdf and svg for papers, vector graphics)."""


def save_figure(fig: Any, path: Path, formats: Sequence[str] = ("png",), *, dpi: int = 120,
                tight: bool = False) -> list[Path]:
    """Write the matplotlib figure `fig` as `path` in each of `formats` (FIGURE_FORMATS; the suffix replaced), each
    atomically; `tight`: crop to the drawn content (a legend outside the axes kept whole). Returns the paths."""
    from mjtraj.checks import choice
    from mjtraj.files import atomic_path

    written = []
    for kind in formats:
        choice("figure_format", kind, FIGURE_FORMATS)
        target = Path(path).with_suffix(f".{kind}")
        with atomic_path(target) as tmp:
            fig.savefig(tmp, dpi=dpi, format=kind, **({"bbox_inches": "tight"} if tight else {}))
        written.append(target)
    return written


def write_figures(result: Comparison, out: Path, *, dpi: int = 120, formats: Sequence[str] = ("png",)
                  ) -> list[Path]:
    """Write FIGURES into `out` (each atomically), once per format of `formats` (FIGURE_FORMATS); returns the
    paths written.

    Per-period signals held over the period (planned ZOH accelerations, corrective torques) are drawn as steps; when
    one planner dwarfs the others, a second column zooms on the others; the torque figure marks the saturation; the
    bar chart sets the paper's Table I beside ours; every title names the controller variant and the score.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mjtraj.study.paper import PAPER_TABLE

    out.mkdir(parents=True, exist_ok=True)
    names = result.planners
    ro = result.rollout
    t = np.arange(ro.e.shape[1]) * ro.dt
    n = ro.e.shape[2]
    model = result.scenario.model
    joints = tuple(model.joint(j).name or f"joint {j}" for j in range(n))  # the model's own joint names
    colors = {name: planner_color(name) for name in names}
    variant = _variant(result)
    written = []

    def save(fig, filename: str) -> None:  # noqa: ANN001
        written.extend(save_figure(fig, out / filename, formats, dpi=dpi))
        plt.close(fig)

    def per_joint(filename: str, series: dict[str, np.ndarray], ylabel: str, times: np.ndarray, *,
                  steps: bool = False, limit: np.ndarray | None = None) -> None:
        """One panel per joint; `limit` (n,) draws each joint's own saturation dashed."""
        zoom = _dwarfed(series)
        biggest = max(series, key=lambda k: float(np.nanmax(np.abs(series[k]))))
        fig, grid = plt.subplots(n, 2 if zoom else 1, figsize=(11 if zoom else 7, 2.1 * n), sharex=True,
                                 squeeze=False)
        for j in range(n):
            for c in range(grid.shape[1]):
                ax = grid[j, c]
                for name in names:
                    if c == 1 and name == biggest:
                        continue
                    if steps:
                        ax.step(times, series[name][:, j], where="post", label=name, color=colors[name], lw=1.3)
                    else:
                        ax.plot(times, series[name][:, j], label=name, color=colors[name], lw=1.4)
                if limit is not None and c == 0:
                    for sign in (-1, 1):
                        ax.axhline(sign * limit[j], color="k", ls="--", lw=0.8)
                ax.grid(alpha=0.3)
                ax.set_ylabel(f"{joints[j]}\n{ylabel}" if c == 0 else ylabel)
                if j == 0:
                    ax.set_title("all planners" + (" (dashed: each joint's saturation)" if limit is not None else "")
                                 if c == 0
                                 else f"zoom: without {biggest}", fontsize=9)
        grid[0, 0].legend(ncol=len(names), fontsize=7, loc="upper right")
        for c in range(grid.shape[1]):
            grid[-1, c].set_xlabel("time [s]")
        fig.suptitle(f"{FIGURES[filename]} of each planner's execution", fontsize=10)
        _caption(fig, variant)
        save(fig, filename)

    ref_t = result.references[names[0]].t
    per_joint("fig2_planned_acceleration.png", {k: result.references[k].qdd for k in names}, "qdd [rad/s²]", ref_t,
              steps=True)
    per_joint("fig3_tracking_error.png", {k: ro.e[i] for i, k in enumerate(names)}, "e [rad]", t)
    limit = np.asarray(result.scenario.torque_limit, dtype=np.float64)
    per_joint("fig4_corrective_torque.png", {k: ro.dtau[i] for i, k in enumerate(names)}, "Δτ [N m]", t, steps=True,
              limit=limit)

    def cumulative(filename: str, series: dict[str, np.ndarray], ylabel: str) -> None:
        zoom = _dwarfed(series)
        biggest = max(series, key=lambda k: float(np.nanmax(np.abs(series[k]))))
        fig, axes = plt.subplots(1, 2 if zoom else 1, figsize=(11 if zoom else 7, 3.6), squeeze=False)
        for c, ax in enumerate(axes[0]):
            for name in names:
                if c == 1 and name == biggest:
                    continue
                ax.plot(t, series[name], label=name, color=colors[name], lw=1.6)
            ax.set_xlabel("time [s]")
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
            if zoom:
                ax.set_title("all planners" if c == 0 else f"zoom: without {biggest}", fontsize=9)
        fig.suptitle(f"{FIGURES[filename]} of each planner's execution", fontsize=10)
        _caption(fig, variant)
        save(fig, filename)

    cumulative("fig5_cumulative_activity.png",
               {k: np.cumsum(np.abs(ro.dtau[i]).sum(axis=1)) * ro.dt for i, k in enumerate(names)},
               "∫ Σ|Δτ| dt [N m s]")
    tracking, effort = step_cost(ro.e, ro.ed, ro.dtau, result.scenario.Q_exec, result.scenario.R_exec)
    per_step = tracking + effort
    cumulative("fig6_cumulative_cost.png", {k: np.cumsum(per_step[i]) for i, k in enumerate(names)},
               "cumulative J_exec")

    metric_labels = (("rms_dtau", "RMS Δτ [N m]"), ("int_dtau", "Int. Δτ [N m s]"), ("rms_err", "RMS err [rad]"),
                     ("cost", "J_exec"))
    fig, axes = plt.subplots(1, len(metric_labels), figsize=(12, 3.6))
    width = 0.4
    for ax, (key, label) in zip(axes, metric_labels, strict=True):
        x = np.arange(len(names))
        ours = [getattr(result.metrics[name], key) for name in names]
        paper = [PAPER_TABLE.get(name, {}).get(key, np.nan) for name in names]
        ax.bar(x - width / 2, ours, width, color=[colors[nm] for nm in names], label="ours")
        ax.bar(x + width / 2, paper, width, color="none", edgecolor="k", hatch="//", label="paper (Table I)")
        ax.set_yscale("log")
        ax.set_xticks(x, names, rotation=30, fontsize=8)
        ax.set_title(label, fontsize=9)
        ax.grid(axis="y", alpha=0.3, which="both")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{FIGURES['fig7_metrics.png']}: ours beside the paper's Table I (log scale)", fontsize=10)
    _caption(fig, variant)
    save(fig, "fig7_metrics.png")
    return written


def plain_log_ticks(ax: object) -> None:
    """Log axes labelled in plain numbers (3, 4, 6 rather than 3 x 10^0): every major tick, and the minor ticks at
    2, 3 and 5 times a power of ten."""
    from matplotlib import ticker

    def minor(value: float, _: int) -> str:
        mantissa = value / 10 ** np.floor(np.log10(value)) if value > 0 else 0.0
        return f"{value:g}" if round(mantissa, 6) in (2.0, 3.0, 5.0) else ""

    for axis in (ax.xaxis, ax.yaxis):  # type: ignore[attr-defined]
        axis.set_major_formatter(ticker.FuncFormatter(lambda value, _: f"{value:g}"))
        axis.set_minor_formatter(ticker.FuncFormatter(minor))


LABEL_OFFSETS = ((6, 4), (6, -12), (-12, 10), (8, 14), (8, -22), (-70, 4), (-70, -12), (-40, 20), (-40, -24))
"""Offsets (points) `place_labels` tries for a label, in turn."""


def place_labels(ax: object, labels: Sequence[tuple[int, float, float, str]], color: str) -> None:
    """Annotate each (rank, x, y, text) of `labels` in the order given at the first of LABEL_OFFSETS where it
    overlaps no label placed before it and stays inside the axes (with a leader line when it stands off); a
    label with no free place is left out (the curve's other labels give its neighbourhood)."""
    fig = ax.figure  # type: ignore[attr-defined]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)  # type: ignore[attr-defined]
    placed: list[Any] = []
    for _, x, y, text in labels:
        for dx, dy in LABEL_OFFSETS:
            far = abs(dx) > 10 or abs(dy) > 12
            note = ax.annotate(text, (x, y), textcoords="offset points", xytext=(dx, dy), fontsize=7,  # type: ignore
                               color=color, arrowprops={"arrowstyle": "-", "lw": 0.5, "color": color} if far else None)
            box = note.get_window_extent(renderer)
            inside = frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1
            if inside and not any(box.overlaps(other) for other in placed):
                placed.append(box.expanded(1.04, 1.15))
                break
            note.remove()


def frontier_figure(result: Frontier, path: Path, *, dpi: int = 120,
                    points: dict[str, tuple[float, float]] | None = None,
                    formats: Sequence[str] = ("png",)) -> Path | None:
    """Corrective effort (RMS dtau) against tracking error (RMS error), log-log: the optimal planner's curve over
    alpha for each split, labelled by alpha, every other planner as a point, and `points` (label -> (RMS dtau N m,
    RMS error rad)) as stars. Written atomically in each of `formats`; returns the first path, or None (nothing
    written) when no execution succeeded."""
    drawable = [(r.metrics["rms_dtau"], r.metrics["rms_err"]) for r in result.rows] + list((points or {}).values())
    if not any(np.isfinite(x) and np.isfinite(y) and x > 0 and y > 0 for x, y in drawable):
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt


    s = result.setting
    fig, ax = plt.subplots(figsize=(7.5, 5.4))
    color = planner_color("optimal")  # every split in the optimal planner's colour, told apart by line style
    labels = _optimal_curves(ax, result, color)
    for r in (row for row in result.rows if row.planner != "optimal"):
        ax.plot(r.metrics["rms_dtau"], r.metrics["rms_err"], "s", ms=8, color=planner_color(r.planner),
                label=r.planner)
    for k, (label, (effort, error)) in enumerate((points or {}).items()):
        ax.plot(effort, error, "*", ms=12, color="k", alpha=1.0 - 0.3 * k, label=label)
    _frontier_axes(ax, s)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    place_labels(ax, sorted(labels), color)
    where = "the scenario's task" if s["task"] == "scenario" else f"{s['scenarios']} {s['task']} scenarios"
    import textwrap

    fig.text(0.01, 0.012, textwrap.fill(f"Q = α Q_bryson, R fixed, on {where}; score: {s['score']}; controller: the "
                                        "scenario's (identical for every planner); squares: the other planners", 130),
             fontsize=7, color="0.3")
    written = save_figure(fig, path, formats, dpi=dpi)
    plt.close(fig)
    return written[0]


def _optimal_curves(ax: Any, result: Frontier, color: Any) -> list[tuple[int, float, float, str]]:
    """Draw the optimal planner's curve over alpha for each split (one line style each); returns the labels to
    place as (rank, x, y, text) (`_alpha_label`)."""
    optimal = [r for r in result.rows if r.planner == "optimal"]
    labels: list[tuple[int, float, float, str]] = []
    styles = ("o-", "^--", "s:", "d-.")
    for k, split in enumerate(dict.fromkeys(r.split for r in optimal)):
        curve = [r for r in optimal if r.split == split and np.isfinite(r.metrics["rms_dtau"])]
        x = [r.metrics["rms_dtau"] for r in curve]
        y = [r.metrics["rms_err"] for r in curve]
        ax.plot(x, y, styles[k % len(styles)], ms=3, lw=1.2, color=color, label=f"optimal, split {split:g}")
        best = min(range(len(curve)), key=lambda i: curve[i].metrics["cost"]) if curve else -1
        for i, r in enumerate(curve):
            label = _alpha_label(r, i == best)
            if label is not None:
                labels.append((label[0], x[i], y[i], label[1]))
    return labels


def _alpha_label(row: FrontierRow, best: bool) -> tuple[int, str] | None:
    """A curve point's label as (rank, text), or None: alpha 0, the decades from 1e-3 and the least J_exec (`best`)
    are labelled, ranked best first, then alpha 0 and 1 (Bryson), then the decades."""
    alpha = row.alpha
    assert alpha is not None
    decade = alpha > 0 and abs(np.log10(alpha) - round(np.log10(alpha))) < 1e-9
    if not (alpha == 0.0 or (decade and alpha >= 1e-3) or best):
        return None
    text = f"α={alpha:.2g}" + (" (least J_exec)" if best else " (Bryson)" if alpha == 1 else "")
    rank = 0 if best else 1 if alpha in (0.0, 1.0) else 2
    return rank, text


def _frontier_axes(ax: Any, setting: dict[str, Any]) -> None:
    """The frontier's log-log axes: ticks, labels (medians over a family), grid, legend and title."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_log_ticks(ax)
    ax.set_xlabel("corrective effort: RMS Δτ [N m]" + (" (median)" if setting["task"] != "scenario" else ""))
    ax.set_ylabel("tracking error: RMS e [rad]" + (" (median)" if setting["task"] != "scenario" else ""))
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title("Tracking error against corrective effort as the optimal planner's weight α varies", fontsize=10)
