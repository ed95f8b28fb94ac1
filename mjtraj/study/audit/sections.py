"""The audit's sections of numbers: the per-condition summary, the conclusions, the weight frontier, where
control-aware planning pays, the minimum-effort reference and the effort left, the floors of the fixed motions, the
ratio figures and the paper's columns against our definitions."""

from __future__ import annotations

import dataclasses
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mjtraj.core.metrics import GOAL_TOLERANCE
from mjtraj.exceptions import MjtrajError
from mjtraj.study.audit.formatting import fmt_ratio
from mjtraj.study.audit.reading import Condition, SweepData, weights_label
from mjtraj.study.audit.rules import CLASSICAL, MIN_SCENARIOS
from mjtraj.study.fixed_tasks import TASKS
from mjtraj.study.paper import PAPER_TABLE
from mjtraj.study.stats import cvar, paired_ratio
from mjtraj.study.sweep import SHIPPED_CONFIG, SweepSettings


def summary_section(data: SweepData) -> list[str]:
    """The per-condition summary: what it counts (failures, missed goals among them), then its table."""
    summary = summary_table(data)
    return ["## Per-condition summary", "", "Mean and median per planner; CVaR(90 %) of the RMS tracking error "
            "(the mean of the worst 10 % of scenarios); failures are rows whose status is not ok. Missed goals "
            "(status missed_goal, on every family: the execution ended farther from its goal than "
            f"{GOAL_TOLERANCE:g} x the task's largest joint displacement) are failures: they keep their metrics in "
            "the sweep file but leave every paired ratio and verdict above, as a diverged row does, so each "
            "verdict reads only executions that reached their goals.", ""] + summary


def summary_table(data: SweepData) -> list[str]:
    """Per condition and planner: the rows ok and failed, and the means, medians and CVaR of the main metrics."""
    out = ["| condition | planner | n ok | failures | of them missed goals | RMS err mean / median (rad) | "
           "CVaR90 RMS err | Int. dtau mean / median (N m s) | RMS dtau mean | J_exec mean / median |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for c in data.conditions:
        for p in data.planners:
            if not data.has(c, p):
                continue
            e, i, r, j = (data.values(c, p, m) for m in ("rms_err", "int_dtau", "rms_dtau", "cost"))
            ok = int(np.sum(np.isfinite(e)))
            failed, missed = data.failures(c, p), data.missed_goals(c, p)
            out.append(f"| {c} | {p} | {ok} | {failed} | {missed} | {np.nanmean(e):.4g} / {np.nanmedian(e):.4g} | "
                       f"{cvar(e, 0.9):.4g} | {np.nanmean(i):.4g} / {np.nanmedian(i):.4g} | {np.nanmean(r):.4g} | "
                       f"{np.nanmean(j):.4g} / {np.nanmedian(j):.4g} |" if ok else
                       f"| {c} | {p} | 0 | {failed} | {missed} | - | - | - | - | - |")
    return out + [""]


def conclusions(data: SweepData) -> list[str]:
    """Plain sentences from the numbers: per set of weights and family (first controller variant), the optimal
    planner's J_exec and tracking error against the cubic's."""
    lines = ["## Conclusions", "",
             "The optimal planner against the cubic (the minimum-effort reference of a constant-inertia arm), in "
             "the first controller variant of each family, as mean ratios over paired scenarios [95 % interval]:",
             ""]
    seen: set[tuple[str, str]] = set()
    for c in data.conditions:
        if (c.weights, c.family) in seen or not (data.has(c, "optimal") and data.has(c, "cubic")):
            continue
        seen.add((c.weights, c.family))
        cost = paired_ratio(data.values(c, "optimal", "cost"), data.values(c, "cubic", "cost"))
        err = paired_ratio(data.values(c, "optimal", "rms_err"), data.values(c, "cubic", "rms_err"))
        if cost.count < MIN_SCENARIOS:
            continue
        verdict = ("lower than" if cost.high < 1.0 else "higher than" if cost.low > 1.0 else
                   "not distinguishable from")
        weights = c.weights or "these weights"
        lines.append(f"- {weights}, {c.family} motions ({cost.count} scenarios): J_exec {verdict} the cubic's, "
                     f"ratio {fmt_ratio(cost)}, won in {100 * (1 - cost.win_rate):.0f} % of them; RMS tracking "
                     f"error ratio {fmt_ratio(err)}.")
    return lines + [""] if len(lines) > 4 else []


def frontier_section(data: SweepData, out: Path, paths: Sequence[str | os.PathLike[str]], *, figures: bool,
                      formats: Sequence[str] = ("png",)) -> list[str]:
    """The optimal planner's weight frontier on the paper task of the first file's scenario, in its first controller
    variant: the table, the figure, and where each audited set of weights puts the optimal planner on that task."""
    from mjtraj.study.frontier import frontier
    from mjtraj.study.report import format_frontier

    head = ["## The weight frontier on the paper task", ""]
    try:
        settings = SweepSettings.from_record(data.first)
    except MjtrajError as e:
        return head + [f"(not computed: {e})", ""]
    ff, gc = settings.ff_accel[0], settings.gravity_comp[0]
    scenario = dataclasses.replace(settings.base, loop=settings.loop_config(ff, gc, mismatch=False))
    result = frontier(scenario)
    points = {}
    for label in data.weights:
        c = Condition(TASKS[0], ff, gc, label)
        if c in data.conditions and data.has(c, "optimal"):
            points[f"optimal, {label or 'these weights'}"] = (float(data.values(c, "optimal", "rms_dtau")[0]),
                                                              float(data.values(c, "optimal", "rms_err")[0]))
    config = data.first.get("config", "")
    lines = head + [
             "The optimal planner for Q = alpha Q_bryson (R = R_bryson fixed), alpha from 0 to 100, on the paper task "
             f"of {weights_label(config) or 'the first file'}, controller ff_accel={ff}, gravity_comp={gc}, scored "
             "by the scenario's fixed J_exec; every other planner as one point. The same table is printed by "
             "`mjtraj frontier`" + ("" if config == SHIPPED_CONFIG else f" --config {config}") + "." + (
                 " Each audited set of weights puts the optimal planner here on this task (RMS dtau N m, RMS error "
                 "rad): " + "; ".join(f"{k}: {v[0]:.4g}, {v[1]:.4g}" for k, v in points.items()) + "."
                 if points else ""), "",
             "```", format_frontier(result), "```", ""]
    if figures:
        from mjtraj.study.plots import frontier_figure

        folder = out.parent / (out.stem + "_figures")
        folder.mkdir(parents=True, exist_ok=True)
        shown = frontier_figure(result, folder / "frontier_paper_task.png", points=points, formats=formats)
        if shown is not None:
            lines += [f"![the weight frontier on the paper task]({folder.name}/{shown.name})", ""]
    return lines


DISPLACEMENT_BINS = (0.0, 0.5, 1.0, 1.5)
"""rad: the largest joint displacement's bins of the "where it pays" table."""
DURATION_BINS = (0.0, 0.7, 0.85, 1.0, 2.0)
"""s: the duration bins (the aggressive family spans 0.5 to 1 s; nominal moves take 2 s)."""


def floors_section(data: SweepData) -> list[str]:
    """Each planner's reference on the paper task and its reverse: its execution under the first file's controller
    beside the clairvoyant floor of that reference (`mjtraj.study.fixed_tasks.task_floors`)."""
    from mjtraj.study.fixed_tasks import task_floors

    rows, why = task_floors(data.first)
    lines = ["## How well each reference can be executed: the floor", "",
             "The clairvoyant floor of a reference is the least J_exec any controller can score executing it on the "
             "nominal plant within the saturation, reaching the goal (docs/floor.md): how well the reference can be "
             "executed at best. Beside it, the first file's controller's execution (its first controller variant, "
             "native gravity compensation) on the paper task and its reverse.", ""]
    if not rows:
        return lines + [f"Not computed: {why}.", ""]
    lines += ["| motion | planner | J_exec of its execution | floor of its reference | J / floor |",
              "|---|---|---|---|---|"]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['task']} | {r['planner']} | not computed: {r['error']} | - | - |")
            continue
        cost, floor = float(r["cost"]), float(r["floor"])  # type: ignore[arg-type]
        note = "" if r["status"] == "ok" else f" ({r['status']})"
        lines.append(f"| {r['task']} | {r['planner']} | {cost:.4g}{note} | {floor:.4g} | {cost / floor:.3f} |")
    return lines + [""]


def where_it_pays(data: SweepData) -> list[str]:
    """J_exec of cubic over the optimal planner's, per condition and bin of displacement and duration: above 1 (the
    whole interval) is where control-aware planning pays."""
    lines = ["## Where control-aware planning pays", "",
             "Paired ratio mean(J_exec cubic) / mean(J_exec optimal) [95 % bootstrap interval] and the share of "
             "scenarios the optimal planner wins, per bin of the largest joint displacement and of the duration. "
             f"Above 1 is where it pays; bins with fewer than {MIN_SCENARIOS} scenarios are left out.", "",
             "| condition | bin | scenarios | cubic / optimal | optimal wins |", "|---|---|---|---|---|"]
    rows = 0
    for c in data.conditions:
        if not (data.has(c, "optimal") and data.has(c, "cubic")):
            continue
        move, duration = data.values(c, "optimal", "max_displacement"), data.values(c, "optimal", "duration")
        for label, values, edges, unit in (("max abs(dq)", move, DISPLACEMENT_BINS, "rad"),
                                           ("T", duration, DURATION_BINS, "s")):
            for low, high in zip(edges[:-1], edges[1:], strict=True):
                mask = (values > low) & (values <= high)
                if mask.sum() < MIN_SCENARIOS:
                    continue
                r = paired_ratio(data.values(c, "cubic", "cost")[mask], data.values(c, "optimal", "cost")[mask])
                if r.count < MIN_SCENARIOS:
                    continue
                lines.append(f"| {c} | {label} in ({low:g}, {high:g}] {unit} | {r.count} | {fmt_ratio(r)} | "
                             f"{100 * r.win_rate:.0f} % |")
                rows += 1
    return lines + ([] if rows else ["| (not measured: optimal and cubic are both needed) | | | | |"]) + [""]


def min_effort(data: SweepData) -> list[str]:
    """Why the cubic is the minimum-effort reference of a constant-inertia arm, how far the optimal planner's effort
    lies from its own minimum-effort variant, then the effort left on the table (`effort_left`)."""
    lines = [
        "## The minimum-effort reference", "",
        "For a gravity-compensated arm with constant inertia D (so C = 0), the plant is D q'' = u. A reference "
        "q(t) tracked exactly needs u = D q''(t), so its effort is E = integral of u^T R u dt = integral of "
        "q''^T (D R D) q'' dt. Rest to rest (q(0) = q0, q(T) = qg, q'(0) = q'(T) = 0), the Euler-Lagrange "
        "equation of this integrand is (D R D) q'''' = 0: every joint follows a cubic polynomial, and the "
        "boundary conditions make it the cubic planner's q0 + dq (3 s^2 - 2 s^3), whatever D and R are. Its "
        "effort is 12 dq^T (D R D) dq / T^3; the quintic's is 120/7 = 17.14 (1.43 times, so 1.195 times the RMS "
        "torque), the trapezoid's with V = 1.5 dq/T is 13.5 (1.125 times, 1.061 in RMS). So on such an arm "
        "claim 5 is a theorem, and no planner that moves along the straight joint path needs less L2 "
        "feedforward effort than the cubic.", "",
        "That bound holds only under its assumptions: constant inertia, effort measured as the L2 norm of the "
        "torque, and the straight joint-space path. The UR5's inertia varies with the pose and couples the joints, "
        "so a reference that leaves the straight path (folding the elbow to cut the inertia the big joints move) "
        "can need less torque than the cubic; the true bound is the minimum-effort reference of the nonlinear "
        "dynamics within the joint ranges and speed limits: the `nonlinear_min_effort` planner (below, when the sweep "
        "ran it). Nor is L1 effort (Int. dtau) minimised by the cubic.", "",
        "The paper's optimal planner minimises a different objective: it adds the state weight Q, which pays for "
        "being away from the goal at every step. That pulls the motion forward and costs effort. With Q = 0 its "
        "QP is the discrete minimum-effort problem of its own linear model (the `min_effort` variant): for the "
        "constant-inertia linear model that is the cubic's torque held over each period, the zero-order-held "
        "cubic, which tracks with the same effort and less error than the sampled cubic (see `mjtraj frontier` at "
        "alpha = 0). How far the optimal planner's effort lies from it:", ""]
    rows = ["| condition | planned RMS u: optimal/min_effort | executed RMS dtau: optimal/min_effort | executed "
            "RMS dtau: cubic/min_effort |", "|---|---|---|---|"]
    for c in data.conditions:
        if data.has(c, "min_effort") and data.has(c, "optimal"):
            plan = paired_ratio(data.values(c, "optimal", "plan_effort"), data.values(c, "min_effort", "plan_effort"))
            run = paired_ratio(data.values(c, "optimal", "rms_dtau"), data.values(c, "min_effort", "rms_dtau"))
            cub = paired_ratio(data.values(c, "cubic", "rms_dtau"), data.values(c, "min_effort", "rms_dtau")) \
                if data.has(c, "cubic") else None
            rows.append(f"| {c} | {fmt_ratio(plan)} | {fmt_ratio(run)} | {fmt_ratio(cub) if cub else '-'} |")
    lines += (rows if len(rows) > 2 else ["(not measured: add `min_effort` to the sweep's planners)"]) + [""]
    return lines + effort_left(data)


BOUND = "nonlinear_min_effort"
"""The planner whose executed effort is the study's effort bound."""


def effort_left(data: SweepData) -> list[str]:
    """Every planner's executed RMS dtau over the nonlinear effort bound's, paired by scenario."""
    lines = ["## Effort left on the table", "",
             f"`{BOUND}` is the least corrective effort with which the nominal nonlinear arm makes each move within "
             "its joint ranges, the pi rad/s speed limit and the torque bound (the paper's objective with Q = 0, "
             "solved on the MuJoCo model itself). Each cell is mean(planner's executed RMS dtau) / mean(the "
             f"bound's), paired by scenario, with a 95 % bootstrap interval: 1 means no effort left to save.", ""]
    names = (*CLASSICAL, "scurve", "optimal", "min_effort", "nonlinear_optimal")
    rows = []
    for c in data.conditions:
        if not data.has(c, BOUND):
            continue
        bound = data.values(c, BOUND, "rms_dtau")
        present = [p for p in names if data.has(c, p)]
        rows.append((c, present, [paired_ratio(data.values(c, p, "rms_dtau"), bound) for p in present],
                     int(np.sum(np.isfinite(bound)))))
    if not rows:
        return lines[:2] + [f"(not measured: add `{BOUND}` to the sweep's planners; it plans in about 0.07 s: "
                            "1,000 nominal scenarios take about a minute on two cores)", ""]
    for c, present, ratios, count in rows:
        lines += [f"{c} ({count} scenarios with a bound):", "", "| " + " | ".join(present) + " |",
                  "|" + "---|" * len(present), "| " + " | ".join(fmt_ratio(r) for r in ratios) + " |", ""]
    return lines


METRIC_LABELS = {"rms_err": "RMS tracking error", "int_dtau": "integral of |corrective torque|",
                 "cost": "executed cost J_exec"}
"""Plain names of the metrics the audit's figures draw."""


def ratio_figures(data: SweepData, out: Path, formats: Sequence[str] = ("png",)) -> list[str]:
    """Per condition (not the fixed motions), each planner's ratios to the optimal planner's rms_err, int_dtau and
    cost as box plots, written beside `out` (stale ones removed); the Markdown that shows them."""
    import matplotlib

    from mjtraj.study.plots import planner_color, save_figure

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = out.parent / (out.stem + "_figures")
    folder.mkdir(parents=True, exist_ok=True)
    written: set[str] = set()
    lines = ["## Figures", ""]
    for c in data.conditions:
        if not data.has(c, "optimal") or c.family in TASKS:  # one motion: no distribution to draw
            continue
        present = [p for p in data.planners if p != "optimal" and data.has(c, p)]
        fig, axes = plt.subplots(1, 3, figsize=(12, 4.2))
        for ax, metric in zip(axes, ("rms_err", "int_dtau", "cost"), strict=True):
            ratios = []
            for p in present:
                r = data.values(c, p, metric) / data.values(c, "optimal", metric)
                ratios.append(r[np.isfinite(r) & (r > 0)])
            boxes = ax.boxplot(ratios, showfliers=False, patch_artist=True)
            for box, p in zip(boxes["boxes"], present, strict=True):
                box.set_facecolor(planner_color(p))
                box.set_alpha(0.6)
            ax.set_xticks(range(1, len(present) + 1), present, rotation=30, fontsize=9)
            ax.axhline(1.0, color="k", lw=0.8, ls="--")
            ax.set_yscale("log")
            ax.set_ylabel(f"{METRIC_LABELS[metric]}, planner / optimal (log)", fontsize=9)
            ax.set_title(METRIC_LABELS[metric], fontsize=10)
        fig.suptitle(str(c), fontsize=9)
        fig.tight_layout()
        slug = re.sub(r"[^A-Za-z0-9]+", "_", c.weights).strip("_")
        name = f"ratios_{slug + '_' if slug else ''}{c.family}_{c.ff_accel}_{c.gravity_comp}.png"
        paths = save_figure(fig, folder / name, formats, dpi=150)
        plt.close(fig)
        written.update(path.name for path in paths)
        lines.append(f"![{c}]({folder.name}/{paths[0].name})")
    for stale in folder.glob("ratios_*"):  # the figures of an earlier audit into the same file
        if stale.name not in written:
            stale.unlink()
    return lines + [""]


def definitions(data: SweepData) -> list[str]:
    """How the paper's columns read against our metric definitions, with the arithmetic."""
    p = PAPER_TABLE
    o = p["optimal"]
    lines = [
        "## The paper's columns and our definitions", "",
        "Our metrics (docs/design.md): `rms_dtau` is the RMS over every joint and period; `rms_dtau_norm` the RMS over "
        "periods of the torque vector's norm (sqrt(n) times `rms_dtau`); `rms_tau_total` the RMS of the total torque "
        "G(q) + dtau; `int_dtau` the sum over joints and periods of |dtau| dt, the paper's J_dtau.", "",
        "| paper column | reads as | arithmetic from its Table I |", "|---|---|---|"]
    for name in ("cubic", "quintic", "trapezoidal"):
        row = p[name]
        from_int = 100 * (row["int_dtau"] - o["int_dtau"]) / row["int_dtau"]
        from_rms = 100 * (row["rms_dtau"] - o["rms_dtau"]) / row["rms_dtau"]
        lines.append(f"| dtau Red. ({name}) = {row['dtau_red']} % | the reduction of Int. dtau (L1), not of RMS dtau | "
                     f"Int.: 100 ({row['int_dtau']} - {o['int_dtau']}) / {row['int_dtau']} = {from_int:.2f} %; RMS: "
                     f"{from_rms:.2f} % |")
    for name, stated in (("cubic", 22), ("quintic", 50), ("trapezoidal", 73)):
        row = p[name]
        as_reduction = 100 * (row["rms_err"] - o["rms_err"]) / row["rms_err"]
        as_increase = 100 * (row["rms_err"] - o["rms_err"]) / o["rms_err"]
        lines.append(f"| RMS error \"increased by approximately {stated} %\" ({name}) | a reduction relative to "
                     f"{name}, worded as an increase | 100 ({row['rms_err']:.4g} - {o['rms_err']:.4g}) / "
                     f"{row['rms_err']:.4g} = {as_reduction:.1f} %; as an increase over optimal: {as_increase:.1f} % |")
    paper_ratio = [p[k]["int_dtau"] / (2.0 * 3 * p[k]["rms_dtau"])
                   for k in ("optimal", "cubic", "quintic", "trapezoidal")]
    lines += ["", "Int. dtau / (T n RMS) is the mean |dtau| over the RMS: near 0.8 for these smooth torques when the "
              "RMS is over every joint and period. The paper's Table I gives "
              f"{min(paper_ratio):.2f} to {max(paper_ratio):.2f} (T = 2 s, n = 3). The same ratio with the norm-based "
              "RMS (`rms_dtau_norm`, sqrt(n) times larger) comes close to the paper's range, which suggests its RMS "
              "dtau is of the torque vector's norm. Ours, per condition (median over scenarios):",
              "", "| condition | planner | Int. dtau / (T n rms_dtau) | Int. dtau / (T n rms_dtau_norm) |",
              "|---|---|---|---|"]
    for c in data.conditions:
        for planner in data.planners:
            if not data.has(c, planner):
                continue
            integral, rms_value = data.values(c, planner, "int_dtau"), data.values(c, planner, "rms_dtau")
            norm, T = data.values(c, planner, "rms_dtau_norm"), data.values(c, planner, "duration")
            ours = integral / (T * 3 * rms_value)
            by_norm = integral / (T * 3 * norm)
            if np.isfinite(ours).any():
                lines.append(f"| {c} | {planner} | {np.nanmedian(ours):.3f} | {np.nanmedian(by_norm):.3f} |")
    return lines + [""]


