"""The learning curve of a training run: a CSV row per validation point, and its plot."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mjtraj.study import append_rows, numeric, read_rows, save_figure

COLUMNS = ("timesteps", "wall_s", "episodes", "train_return_mean", "train_diverged", "val_cost_mean",
           "val_cost_median", "val_rms_err_mean", "val_diverged", "pid_cost_mean", "pid_rms_err_mean")
"""timesteps: env steps so far; train_*: the training episodes that ended since the previous row (their mean return
-J_exec on the stochastic policy, and how many diverged); val_*: the deterministic policy on the validation tasks
(J_exec and RMS tracking error means over those that did not diverge); pid_*: the planner + PID alone on them."""


class CurveFile:
    """learning_curve.csv, appended row by row and fsynced (a crashed run keeps its curve so far)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        path.open("x").close()  # never over another run's curve
        append_rows(path, list(COLUMNS), [dict(zip(COLUMNS, COLUMNS, strict=True))])

    @classmethod
    def resumed(cls, path: Path, rows: int) -> CurveFile:
        """The curve of a resumed run: its header and first `rows` points kept, later ones (written after the resume
        point, and recomputed now) dropped."""
        from mjtraj.files import write_text_atomic

        lines = path.read_text().splitlines(keepends=True)
        write_text_atomic(path, "".join(lines[: 1 + rows]))
        curve = cls.__new__(cls)
        curve.path = path
        return curve

    def append(self, row: dict[str, Any]) -> None:
        """One validation point (COLUMNS -> value; floats as Python floats)."""
        append_rows(self.path, list(COLUMNS), [row])


def plot_curve(csv_path: Path, out: Path, *, title: str, formats: Sequence[str] = ("png",)) -> Path:
    """learning_curve.png: validation J_exec of the policy against planner + PID, the training return, and how
    many episodes diverged (a diverged episode has no J_exec: a gap in the upper panels). Written in each of
    `formats` (png, pdf, svg); returns the first path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read_rows(csv_path)
    col = {c: np.array([numeric(r[c]) for r in rows]) for c in COLUMNS}
    t = col["timesteps"]
    fig, (top, middle, bottom) = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True,
                                              gridspec_kw={"height_ratios": [3, 2, 1.3]})
    top.plot(t, col["val_cost_mean"], "o-", label="policy (deterministic), mean J_exec of the non-diverged")
    top.plot(t, col["val_cost_median"], ".:", color="C0", alpha=0.6, label="policy, median J_exec")
    top.axhline(col["pid_cost_mean"][0], color="k", ls="--", label="planner + PID alone, mean J_exec")
    top.set_yscale("log")
    top.set_ylabel("validation J_exec")
    top.legend(fontsize=8)
    top.set_title(textwrap.fill(title, 85), fontsize=9)  # a long run description wraps, not cut off
    train = np.isfinite(col["train_return_mean"])
    middle.plot(t[train], -col["train_return_mean"][train], "o-", color="C1",
                label="training episodes (stochastic policy), mean J_exec = -return")
    middle.set_yscale("log")
    middle.set_ylabel("training J_exec")
    middle.legend(fontsize=8)
    bottom.plot(t, col["train_diverged"], "o-", color="C1", label="training episodes since the previous point")
    bottom.plot(t, col["val_diverged"], "s-", color="C0", label="validation episodes")
    bottom.set_ylabel("diverged")
    bottom.set_xlabel("environment steps")
    bottom.legend(fontsize=8)
    return _saved(fig, out, formats)


def plot_batched_curve(csv_path: Path, out: Path, *, title: str, formats: Sequence[str] = ("png",)) -> Path:
    """learning_curve.png of a batched run (`mjtraj.rl.batched`): each family's validation mean J_exec over the law
    alone's on the same tasks (1: the law; below: better; protocol v2: J_settle over the episodes both came to rest
    on) and the worst family's, which picks best.pt (v2: after the fewest missed episodes), against env steps; below,
    the training advantage over the law. Written in each of `formats`; returns the first path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = read_rows(csv_path)
    families = [c.removesuffix("_ratio") for c in rows[0] if c.endswith("_ratio") and c != "worst_ratio"]
    t = np.array([numeric(r["timesteps"]) for r in rows])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
    for family in families:
        top.plot(t, [numeric(r[f"{family}_ratio"]) for r in rows], "o-", ms=3, label=family)
    worst = np.array([numeric(r["worst_ratio"]) for r in rows])
    v2 = "missed" in rows[0]  # protocol v2: the fewest missed episodes first, then the worst family
    top.plot(t, worst, "k--", lw=1, label="worst family" + (" (after missed episodes, picks best.pt)" if v2 else
                                                           " (picks best.pt)"))
    missed = np.array([numeric(r["missed"]) for r in rows]) if v2 else np.zeros(len(rows))
    best = int(np.lexsort((worst, missed))[0]) if v2 else int(np.argmin(worst))
    top.plot(t[best], worst[best], "k*", ms=12, label=f"best.pt, at {t[best]:,.0f} steps"
             + (f" ({missed[best]:.0f} missed)" if v2 else ""))
    top.axhline(1.0, color="0.5", lw=0.8)
    top.set_ylabel(f"validation {'J_settle' if v2 else 'J_exec'} / the law alone's")
    top.ticklabel_format(axis="y", useOffset=False)  # ratios near 1 read as themselves, not as "+1" and 1e-4 steps
    top.legend(fontsize=8)
    top.set_title(textwrap.fill(title, 85), fontsize=9)
    bottom.plot(t, [numeric(r["train_advantage_mean"]) for r in rows], "o-", ms=3, color="C1",
                label=f"training episodes: mean advantage over the law (J_law - {'J_settle' if v2 else 'J_exec'})")
    bottom.axhline(0.0, color="0.5", lw=0.8)
    bottom.set_ylabel("advantage")
    bottom.set_xlabel("environment steps")
    bottom.legend(fontsize=8)
    return _saved(fig, out, formats)


def _saved(fig: Any, out: Path, formats: Sequence[str]) -> Path:
    """Lay `fig` out, write it in each of `formats` beside `out` and close it; the first path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    written = save_figure(fig, out, formats, dpi=120)
    plt.close(fig)
    return written[0]
