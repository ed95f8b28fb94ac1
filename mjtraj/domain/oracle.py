"""The adaptive law's oracle: started at each plant's true payload, damping and friction (what the nominal model
leaves out, but for the links' mass and inertia errors), so that a table can show how close a deployable
controller comes to knowing the plant. Labelled an oracle wherever it appears; never deployable."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.domain.families import Perturbation

ORACLE_LABEL = "cubic+adaptive CT from the true parameters (oracle)"
"""The oracle's method label in `mjtraj rl eval`'s tables."""


def true_parameters(plants: Sequence[Perturbation | None], n: int) -> NDArray[np.float64]:
    """The adaptive law's theta of each plant, shape (len(plants), 1 + 2n): payload kg, damping N m s/rad and
    dry friction N m per joint; zeros for the nominal plant (None)."""
    rows = [np.zeros(1 + 2 * n) if p is None else np.concatenate([[p.payload], p.damping, p.friction])
            for p in plants]
    return np.array(rows).reshape(len(plants), 1 + 2 * n)


class TrueParameters:
    """An actor (mjtraj.domain.pipeline.Actor) that adds no torque and, as each batch starts, sets the adaptive
    law's estimate to the plants' true parameters (the law then adapts from there as usual)."""

    action_mode = "residual"

    def begin(self, loop: Any, references: Sequence[Any], plants: Sequence[Perturbation | None] = ()) -> None:
        """Set the estimate of every simulation of `loop` (a ClosedLoop on the adaptive law) to its plant's."""
        n = loop.model.nv
        loop.set_law_state(true_parameters(list(plants) or [None] * loop.nsim, n))
        self._zero = np.zeros((loop.nsim, n))

    def act(self, loop: Any) -> NDArray[np.float64]:
        """No torque of its own, shape (B, n)."""
        return self._zero
