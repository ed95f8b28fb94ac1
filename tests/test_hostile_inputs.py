"""Hundreds of bad and extreme inputs (tests/hostile.py): every one gets its right outcome, a bad one refused in one
line naming what it got wrong, an extreme one run; none ends in a traceback, none bad is silently accepted.

`python -m pytest tests/test_hostile_inputs.py -s -m slow` prints the table by kind, which docs/cli.md shows.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest
from hostile import BAD, EXTREME, catalogue, run_catalogue, table

DOCS = Path(__file__).resolve().parents[1] / "docs" / "cli.md"


def documented() -> dict[str, tuple[int, ...]]:
    """docs/cli.md's table of the catalogue: kind -> (cases, bad, extreme, refused, ran, tracebacks, accepted)."""
    rows = {}
    for line in DOCS.read_text().splitlines():
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.startswith("| ") and len(cells) == 8 and cells[1].isdigit():
            rows[cells[0]] = tuple(int(c) for c in cells[1:])
    return rows


def test_the_catalogue_is_the_documented_one_and_every_bad_case_says_what_its_refusal_names():
    """Cases per kind, bad and extreme, as docs/cli.md's table says (a case lost from a kind fails here), each
    (kind, label) once, and every bad case with the words its refusal must contain."""
    cases = catalogue()
    rows = documented()
    assert rows.pop("**all**")[:3] == (len(cases), sum(c.expect == BAD for c in cases), 17)
    assert {kind: row[:3] for kind, row in rows.items()} == {
        kind: (sum(c.kind == kind for c in cases), sum(c.kind == kind and c.expect == BAD for c in cases),
               sum(c.kind == kind and c.expect == EXTREME for c in cases)) for kind in dict.fromkeys(c.kind
                                                                                                for c in cases)}
    assert len({(c.kind, c.label) for c in cases}) == len(cases) == 441
    assert all(c.names for c in cases if c.expect == BAD)


@pytest.mark.slow
def test_every_bad_input_is_refused_in_one_line_and_no_input_ends_in_a_traceback(tmp_path):
    outcomes = run_catalogue(catalogue(), tmp_path)
    print("\n" + table(outcomes))
    failures = [f"{o.case.kind} | {o.case.label} | expected {o.case.expect}, naming {o.case.names!r} | {o.result} | "
                f"{o.detail[:300]}" for o in outcomes if not o.ok]
    assert failures == [], "\n".join(failures)
    assert Counter(o.result for o in outcomes) == {"refused": 424, "ran": 17}
    assert table(outcomes).splitlines()[2:] == [line for line in DOCS.read_text().splitlines()
                                                if line.startswith("| ") and line.split("|")[2].strip().isdigit()]
