"""The paper's figures 2-7 from a Comparison, as PNG files (matplotlib, imported here only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mjtraj.core.scoring import step_cost
from mjtraj.study.comparison import Comparison
from mjtraj.study.frontier import Frontier

FIGURES = {
    "fig2_planned_acceleration.png": "Planned joint accelerations",
    "fig3_tracking_error.png": "Tracking error",
    "fig4_corrective_torque.png": "Corrective torque",
    "fig5_cumulative_activity.png": "Cumulative corrective activity",
    "fig6_cumulative_cost.png": "Cumulative executed cost",
    "fig7_metrics.png": "Quantitative comparison",
}


def write_figures(result: Comparison, out: Path, *, dpi: int = 120) -> list[Path]:
    """Write FIGURES into `out`; returns the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    names = result.planners
    ro = result.rollout
    s = result.scenario
    t = np.arange(ro.e.shape[1]) * ro.dt
    n = ro.e.shape[2]
    joints = ("shoulder_pan", "shoulder_lift", "elbow")[:n] if n <= 3 else tuple(f"joint {i}" for i in range(n))
    colors = {name: f"C{i}" for i, name in enumerate(names)}
    written = []

    def per_joint(filename: str, series: dict[str, np.ndarray], ylabel: str, times: np.ndarray) -> None:
        fig, grid = plt.subplots(n, 1, figsize=(7, 2.1 * n), sharex=True, squeeze=False)
        axes = grid[:, 0]
        for j, ax in enumerate(axes):
            for name in names:
                ax.plot(times, series[name][:, j], label=name, color=colors[name], lw=1.4)
            ax.set_ylabel(f"{joints[j]}\n{ylabel}")
            ax.grid(alpha=0.3)
        axes[0].legend(ncol=len(names), fontsize=8, loc="upper right")
        axes[-1].set_xlabel("time [s]")
        fig.suptitle(FIGURES[filename])
        fig.tight_layout()
        fig.savefig(out / filename, dpi=dpi)
        plt.close(fig)
        written.append(out / filename)

    ref_t = result.references[names[0]].t
    per_joint("fig2_planned_acceleration.png", {k: result.references[k].qdd for k in names}, "qdd [rad/s²]", ref_t)
    per_joint("fig3_tracking_error.png", {k: ro.e[i] for i, k in enumerate(names)}, "e [rad]", t)
    per_joint("fig4_corrective_torque.png", {k: ro.dtau[i] for i, k in enumerate(names)}, "Δτ [N m]", t)

    def cumulative(filename: str, series: dict[str, np.ndarray], ylabel: str) -> None:
        fig, ax = plt.subplots(figsize=(7, 3.6))
        for name in names:
            ax.plot(t, series[name], label=name, color=colors[name], lw=1.6)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        ax.set_title(FIGURES[filename])
        fig.tight_layout()
        fig.savefig(out / filename, dpi=dpi)
        plt.close(fig)
        written.append(out / filename)

    cumulative("fig5_cumulative_activity.png",
               {k: np.cumsum(np.abs(ro.dtau[i]).sum(axis=1)) * ro.dt for i, k in enumerate(names)},
               "∫ Σ|Δτ| dt [N m s]")
    tracking, effort = step_cost(ro.e, ro.ed, ro.dtau, s.Q_exec, s.R_exec)
    per_step = tracking + effort
    cumulative("fig6_cumulative_cost.png", {k: np.cumsum(per_step[i]) for i, k in enumerate(names)},
               "cumulative J_exec")

    metric_labels = (("rms_dtau", "RMS Δτ [N m]"), ("int_dtau", "Int. Δτ [N m s]"), ("rms_err", "RMS err [rad]"),
                     ("cost", "J_exec"))
    fig, axes = plt.subplots(1, len(metric_labels), figsize=(11, 3.2))
    for ax, (key, label) in zip(axes, metric_labels, strict=True):
        values = [getattr(result.metrics[name], key) for name in names]
        ax.bar(range(len(names)), values, color=[colors[nm] for nm in names])
        ax.set_xticks(range(len(names)), names, rotation=30, fontsize=8)
        ax.set_title(label, fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(FIGURES["fig7_metrics.png"])
    fig.tight_layout()
    fig.savefig(out / "fig7_metrics.png", dpi=dpi)
    plt.close(fig)
    written.append(out / "fig7_metrics.png")
    return written


def frontier_figure(result: Frontier, path: Path, *, dpi: int = 120) -> Path:
    """Corrective effort (RMS dtau) against tracking error (RMS error), log-log: the optimal planner's curve over
    alpha for each split, labelled by alpha, and every other planner as a point. Written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mjtraj.files import atomic_path

    s = result.setting
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    optimal = [r for r in result.rows if r.planner == "optimal"]
    for k, split in enumerate(dict.fromkeys(r.split for r in optimal)):
        curve = [r for r in optimal if r.split == split and np.isfinite(r.metrics["rms_dtau"])]
        x = [r.metrics["rms_dtau"] for r in curve]
        y = [r.metrics["rms_err"] for r in curve]
        ax.plot(x, y, "o-", ms=3, lw=1.2, color=f"C{k}", label=f"optimal, split {split:g}")
        best = min(range(len(curve)), key=lambda i: curve[i].metrics["cost"]) if curve else -1
        for i, r in enumerate(curve):
            assert r.alpha is not None
            decade = r.alpha > 0 and abs(np.log10(r.alpha) - round(np.log10(r.alpha))) < 1e-9
            if r.alpha == 0.0 or (decade and r.alpha >= 1e-3) or i == best:
                text = f"α={r.alpha:.2g}" + (" (least J_exec)" if i == best else " (Bryson)" if r.alpha == 1 else "")
                ax.annotate(text, (x[i], y[i]), textcoords="offset points", fontsize=7, color=f"C{k}",
                            xytext=(6, -10) if i == best else (-14, 8) if r.alpha == 0 else (5, 3))
    for k, r in enumerate(row for row in result.rows if row.planner != "optimal"):
        ax.plot(r.metrics["rms_dtau"], r.metrics["rms_err"], "s", ms=8, color=f"C{k + 5}", label=r.planner)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("corrective effort: RMS Δτ [N m]" + (" (median)" if s["task"] != "scenario" else ""))
    ax.set_ylabel("tracking error: RMS e [rad]" + (" (median)" if s["task"] != "scenario" else ""))
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    where = "the scenario's task" if s["task"] == "scenario" else f"{s['scenarios']} {s['task']} scenarios"
    ax.set_title(f"Weight frontier on {where}; score: {s['score']}; controller: the scenario's FF + PID",
                 fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi)
    plt.close(fig)
    return path
