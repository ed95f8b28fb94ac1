"""The floors of a sweep family's scenarios, one record each (`mjtraj floor`): the starting laws' J_exec on a
planner's reference and the clairvoyant floor of that execution (`mjtraj.domain.floor`), drawn and scored as sweeps
draw and score them."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from mjtraj.core.model import JointInfo
from mjtraj.core.scoring import Scoring
from mjtraj.core.settle import window_steps, with_window
from mjtraj.domain.families import draw_scenario, perturbed_plant
from mjtraj.domain.floor import ORACLE, STARTS, Floor, floor_of
from mjtraj.domain.pipeline import Job, one_line
from mjtraj.exceptions import MjtrajError

if TYPE_CHECKING:
    from mjtraj.domain.scenario import Scenario


def family_floors(scenario: Scenario, family: str, *, seed: int, scenarios: Sequence[int], planner: str = "cubic",
                  starts: Sequence[str] = STARTS, every_start: bool = False, settle: float = 0.0
                  ) -> Iterator[dict[str, Any]]:
    """One record per scenario of `family` (drawn and scored as sweeps draw and score it, seed `seed`: Bryson's
    weights on each task): the starting laws' J_exec on `planner`'s reference and the floor of that execution. A
    scenario whose planning or floor fails gets its error in 'status' and the run goes on.

    Args:
      scenario: the base scenario (model, controller), as sweeps take it.
      scenarios: the scenario indices.
      every_start: solve from every start (`clairvoyant_floor`).
      settle: the settle window, s (protocol v2: each episode and its floor run this long after the motion, scored
        by J_settle; records gain end_speed, and on the mismatch plants floor_without_LAW for each starting law).
    """
    model = scenario.model
    plant = (perturbed_plant(model, scenario.model_path, scenario.model_torque_limit) if family == "mismatch"
             else None)
    limit = JointInfo.of(model).torque_limit
    config = dataclasses.replace(scenario.loop, delay=0)
    window = window_steps(settle, scenario.task.dt)
    for index in scenarios:
        drawn = draw_scenario(family, seed, index, model, scenario.task.dt)
        move = float(np.max(np.abs(drawn.task.displacement)))
        record: dict[str, Any] = {"family": family, "scenario": index, "planner": planner}
        try:
            reference = scenario.planner(planner).plan(drawn.task, model)
            reference, rest = with_window(drawn.task, reference, window)
            job = Job(reference, Scoring().weights(drawn.task, limit), drawn.perturbation, settle=rest)  # as sweeps do
            found = floor_of(model, config, job, plant=plant, starts=starts, displacement=move,
                             every_start=every_start)
        except MjtrajError as e:
            yield {**record, "status": one_line(e)}
            continue
        best = min(found.controllers.values())
        yield {**record, "status": "ok", **{f"J_{law}": cost for law, cost in found.controllers.items()},
               "floor": found.cost, "floor_over_best": found.cost / best, "start": found.start,
               "start_spread": _spread(found.starts), "iterations": found.iterations, "converged": found.converged,
               "terminal_err": found.terminal_err, "goal_radius": found.goal_radius, "seconds": found.seconds,
               **(_settled(found, family) if window else {})}


def _settled(found: Floor, family: str) -> dict[str, float]:
    """A protocol-v2 record's end speed and, on the mismatch plants, each starting law's floor without it."""
    out = {"end_speed": found.end_speed}
    if family == "mismatch":
        out.update({f"floor_without_{law}": found.without(law) for law in found.controllers if law != ORACLE})
    return out


def _spread(costs: Mapping[str, float]) -> float:
    """(largest - least) / least over the starts that reached the goal; NaN with fewer than two."""
    finite = [c for c in costs.values() if np.isfinite(c)]
    return (max(finite) - min(finite)) / min(finite) if len(finite) > 1 else float("nan")
