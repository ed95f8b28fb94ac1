"""`mjtraj audit`: the paper's six claims checked against sweep files, written as AUDIT.md with figures.

`reading` reads the sweep files into per-condition arrays (`SweepData`); `rules` states the verdict rule
(`VERDICT_RULE`) and checks each claim in each condition; `sections` computes the sections of numbers (summary,
conclusions, frontier, floors, effort, figures, definitions); `formatting` writes ratios, the verdict and claim
tables and the fixed text. `write_audit` puts them together.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

from mjtraj.study.audit.formatting import NO_PAIRS, claim_tables, header, paper_note, verdict_table
from mjtraj.study.audit.reading import (
    FAILED_NAN,
    NUMERIC,
    READ_CHUNK,
    READ_COLUMNS,
    Condition,
    SweepData,
    complete_units,
    unit_counts,
    weights_label,
    whole_units,
)
from mjtraj.study.audit.rules import (
    CLASSICAL,
    LARGE_MOTION,
    MIN_SCENARIOS,
    VERDICT_RULE,
    below,
    check_claims,
)
from mjtraj.study.audit.sections import (
    BOUND,
    DISPLACEMENT_BINS,
    DURATION_BINS,
    METRIC_LABELS,
    conclusions,
    definitions,
    floors_section,
    frontier_section,
    min_effort,
    ratio_figures,
    summary_section,
    where_it_pays,
)

__all__ = ["BOUND", "CLASSICAL", "DISPLACEMENT_BINS", "DURATION_BINS", "FAILED_NAN", "LARGE_MOTION", "METRIC_LABELS",
           "MIN_SCENARIOS", "NO_PAIRS", "NUMERIC", "READ_CHUNK", "READ_COLUMNS", "VERDICT_RULE", "Condition",
           "SweepData", "below", "complete_units", "unit_counts", "weights_label", "whole_units", "write_audit"]


def write_audit(paths: Sequence[str | os.PathLike[str]], out: str | os.PathLike[str], *, figures: bool = True,
                partial: bool = False, tasks: bool = True, progress: Callable[[str], None] | None = None,
                figure_formats: Sequence[str] = ("png",)) -> str:
    """Write the audit of the sweep files `paths` to `out` (Markdown) and its figures beside it; return the text.

    An incomplete sweep file is refused unless `partial`, which audits its complete units and says what is missing.
    With `tasks`, each file's planners, controller variants and scenario file are also run on the paper task and its
    reverse (conditions of their own), and the weight frontier on the paper task is computed and drawn.
    `progress(stage)` is called as each stage begins. Each figure is written in every format of `figure_formats`
    (png, pdf, svg); the Markdown shows the first.
    """
    def stage(name: str) -> None:
        if progress is not None:
            progress(name)

    data = SweepData(paths, partial=partial, tasks=tasks, progress=progress)
    stage("the claims")
    out = Path(out)
    checks = check_claims(data)
    summary = summary_section(data)
    lines = header(data, paths) + verdict_table(data, checks)
    lines += ["", "Verdict rule: " + " ".join(VERDICT_RULE.split()), ""]
    lines += claim_tables(checks)
    lines += conclusions(data)
    if tasks:
        stage("the weight frontier")
        lines += frontier_section(data, out, paths, figures=figures, formats=figure_formats)
    lines += where_it_pays(data)
    lines += min_effort(data)
    if tasks:
        stage("the floors of the fixed motions")
        lines += floors_section(data)
    lines += summary
    if figures:
        stage("the figures")
        lines += ratio_figures(data, out, figure_formats)
    lines += definitions(data)
    lines += paper_note()
    text = "\n".join(lines) + "\n"
    from mjtraj.files import write_text_atomic

    write_text_atomic(out, text)
    return text
