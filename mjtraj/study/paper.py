"""The paper's published numbers (its Table I), kept beside ours for reference, never as a target.

The paper: see docs/paper.md for the citation.
"""

from __future__ import annotations

PAPER_TABLE = {
    "optimal": {"rms_dtau": 1.893, "int_dtau": 4.535, "rms_err": 2.825e-4, "cost": 3.622},
    "cubic": {"rms_dtau": 2.629, "int_dtau": 6.329, "rms_err": 3.622e-4, "cost": 6.983,
              "dtau_red": 28.35, "cost_red": 48.13},
    "quintic": {"rms_dtau": 3.074, "int_dtau": 7.723, "rms_err": 5.653e-4, "cost": 9.562,
                "dtau_red": 41.29, "cost_red": 62.12},
    "trapezoidal": {"rms_dtau": 3.066, "int_dtau": 6.504, "rms_err": 1.059e-3, "cost": 9.697,
                    "dtau_red": 30.27, "cost_red": 62.64},
}
"""The paper's Table I (docs/paper.md). Its 'dtau Red.' column is the reduction of Int. dtau (it reproduces
from that column, not from RMS dtau)."""
