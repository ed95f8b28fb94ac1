"""The clairvoyant floor of a scenario (`mjtraj.core.floor`), computed on its true plant, started from the executed
torques of the classical control laws, and checked by replaying its torques through the one closed loop.

The floor is what no controller can beat on that execution: the least J_exec over corrective torques within the
saturation, on the plant the scenario really runs (payload, link scales, damping and friction included), among
executions that reach the goal by the benchmark's goal rule (GOAL_TOLERANCE of the move). Its value is the replay's
J_exec (the pipeline's own metrics of the torques, applied in the env's torque mode), not the solver's.

A job with a settle window (protocol v2, `mjtraj.core.settle`) gets protocol v2's floor: the least J_settle over the
whole episode among executions at rest at the goal when the window ends (`mjtraj.core.floor.AtRest`). On a perturbed
plant every start is then solved, so that each law can be read against the floor found without its own execution
(`Floor.without`): a law is not measured against a refinement of itself.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.core.closed_loop import ClosedLoop, LoopConfig
from mjtraj.core.floor import DEFAULT_SETTINGS, AtRest, FloorSettings, clairvoyant_floor
from mjtraj.core.model import JointInfo
from mjtraj.core.reference import Reference
from mjtraj.core.settle import SETTLE_SPEED
from mjtraj.domain.families import Perturbation, plant_fields
from mjtraj.domain.oracle import TrueParameters
from mjtraj.domain.pipeline import GOAL_TOLERANCE, Job, Outcome, execute_batch, goal_checked
from mjtraj.exceptions import InvalidInputError, MjtrajError

ORACLE = "oracle"
"""The start named so is the adaptive law started from the plant's true parameters (`mjtraj.domain.oracle`), run on
perturbed jobs only (on the nominal plant it is the adaptive law)."""
STARTS = ("pid", "computed_torque", "adaptive_computed_torque", "mpc", "adaptive_mpc", ORACLE)
"""The control laws whose executed torques start the floor's solves (each one's execution of the same job). The
solve starts from the least of them that reached the goal and accepts only decreases, so the floor is never above
any of these laws' scores: every control law of the benchmark's table is among them, so on the mismatch plants,
where the solves stop in local minima and the floor is an upper estimate, no law of the table scores below it (with
the four classical laws alone `adaptive_mpc` and the oracle did, on 2 of 200 scenarios each)."""
REPLAY_TOLERANCE = 1e-6
"""The replay's J_exec and the solver's agree to this relative difference (the same steps; MuJoCo's warm start of
a friction-loss constraint may differ in the last bits)."""


@dataclass(frozen=True)
class Floor:
    """One execution's floor.

    Attributes:
      cost: J_exec of the floor's torques replayed through the closed loop (the floor's value).
      solver_cost: J_exec by the solver's own rollout.
      terminal_err: the replay's |q_ref,N - q_N|, rad; goal_radius: the goal rule's bound on it, rad (protocol v2:
        the largest joint's end error and the settling band).
      start: the start the best solve came from; starts: each start's cost (inf: it did not reach the goal).
      controllers: J_exec of each starting law's own execution (the starts' sources).
      iterations, converged: the best solve's Gauss-Newton iterations and whether it converged.
      seconds: the solve's wall time, s (the starting executions and the replay not included).
      torques: the applied corrective torques, (N, n), N m.
      end_speed: protocol v2: the replay's largest joint speed at the window's end, rad/s (NaN in v1).
    """

    cost: float
    solver_cost: float
    terminal_err: float
    goal_radius: float
    start: str
    starts: Mapping[str, float]
    controllers: Mapping[str, float]
    iterations: int
    converged: bool
    seconds: float
    torques: NDArray[np.float64]
    end_speed: float = float("nan")

    def without(self, law: str) -> float:
        """The least of the starts' results other than `law`'s (inf if none reached the goal; NaN where only the
        best-ranked start was solved): the floor as found without that law's own execution."""
        others = [cost for name, cost in self.starts.items() if name != law]
        return min(others, default=float("inf"))

    def as_dict(self) -> dict[str, object]:
        """JSON-ready, without the torques."""
        out = dataclasses.asdict(self)
        out.pop("torques")
        out["starts"] = dict(self.starts)
        out["controllers"] = dict(self.controllers)
        return out


class Replay:
    """An Actor that applies given corrective torques (the env's torque mode), (B, N, n) N m. With a one-period
    actuation delay the command of period k is the torque the plant is to receive in period k + 1."""

    action_mode = "torque"

    def __init__(self, torques: NDArray[np.float64], *, delay: int = 0) -> None:
        self.torques = np.asarray(torques, dtype=np.float64)
        self.delay = delay

    def begin(self, loop: ClosedLoop, references: Sequence[Reference],
              plants: Sequence[Perturbation | None] = ()) -> None:
        """Nothing to prepare: the torques are given."""

    def act(self, loop: ClosedLoop) -> NDArray[np.float64]:
        k = loop.periods + self.delay
        N = self.torques.shape[1]
        rows = np.arange(self.torques.shape[0])
        out = self.torques[rows, np.minimum(k, N - 1)]
        return np.where((k < N)[:, None], out, 0.0)  # type: ignore[no-any-return]


def true_plant(plant: mujoco.MjModel, perturbation: Perturbation) -> mujoco.MjModel:
    """A copy of the perturbed `plant` model (`perturbed_plant`) with `perturbation`'s fields set: the scenario's
    true plant as one MjModel."""
    out = copy.copy(plant)
    for name, values in plant_fields(plant, [perturbation]).items():
        getattr(out, name)[:] = values[0]
    mujoco.mj_setConst(out, mujoco.MjData(out))
    return out


def floor_of(model: mujoco.MjModel, config: LoopConfig, job: Job, *, plant: mujoco.MjModel | None = None,
             starts: Sequence[str] = STARTS, displacement: float | None = None, every_start: bool = False,
             settings: FloorSettings = DEFAULT_SETTINGS) -> Floor:
    """The floor of executing `job` (its reference, weights, plant perturbation; noise does not reach a torque
    sequence) under `config`'s saturation, delay and integrator.

    Args:
      model: the nominal model; plant: the perturbed plant model (`perturbed_plant`) when the job is perturbed.
      starts: the control laws whose executions start the solves.
      displacement: the task's largest joint displacement, rad, for the goal rule (default: the reference's).
      every_start: solve from every start, not only the best-ranked one (`clairvoyant_floor`).
      settings: the solver's tunables (`mjtraj.core.floor.FloorSettings`).

    Raises:
      InvalidInputError: a configuration the floor does not model (zoh gravity compensation, substeps), or no start.
      SolverError: no start reached the goal.
      MjtrajError: the replay does not reproduce the solver's cost or misses the goal (a defect).
    """
    found = floors_of(model, config, [job], plant=plant, starts=starts,
                      displacements=None if displacement is None else [displacement], every_start=every_start,
                      settings=settings)[0]
    if isinstance(found, MjtrajError):
        raise found
    return found


def floors_of(model: mujoco.MjModel, config: LoopConfig, jobs: Sequence[Job], *, plant: mujoco.MjModel | None = None,
              starts: Sequence[str] = STARTS, displacements: Sequence[float] | None = None,
              every_start: bool = False, settings: FloorSettings = DEFAULT_SETTINGS) -> list[Floor | MjtrajError]:
    """`floor_of` of each of `jobs` (all perturbed or all nominal), each start law executing them as batches of one
    length (as sweeps execute): the floor, or the error that refused it, per job in order.

    Raises:
      InvalidInputError: a configuration the floor does not model, or no start (for every job at once).
    """
    if config.gravity_comp != "native" or config.substeps != 1:
        raise InvalidInputError(f"config: the floor models native gravity compensation at one integrator step per "
                                f"period; got gravity_comp={config.gravity_comp!r}, substeps={config.substeps}")
    if not starts:
        raise InvalidInputError("starts: expected at least one control law, got none")
    moves = [_move(job.reference) for job in jobs] if displacements is None else list(displacements)
    executed: list[dict[str, NDArray[np.float64]]] = [{} for _ in jobs]
    controllers: list[dict[str, float]] = [{} for _ in jobs]
    groups: dict[int, list[int]] = {}
    for i, job in enumerate(jobs):
        groups.setdefault(job.reference.steps, []).append(i)
    for law in starts:
        law_config = dataclasses.replace(config, controller="adaptive_computed_torque" if law == ORACLE else law)
        for group in groups.values():
            ids = [i for i in group if law != ORACLE or jobs[i].perturbation is not None]
            if not ids:
                continue
            rollout, outcomes = execute_batch(model, law_config, [jobs[i] for i in ids], plant=plant,
                                              actor=TrueParameters() if law == ORACLE else None)
            for b, (i, result) in enumerate(zip(ids, outcomes, strict=True)):
                if result.status in ("ok", "not_settled"):  # the torques the plant received (after a delay, if any)
                    executed[i][law] = rollout.dtau[b]
                controllers[i][law] = (float(result.metrics.get("cost", np.inf)) if result.status != "not_settled"
                                       else np.inf)
    limit = JointInfo.of(model).torque_limit
    out: list[Floor | MjtrajError] = []
    for job, move, torques, costs in zip(jobs, moves, executed, controllers, strict=True):
        try:
            out.append(_solved(model, config, job, plant, limit, move, torques, costs, every_start, settings))
        except MjtrajError as e:
            out.append(e)
    return out


def _solved(model: mujoco.MjModel, config: LoopConfig, job: Job, plant: mujoco.MjModel | None,
            limit: NDArray[np.float64], displacement: float, executed: dict[str, NDArray[np.float64]],
            controllers: dict[str, float], every_start: bool, settings: FloorSettings) -> Floor:
    """One job's floor from its start laws' executed torques, replayed through the closed loop as its check."""
    reference = job.reference
    truth = model if job.perturbation is None else true_plant(_needs(plant), job.perturbation)
    if not executed:
        executed = {"zero": np.zeros((reference.steps, reference.n))}
    if job.settle is None:
        radius = GOAL_TOLERANCE * displacement
        rule: dict[str, Any] = {"goal_radius": radius}
    else:  # protocol v2: at rest at the goal; on a perturbed plant every start, for `Floor.without`
        radius = job.settle.band
        rule = {"at_rest": AtRest(job.settle.goal, radius, SETTLE_SPEED)}
        every_start = every_start or job.perturbation is not None
    solution = clairvoyant_floor(truth, reference.q, reference.qd, job.weights[0], job.weights[1], limit,
                                 starts=executed, first_fixed=bool(config.delay), every_start=every_start,
                                 settings=settings, **rule)
    result = replay(model, config, job, solution.torques, plant=plant, displacement=displacement)
    if result.status != "ok":
        raise MjtrajError(f"the floor's torques replayed: {result.status} ({result.reason})")
    cost = result.metrics["cost"]
    if abs(cost - solution.cost) > REPLAY_TOLERANCE * max(cost, 1e-12):
        raise MjtrajError(f"the floor's torques replayed give J {cost!r}, the solver's rollout {solution.cost!r}")
    if job.settle is None:
        return Floor(cost, solution.cost, result.metrics["terminal_err"], radius, solution.start, solution.starts,
                     controllers, solution.iterations, solution.converged, solution.seconds, solution.torques)
    return Floor(cost, solution.cost, result.metrics["end_err"], radius, solution.start, solution.starts,
                 controllers, solution.iterations, solution.converged, solution.seconds, solution.torques,
                 result.metrics["end_speed"])


def replay(model: mujoco.MjModel, config: LoopConfig, job: Job, torques: NDArray[np.float64], *,
           plant: mujoco.MjModel | None = None, displacement: float | None = None) -> Outcome:
    """The outcome of applying `torques` (N, n), N m (the applied ones), to `job`'s plant through the closed loop,
    with the goal rule applied (every family)."""
    _, outcomes = execute_batch(model, config, [job], plant=plant,
                                actor=Replay(np.asarray(torques)[None], delay=config.delay))
    return goal_checked(outcomes[0], _move(job.reference) if displacement is None else displacement)


def _move(reference: Reference) -> float:
    """The reference's largest joint displacement, rad (the goal rule's scale when the task's is not given)."""
    return float(np.max(np.abs(reference.q[-1] - reference.q[0])))


def _needs(plant: mujoco.MjModel | None) -> mujoco.MjModel:
    if plant is None:
        raise InvalidInputError("plant: a perturbed job needs the perturbed plant model (perturbed_plant)")
    return plant
