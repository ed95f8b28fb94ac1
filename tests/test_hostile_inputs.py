"""Hundreds of bad and extreme inputs (tests/hostile.py): none ends in a traceback, none bad is silently accepted.

`python -m pytest tests/test_hostile_inputs.py -s -m slow` prints the table by kind.
"""

from __future__ import annotations

import pytest
from hostile import EXTREME, catalogue, run_catalogue, table


@pytest.mark.slow
def test_every_bad_input_is_refused_in_one_line_and_no_input_ends_in_a_traceback(tmp_path):
    cases = catalogue()
    assert len(cases) >= 300
    outcomes = run_catalogue(cases, tmp_path)
    print("\n" + table(outcomes))
    failures = [f"{o.case.kind} | {o.case.label} | {o.result} | {o.detail[:300]}" for o in outcomes if not o.ok]
    assert failures == [], "\n".join(failures)
    assert any(o.case.expect == EXTREME and o.result == "ran" for o in outcomes)  # extreme inputs do run
