"""Text tables: our Table I in the paper's columns, and the paper's own numbers for reference."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from mjtraj.core.arm import held_joints, integrator_note
from mjtraj.core.controller import CT_RULE
from mjtraj.core.gains import GAIN_RULE
from mjtraj.core.metrics import GOAL_TOLERANCE, METRIC_UNITS
from mjtraj.domain.comparison import Comparison
from mjtraj.study.frontier import TABLE_METRICS, Frontier
from mjtraj.study.paper import PAPER_TABLE

HEADER = ("Planner", "RMS dtau", "Int. dtau", "RMS Err.", "Cost", "dtau Red.", "Cost Red.", "RMS fb", "Peak dtau",
          "Term. err", "Goal")
UNITS = ("", "N m", "N m s", "rad", "-", "%", "%", "N m", "N m", "rad", "")
GOAL_WORDS = {"ok": "reached", "missed_goal": "MISSED"}
"""The Goal column: the goal rule's verdict on each planner's execution (`--` where it diverged)."""


def _fmt(value: float, kind: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "--"
    if kind == "err":
        return f"{value:.3e}"
    if kind == "pct":
        return f"{value:.2f}"
    return f"{value:.3f}"


def _grid(rows: list[tuple[str, ...]]) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(cell.ljust(w) if i == 0 else cell.rjust(w)
                       for i, (cell, w) in enumerate(zip(r, widths, strict=True))) for r in rows]
    lines.insert(2, "-" * len(lines[0]))
    return "\n".join(lines)


def table_rows(result: Comparison) -> list[tuple[str, ...]]:
    """Our Table I rows (strings), header and units first."""
    rows: list[tuple[str, ...]] = [HEADER, UNITS]
    for name in result.planners:
        m = result.metrics[name]
        red = name != "optimal"
        rows.append((name, _fmt(m.rms_dtau, "num"), _fmt(m.int_dtau, "num"), _fmt(m.rms_err, "err"),
                     _fmt(m.cost, "num"), _fmt(result.reduction(name, "int_dtau") if red else float("nan"), "pct"),
                     _fmt(result.reduction(name, "cost") if red else float("nan"), "pct"),
                     _fmt(m.rms_fb, "num"), _fmt(m.peak_dtau, "num"), _fmt(m.terminal_err, "err"),
                     GOAL_WORDS.get(result.outcomes[name].status, "--") if name in result.outcomes else "--"))
    return rows


def paper_rows() -> list[tuple[str, ...]]:
    """The paper's Table I rows (strings), in the same columns; RMS fb and peak are not published."""
    rows: list[tuple[str, ...]] = [HEADER, UNITS]
    for name, p in PAPER_TABLE.items():
        rows.append((name, _fmt(p["rms_dtau"], "num"), _fmt(p["int_dtau"], "num"), _fmt(p["rms_err"], "err"),
                     _fmt(p["cost"], "num"), _fmt(p.get("dtau_red", float("nan")), "pct"),
                     _fmt(p.get("cost_red", float("nan")), "pct"), "n/a", "n/a", "n/a", "n/a"))
    return rows


def format_report(result: Comparison) -> str:
    """The text `mjtraj compare` prints: settings, our table, the paper's table, and the facts behind them."""
    s = result.scenario
    g = s.loop.gains
    fmt = lambda a: "[" + ", ".join(f"{x:.6g}" for x in a) + "]"  # noqa: E731
    diverged = [n for i, n in enumerate(result.planners) if result.rollout.diverged_step[i] >= 0]
    limit = f"{s.torque_limit[0]:g}" if np.all(s.torque_limit == s.torque_limit[0]) else fmt(s.torque_limit)
    arm = "MuJoCo UR5 3-DoF" if s.model_path is None else f"MuJoCo arm {Path(s.model_path).name}, {s.task.n} joints"
    lines = [
        f"Scenario '{s.name}' ({s.source or 'in memory'})" + ("" if s.model_path is None else
                                                               f", model {s.model_path}"),
        *([f"  held fixed (not planned): {held}"] if (held := held_joints(s.model)) else []),
        *([f"  integrator: {note}"] if (note := integrator_note(s.model)) else []),
        f"  q0 = {fmt(s.task.q0)} rad, qg = {fmt(s.task.qg)} rad, T = {s.task.duration:g} s, dt = {s.task.dt:g} s, "
        f"N = {s.task.steps}",
        f"  controller = {s.loop.controller}, feedforward = {s.loop.feedforward}, ff_accel = {s.loop.ff_accel}, "
        f"gravity_comp = {s.loop.gravity_comp}, anti_windup = {s.loop.anti_windup}, substeps = {s.loop.substeps}",
        *([f"  kp = {fmt(g.kp)}, ki = {fmt(g.ki)}, kd = {fmt(g.kd)}", f"  gain rule: {GAIN_RULE}"]
          if s.loop.controller == "pid" else [f"  computed-torque gain rule: {CT_RULE}"]
          if s.loop.controller in ("computed_torque", "adaptive_computed_torque") else []),
        f"  closed-loop spectral radius (frozen-time, linearised): at rest on every reference pose "
        f"{result.stability['at_rest']:.4f}, along the moving references {result.stability['moving']:.4f}"
        if s.loop.controller == "pid" else "  closed-loop spectral radius: checked for pid only",
        f"  Q_exec = diag{fmt(s.Q_exec)}, R_exec = diag{fmt(s.R_exec)}",
        "",
        f"Table I (ours: {arm}, identical {'FF+PID' if s.loop.controller == 'pid' else s.loop.controller}, "
        f"|dtau| <= {limit} N m; dtau Red. = reduction of Int. dtau)",
        _grid(table_rows(result)),
    ]
    if diverged:
        lines.append(f"  diverged (metrics NaN): {', '.join(diverged)}")
    move = float(np.max(np.abs(s.task.displacement)))
    missed = [n for n in result.planners if n in result.outcomes and result.outcomes[n].status == "missed_goal"]
    worst = max((result.metrics[n].terminal_err for n in result.planners), default=float("nan"))
    if missed:
        lines.append(f"  MISSED THE GOAL ({len(missed)} of {len(result.planners)}: terminal error above "
                     f"{GOAL_TOLERANCE:g} x the move of {move:.3g} rad, a failure by the goal rule): "
                     + ", ".join(f"{n} ({result.metrics[n].terminal_err:.3g} rad)" for n in missed))
    else:
        lines.append(f"  every planner reached its goal (largest terminal error {worst:.3g} rad, within "
                     f"{GOAL_TOLERANCE:g} x the move of {move:.3g} rad)")
    for name, reason in result.failed.items():
        lines.append(f"  not planned: {name}: {reason}")
    if "optimal" in result.references:
        info = result.references["optimal"].info
        lines.append(f"  optimal plan: {info['solver']} {info['status']}, {info['iterations']} iterations, "
                     f"terminal residual {info['terminal_residual']:.2e}, plan time {1e3 * info['plan_time']:.1f} ms")
    if s.model_path is None:  # the paper's table describes the UR5, not a user's arm
        lines += ["", "Table I as published (the paper, docs/paper.md; for reference only, never a target)",
                  _grid(paper_rows())]
    return "\n".join(lines)


def results_csv(result: Comparison) -> str:
    """results.csv: one row per planner, every metric and the reduction columns."""
    out = io.StringIO()
    metric_names = list(result.metrics[result.planners[0]].as_dict())
    writer = csv.writer(out)
    writer.writerow(["planner", *metric_names, "int_dtau_red_pct", "cost_red_pct"])
    for name in result.planners:
        m = result.metrics[name].as_dict()
        writer.writerow([name, *(repr(m[k]) for k in metric_names), repr(result.reduction(name, "int_dtau")),
                         repr(result.reduction(name, "cost"))])
    return out.getvalue()


def format_frontier(result: Frontier) -> str:
    """The frontier table: each alpha's metrics and their ratio to cubic (medians and 95 % intervals on a family)."""
    s = result.setting
    family = s["task"] != "scenario"
    head = ["planner", "alpha", "split"]
    for metric in TABLE_METRICS:
        head += [LABELS[metric], "/ cubic"]
    head.append("failed")
    units = ["", "", ""] + [u for metric in TABLE_METRICS for u in (METRIC_UNITS[metric], "")] + [""]
    rows: list[tuple[str, ...]] = [tuple(head), tuple(units)]
    for row in result.rows:
        cells = [row.planner, "" if row.alpha is None else f"{row.alpha:.3g}",
                 "" if row.split is None else f"{row.split:g}"]
        for metric in TABLE_METRICS:
            r = row.ratio[metric]
            cells.append(_fmt(row.metrics[metric], "err" if metric == "rms_err" else "num"))
            cells.append("--" if not np.isfinite(r.value) else f"{r.value:.3f}" if not family else
                         f"{r.value:.3f} [{r.low:.3f}, {r.high:.3f}]")
        cells.append(str(row.failed))
        rows.append(tuple(cells))
    where = (f"the scenario's task ({s['scenario']})" if not family else
             f"{s['scenarios']} {s['task']} scenarios (seed {s['seed']}); medians, [95 % bootstrap interval]")
    failures = [f"  failed: {r.planner}" + (f" (alpha {r.alpha:.3g}, split {r.split:g})" if r.alpha is not None
                                             else "") + f": {reason}"
                for r in result.rows for reason in r.reasons[:3]]
    return "\n".join([f"Weight frontier of the optimal planner: Q = alpha * Q_bryson (position/velocity split), "
                      f"R = R_bryson, on {where}; score: {s['score']}; controller: the scenario's",
                      _grid(rows), *failures])


LABELS = {"rms_dtau": "RMS dtau", "int_dtau": "Int. dtau", "rms_err": "RMS Err.", "peak_dtau": "Peak dtau",
          "cost": "J_exec"}


def write_series(result: Comparison, path: Path) -> Path:
    """results.npz: every planner's time series, to re-plot without re-running. Arrays: planners (B,), t (N+1,) s,
    q_ref (B, N+1, n) rad, and per period q, e (rad), tau_ff, tau_fb, dtau (N m), shapes (B, N, n); row b is
    planners[b]. Written atomically."""
    from mjtraj.files import atomic_path

    ro = result.rollout
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, planners=np.array(result.planners), t=result.references[result.planners[0]].t,
                 q_ref=np.stack([result.references[name].q for name in result.planners]), q=ro.q, e=ro.e,
                 tau_ff=ro.tau_ff, tau_fb=ro.tau_fb, dtau=ro.dtau)
    return path
