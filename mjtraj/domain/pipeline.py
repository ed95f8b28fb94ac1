"""The one evaluation pipeline: references (+ scoring weights, plant perturbation, measurement noise) through the
one closed loop, optionally with an actor adding torque, to statuses, reasons and metric values.

`mjtraj compare`, sweeps, `mjtraj rl eval` and the RL learning curve all execute here; planning happens before
(`plan_all`), writing after (`mjtraj.study.rows`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.core.closed_loop import ClosedLoop, LoopConfig
from mjtraj.core.metrics import GOAL_TOLERANCE, METRIC_NAMES, gravity_along, metrics_arrays, missed_goal
from mjtraj.core.reference import Reference
from mjtraj.core.rollout import Rollout
from mjtraj.core.settle import SETTLE_METRICS, Settle, settle_arrays, unsettled
from mjtraj.domain.families import Perturbation, plant_fields
from mjtraj.exceptions import InfeasibleError, InvalidInputError, MjtrajError

STATUSES = ("ok", "infeasible", "solver_error", "diverged", "unstable", "missed_goal", "not_settled", "error")
"""Every status a row can have: executed (ok), planning failed (infeasible, solver_error), execution failed
(diverged, unstable, missed_goal: see GOAL_TOLERANCE, on every family; or, in protocol v2's episodes with a settle
window, not_settled: not at rest at the goal when the window ends, `mjtraj.core.settle`), or an unexpected error
(error)."""


def goal_checked(result: Outcome, displacement: float) -> Outcome:
    """`result`, with status missed_goal if its terminal error exceeds GOAL_TOLERANCE of `displacement` (the task's
    largest joint displacement, rad); every family's rows and the floor's replay pass through it."""
    if result.status != "ok" or not missed_goal(result.metrics["terminal_err"], displacement):
        return result
    return Outcome("missed_goal", f"terminal error {result.metrics['terminal_err']:.3g} rad > {GOAL_TOLERANCE:g} x "
                                  f"the move ({displacement:.3g} rad)", result.metrics)


class Actor(Protocol):
    """Adds torque inside the closed loop (an RL policy): `begin` once the loop has started on `references`, then
    `act` before every control period. An actor may also name `shadows`, a tuple of laws or estimators the loop is
    to run in its shadow for it to read (`ClosedLoop(teachers=...)`; none if it names none)."""

    action_mode: str
    """'residual' (added to feedforward + PID before the saturation) or 'torque' (the whole corrective torque)."""

    def begin(self, loop: ClosedLoop, references: Sequence[Reference],
              plants: Sequence[Perturbation | None] = ()) -> None:
        """A new batch of episodes has started on `loop`, on `plants` (one per episode; None: nominal)."""
        ...

    def act(self, loop: ClosedLoop) -> NDArray[np.float64]:
        """The torque for the next period, shape (B, n), N m."""
        ...


@dataclass(frozen=True)
class Job:
    """One execution to run: a reference, the diagonal weights that score it (Q_exec (2n,), R_exec (n,)), and
    optionally how the plant differs from the nominal one, the measurement noise on [q; qd] ((N, 2n)) and, for an
    episode of protocol v2, its settle window (the reference then ends with the window's held goal:
    `mjtraj.core.settle.held`; the outcome carries SETTLE_METRICS and is not_settled unless at rest at the goal);
    `sensor`: the noise's standard deviation on q declared to the control law, rad (`ClosedLoop.start`)."""

    reference: Reference
    weights: tuple[NDArray[np.float64], NDArray[np.float64]]
    perturbation: Perturbation | None = None
    noise: NDArray[np.float64] | None = None
    settle: Settle | None = None
    sensor: float = 0.0


@dataclass(frozen=True)
class Outcome:
    """How one execution went: status (see STATUSES), a one-line reason if not ok, and every metric if ok."""

    status: str
    reason: str = ""
    metrics: dict[str, float] = field(default_factory=dict)


def one_line(error: BaseException) -> str:
    """An error as one line: 'Type: message'."""
    return " ".join(f"{type(error).__name__}: {error}".split())


def plan_failure(error: MjtrajError) -> Outcome:
    """The outcome of a job whose planning failed."""
    return Outcome("infeasible" if isinstance(error, InfeasibleError) else "solver_error", one_line(error))


def outcome(arrays: dict[str, NDArray[np.float64]], j: int, unstable: bool, diverged_step: int,
            config: LoopConfig, settle: Settle | None = None) -> Outcome:
    """Execution j of a batch: unstable, diverged (no metrics), not_settled (with a settle window: not at rest at
    the goal when it ends; metrics kept) or ok."""
    if unstable:
        return Outcome("unstable", "MuJoCo flagged the simulation numerically unstable (bad qacc/qpos/qvel)")
    if diverged_step >= 0:
        return Outcome("diverged", f"|e| > {config.divergence_bound:.4g} rad at step {diverged_step}")
    if settle is None:
        return Outcome("ok", "", {m: float(arrays[m][j]) for m in METRIC_NAMES})
    values = {m: float(arrays[m][j]) for m in (*METRIC_NAMES, *SETTLE_METRICS)}
    why = unsettled(values["end_err"], values["end_speed"], settle)
    return Outcome("not_settled" if why else "ok", why, values)


def execute_batch(model: mujoco.MjModel, config: LoopConfig, jobs: Sequence[Job], *,
                  plant: mujoco.MjModel | None = None, actor: Actor | None = None, nthread: int = 1,
                  seconds: dict[str, float] | None = None, total_torque: bool = False
                  ) -> tuple[Rollout, list[Outcome]]:
    """Execute `jobs` (references of one length N) together on one ClosedLoop; the rollout and each outcome.

    Args:
      plant: the simulated model whose fields the jobs' perturbations set (`mjtraj.domain.families.perturbed_plant`);
        None for the nominal `model` (the jobs must then carry no perturbation).
      actor: adds torque every period (None: the controller alone).
      seconds: if given, 'execute' and 'metrics' accumulate the wall time of each stage.
      total_torque: also measure rms_tau_total (G(q) at every recorded pose: about 3 us a state, so compare and
        frontier measure it and sweeps do not; NaN otherwise).
    """
    clock = time.perf_counter()
    references = [job.reference for job in jobs]
    loop = _loop(model, config, jobs, plant, nthread, tuple(getattr(actor, "shadows", ())))
    noise = _noise(jobs, references, model.nv)
    rollout = _run(loop, jobs, references, noise, actor)
    unstable = loop.unstable()
    middle = time.perf_counter()
    outcomes = _outcomes(model, config, jobs, rollout, unstable, total_torque)
    if seconds is not None:
        seconds["execute"] = seconds.get("execute", 0.0) + middle - clock
        seconds["metrics"] = seconds.get("metrics", 0.0) + time.perf_counter() - middle
    return rollout, outcomes


def _loop(model: mujoco.MjModel, config: LoopConfig, jobs: Sequence[Job], plant: mujoco.MjModel | None,
          nthread: int, shadows: tuple[str, ...] = ()) -> ClosedLoop:
    """The ClosedLoop of `jobs`: on the nominal `model`, or on `plant` with each job's perturbation (all perturbed
    or none); `shadows` run beside its law (an actor's estimators, `ClosedLoop(teachers=...)`)."""
    perturbed = [job.perturbation for job in jobs if job.perturbation is not None]
    if perturbed and (plant is None or len(perturbed) != len(jobs)):
        raise InvalidInputError("jobs: perturbed jobs need the perturbed plant model, and a batch is either all "
                                "perturbed or all nominal")
    fields = plant_fields(plant, perturbed) if plant is not None and perturbed else None
    return ClosedLoop(model, config, nsim=len(jobs), plant=plant, plant_fields=fields, nthread=nthread,
                      teachers=shadows)


def _noise(jobs: Sequence[Job], references: list[Reference], n: int) -> NDArray[np.float64] | None:
    """The jobs' measurement noise, shape (N, B, 2n) (zero for a job without), or None where none has any."""
    if not any(job.noise is not None for job in jobs):
        return None
    N = references[0].steps
    return np.stack([job.noise if job.noise is not None else np.zeros((N, 2 * n)) for job in jobs], axis=1)


def _run(loop: ClosedLoop, jobs: Sequence[Job], references: list[Reference], noise: NDArray[np.float64] | None,
         actor: Actor | None) -> Rollout:
    """Run `loop` on `references`: by the controller alone, or with `actor`'s torque every period (added to the
    controller's in residual mode, else in its place)."""
    sensor = np.array([job.sensor for job in jobs])
    if actor is None:
        return loop.run(references, noise=noise, sensor=sensor)
    loop.start(references, noise=noise, sensor=sensor)
    actor.begin(loop, references, [job.perturbation for job in jobs])
    residual = actor.action_mode == "residual"
    for _ in range(loop.steps):
        torque = actor.act(loop)
        loop.step(residual=torque if residual else None, override=None if residual else torque)
    return loop.rollout()


def _outcomes(model: mujoco.MjModel, config: LoopConfig, jobs: Sequence[Job], rollout: Rollout,
              unstable: NDArray[np.bool_], total_torque: bool) -> list[Outcome]:
    """Each job's outcome from `rollout`: its metrics under its weights (and its settle window's, where the jobs
    have one: all or none), its status (`outcome`)."""
    q_diag = np.array([job.weights[0] for job in jobs])
    r_diag = np.array([job.weights[1] for job in jobs])
    arrays = metrics_arrays(rollout, q_diag, r_diag,
                            gravity=gravity_along(model, rollout) if total_torque else None)
    settles = [job.settle for job in jobs]
    if any(settle is not None for settle in settles):
        if not all(settle is not None for settle in settles):
            raise InvalidInputError("jobs: a batch is either all with a settle window or all without")
        arrays.update(settle_arrays(rollout, q_diag, r_diag, settles))  # type: ignore[arg-type]
    return [outcome(arrays, j, bool(unstable[j]), int(rollout.diverged_step[j]), config, settles[j])
            for j in range(len(jobs))]


def execute(model: mujoco.MjModel, config: LoopConfig, jobs: Sequence[Job], *, plant: mujoco.MjModel | None = None,
            actor: Actor | None = None, nthread: int = 1, seconds: dict[str, float] | None = None,
            total_torque: bool = False) -> list[Outcome]:
    """`execute_batch` over jobs of any lengths (grouped by N, shortest first); outcomes in the order of `jobs`."""
    groups: dict[int, list[int]] = {}
    for i, job in enumerate(jobs):
        groups.setdefault(job.reference.steps, []).append(i)
    out: list[Outcome | None] = [None] * len(jobs)
    for steps in sorted(groups):
        ids = groups[steps]
        _, outcomes = execute_batch(model, config, [jobs[i] for i in ids], plant=plant, actor=actor,
                                    nthread=nthread, seconds=seconds, total_torque=total_torque)
        for i, result in zip(ids, outcomes, strict=True):
            out[i] = result
    return [result for result in out if result is not None]
