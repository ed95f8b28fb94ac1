"""The text of results cells: what every results file (CSV file or SQLite store) writes for a value."""

from __future__ import annotations

import math
from typing import Any

from mjtraj.versions import PROVENANCE

VERSION_COLUMNS = PROVENANCE
"""Columns that hold the rows' provenance (`mjtraj.versions.provenance`: versions, BLAS, CPU, commit), compared
verbatim."""


def cell_text(value: Any) -> str:
    """A value as the text results files store: floats as repr() (the same bits read back), NaN as 'nan'."""
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    return str(value)


def setting_cells(settings: dict[str, Any]) -> dict[str, str]:
    """The setting and provenance columns as the text every row carries (versions verbatim: '3.10' is not 3.1)."""
    return {name: str(value) if name in VERSION_COLUMNS else cell_text(value) for name, value in settings.items()}
