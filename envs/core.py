"""The env's batched engine: B episodes on one ClosedLoop, with their observations, rewards and infos.

UR5TrackEnv is this with B = 1, UR5TrackVectorEnv with B = num_envs: one implementation for both. It reads the
loop only through ClosedLoop's public queries.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
from mjtraj.envs.settings import PREVIEW_FRAMES, TrackSettings
from numpy.typing import NDArray

from mjtraj.core import (
    FILTER,
    METRIC_NAMES,
    RECORDED,
    SETTLE_METRICS,
    ClosedLoop,
    Reference,
    Rollout,
    Settle,
    Task,
    disturbance_of,
    held,
    metrics_arrays,
    missed_goal,
    parameter_bounds,
    settle_arrays,
    step_cost,
    unsettled,
)
from mjtraj.domain import (
    FamilyScenario,
    Job,
    Perturbation,
    measurement_noise,
    no_perturbation,
    perturbed_plant,
    plant_fields,
    true_parameters,
)
from mjtraj.exceptions import InvalidInputError

STEP_INFO = ("tau_ff", "tau_fb", "dtau", "saturated", "e", "reward_tracking", "reward_effort", "reward_baseline")
"""Keys of every step's info (arrays of shape (B, n), or (B,) for the reward terms)."""


def disturbance_estimate(loop: ClosedLoop) -> NDArray[np.float64]:
    """(B, n) N m: the torque disturbance `mpc`'s filter estimates now, after this period's measurement (the
    `mpc_filter` shadowing `loop`; 0 in an episode without a settle window, where the filter does not run)."""
    out = loop.teach(FILTER)
    assert out.state is not None
    return disturbance_of(out.state, loop.model.nv)


def observe(loop: ClosedLoop, preview: int, control: bool = False, measured: bool = False,
            frame: str = "absolute") -> NDArray[np.float64]:
    """Observations of every simulation of a started loop, shape (B, 6n + 1 + 2n preview [+ 2n]): q, qd, q_ref,
    qd_ref, e, ed, the phase k/N, then q_ref and qd_ref of the next `preview` periods (held at N; in the `frame`
    relative, minus the observed q and qd; reference, minus q_ref and qd_ref now, so that the measurement enters
    through q, qd, e and ed alone), then with `control` the PID integral (rad s) and the next period's feedforward
    torque (N m). With `measured`, q and qd (and so e, ed) are what the control law measures
    (`ClosedLoop.measured`: with measurement noise, the noisy ones), else the true state."""
    q, qd = loop.measured() if measured else (loop.positions, loop.velocities)
    q_ref, qd_ref = loop.reference()
    parts = [q, qd, q_ref, qd_ref, q_ref - q, qd_ref - qd, (loop.periods / loop.ends)[:, None]]
    if frame not in PREVIEW_FRAMES:
        raise InvalidInputError(f"frame: expected one of {', '.join(PREVIEW_FRAMES)}, got {frame!r}")
    origin = {"relative": (q, qd), "reference": (q_ref, qd_ref)}.get(frame)  # None: absolute, the samples themselves
    for offset in range(1, preview + 1):
        ahead_q, ahead_qd = loop.reference(offset)
        parts += [ahead_q, ahead_qd] if origin is None else [ahead_q - origin[0], ahead_qd - origin[1]]
    if control:
        parts += loop.controller_state()
    return np.concatenate(parts, axis=1)


class Observer:
    """Observations of `num` simulations as the env gives them: `observe`'s entries, then with observe_plant the
    plant parameters theta / theta_max (1 + 2n: payload, damping, friction; see mjtraj.core.adaptive), then with
    observe_disturbance `mpc`'s filtered torque disturbance over the saturation (n), then with observe_task the move
    (rad) and the time to the motion's end (s, negative in a settle window), then with
    history the `history` previous such observations, the latest first (an episode's first observation fills them).

    The env (after reset and every step) and the policy actor of rl eval and validation (before every period) call
    it once per observation, so both see the same sequence.
    """

    def __init__(self, settings: TrackSettings, num: int) -> None:
        self.settings = settings
        self.num = num
        self._bounds = parameter_bounds(settings.model) if settings.observe_plant != "none" else None
        self._plants = np.zeros((num, 1 + 2 * settings.n))
        size = settings.obs_size // (1 + settings.history)
        self._history = np.zeros((num, settings.history, size))
        self._last = np.zeros((num, size))
        self._fresh = np.ones(num, dtype=bool)
        self._move = np.zeros(num)
        self._motion = np.zeros(num)

    def start(self, rows: NDArray[np.intp], plants: Sequence[Perturbation | None],
              references: Sequence[Reference] = ()) -> None:
        """Simulations `rows` begin episodes on `plants` (None: nominal) tracking `references` (needed with
        observe_task: the move and the motion's periods): their next observation is their first."""
        self._fresh[rows] = True
        if self._bounds is not None:
            self._plants[rows] = true_parameters(list(plants), self.settings.n) / self._bounds
        if self.settings.observe_task:
            if len(references) != np.size(rows):
                raise InvalidInputError(f"references: observe_task needs each episode's reference, expected "
                                        f"{np.size(rows)}, got {len(references)}")
            self._move[rows] = [float(np.max(np.abs(r.q[-1] - r.q[0]))) for r in references]
            self._motion[rows] = [int(r.info.get("motion_steps", r.steps)) for r in references]

    def __call__(self, loop: ClosedLoop, rows: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """The observations of simulations `rows` (all if None) now, shape (len(rows), obs_size); advances their
        history by one observation."""
        s = self.settings
        base = observe(loop, s.preview, s.observe_control, s.observe_measured, s.preview_frame)
        if s.observe_plant == "estimate":
            state = loop.law_state()
            assert state is not None and self._bounds is not None
            base = np.concatenate([base, state / self._bounds], axis=1)
        elif s.observe_plant == "true":
            base = np.concatenate([base, self._plants], axis=1)
        if s.observe_disturbance:
            base = np.concatenate([base, disturbance_estimate(loop) / s.torque_limit], axis=1)
        if s.observe_task:
            left = (self._motion - loop.periods) * s.dt
            base = np.concatenate([base, self._move[:, None], left[:, None]], axis=1)
        rows = np.arange(self.num) if rows is None else rows
        if not s.history:
            return base[rows]
        fresh, old = rows[self._fresh[rows]], rows[~self._fresh[rows]]
        self._history[old, 1:] = self._history[old, :-1]
        self._history[old, 0] = self._last[old]
        self._history[fresh] = base[fresh, None, :]
        self._last[rows] = base[rows]
        self._fresh[rows] = False
        return np.concatenate([base[rows], self._history[rows].reshape(rows.size, -1)], axis=1)


def _numeric_like(action: object) -> bool:
    """A number or a (nested) list or tuple of them; not a string, a dict or another object."""
    if isinstance(action, (list, tuple)):
        return all(_numeric_like(a) for a in action)
    return isinstance(action, (int, float, complex, np.number)) and not isinstance(action, bool)


def check_action(action: npt.ArrayLike, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """The action as float64 of `shape` (a flat array of as many values is reshaped): real and finite, or
    InvalidInputError."""
    raw = action if isinstance(action, np.ndarray) else np.asarray(action) if _numeric_like(action) else None
    if raw is None or raw.dtype.kind not in "iuf":
        kind = type(action).__name__ if raw is None else f"{raw.dtype} values"
        raise InvalidInputError(f"action: expected real numbers in [-1, 1], got {kind}")
    a = raw.astype(np.float64, copy=False)
    if a.shape != shape:
        if a.ndim != 1 or a.size != math.prod(shape):  # only a flat array of as many values is reshaped
            expected = shape[1:] if shape[0] == 1 else shape
            raise InvalidInputError(f"action: expected shape {expected}, got {np.shape(action)}")
        a = a.reshape(shape)
    if not np.isfinite(a).all():
        raise InvalidInputError(f"action: expected finite values in [-1, 1], got {np.asarray(action).tolist()}")
    return a


def scale_action(action: npt.ArrayLike, limit: NDArray[np.float64]) -> NDArray[np.float64]:
    """A (B, n) action in [-1, 1] (clipped outside; a flat array of B n values is reshaped) as torque, N m."""
    a = check_action(action, limit.shape)
    return np.minimum(np.maximum(a, -1.0), 1.0) * limit


class Episode(NamedTuple):
    """What one episode runs: its reference, the diagonal weights that score it (Q_exec (2n,), R_exec (n,)), its
    plant (None: the nominal one), its measurement noise on [q; qd] ((N, 2n), or None) and the noise's standard
    deviation on q declared to the control law (rad, 0 without noise; `ClosedLoop.start`)."""

    reference: Reference
    weights: tuple[NDArray[np.float64], NDArray[np.float64]]
    plant: Perturbation | None = None
    noise: NDArray[np.float64] | None = None
    task: Task | None = None
    """The task the reference was planned for (reset's info reports it)."""
    sensor: float = 0.0


class TrackCore:
    """B tracking episodes advanced together: task sampling, planning, plant randomisation, control, observation,
    reward."""

    def __init__(self, settings: TrackSettings, num: int) -> None:
        self.settings = settings
        self.num = num
        self.model = settings.model
        n = settings.n
        if settings.observe_disturbance and not settings.settle > 0:
            raise InvalidInputError(f"observe_disturbance: mpc's filter runs in protocol v2's episodes, which end with "
                                    f"a settle window; expected settle > 0, got settle={settings.settle!r}")
        self.plant = (perturbed_plant(self.model, settings.model_path, settings.model_torque_limit)
                      if settings.perturbs else None)
        """The simulated model whose fields each episode's perturbation sets; None: the nominal model."""
        fields = plant_fields(self.plant, [no_perturbation(n)] * num) if self.plant is not None else None
        self.loop = ClosedLoop(self.model, settings.loop, nsim=num, plant=self.plant, plant_fields=fields,
                               teachers=settings.shadows())
        self.shadow = (ClosedLoop(self.model, settings.loop, nsim=num, plant=self.plant, plant_fields=fields)
                       if settings.reward_baseline != "none" else None)
        """With reward_baseline 'controller' (or 'pid', its earlier name): the same episodes under the control law
        alone (no action), stepped alongside."""
        self.limit = np.tile(settings.action_scale, (num, 1))
        task = settings.fixed_task
        self.fixed = (self._planned(task), settings.weights(task)) if task is not None else None
        self.references: list[Reference | None] = [None] * num
        self.plants: list[Perturbation | None] = [None] * num
        """Each simulation's current plant (None: nominal)."""
        self.tasks: list[Task | None] = [None] * num
        """Each simulation's current task."""
        self._q_diag = np.zeros((num, 2 * n))
        self._r_diag = np.zeros((num, n))
        self._observer = Observer(settings, num)

    def _planned(self, task: Task) -> Reference:
        """The env's planner's reference for `task`, followed by the settle window holding its goal (if any)."""
        return held(self.settings.planner.plan(task, self.model), self.settings.settle_steps, task.qg)

    def plan(self, rng: np.random.Generator, task: Task | None = None) -> Episode:
        """The next episode, drawn from `rng` in a fixed order: the task (unless given, or the env's task is fixed:
        then planned once), then the plant, then the measurement noise."""
        s = self.settings
        if task is not None:
            reference, weights, plant = self._planned(task), s.weights(task), s.sample_plant(rng)
        elif self.fixed is not None:
            (reference, weights), plant = self.fixed, s.sample_plant(rng)
        else:
            task, plant = s.sample_episode(rng)
            reference, weights = self._planned(task), s.weights(task)
        noise = s.sample_noise(rng, reference.steps)
        return Episode(reference, weights, plant, noise, task if task is not None else s.fixed_task,
                       s.measurement_noise if noise is not None else 0.0)

    def replay(self, scenario: FamilyScenario) -> Episode:
        """The episode of a sweep scenario, as sweeps run it: its task planned by this env's planner, Bryson's
        weights, its plant (None: nominal) and, for a perturbed one under measurement noise, the noise drawn from
        its own seed (`mjtraj.domain.families.measurement_noise`)."""
        s, task = self.settings, scenario.task
        noise = None
        if scenario.perturbation is not None and s.measurement_noise > 0:
            noise = measurement_noise([scenario], task.steps + s.settle_steps, s.n, s.measurement_noise,
                                      self.model.opt.timestep)[:, 0]
        return Episode(self._planned(task), s.weights(task), scenario.perturbation, noise, task,
                       s.measurement_noise if noise is not None else 0.0)

    def reset(self, rngs: Sequence[np.random.Generator], ids: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """Start new episodes on simulations `ids` (all if None), one rng each; their observations (len, d)."""
        return self.begin([self.plan(rng) for rng in rngs], ids)

    def begin(self, episodes: Sequence[Episode], ids: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """Start `episodes` on simulations `ids` (all if None); their observations (len, d)."""
        rows = np.arange(self.num) if ids is None else ids
        for row, episode in zip(rows, episodes, strict=True):
            self.references[row], self.plants[row], self.tasks[row] = episode.reference, episode.plant, episode.task
            self._q_diag[row], self._r_diag[row] = episode.weights
        loops = [self.loop] if self.shadow is None else [self.loop, self.shadow]
        if self.plant is not None:
            plants = [e.plant if e.plant is not None else no_perturbation(self.settings.n) for e in episodes]
            fields = plant_fields(self.plant, plants)
            for loop in loops:
                loop.set_plant_fields(fields, rows)
        noise = None
        if any(e.noise is not None for e in episodes):
            n2 = 2 * self.settings.n
            longest = max(e.reference.steps for e in episodes)  # a shorter episode's noise padded (never read)
            noise = np.zeros((longest, len(episodes), n2))
            for b, e in enumerate(episodes):
                if e.noise is not None:
                    noise[:e.reference.steps, b] = e.noise
        references, sensor = [e.reference for e in episodes], np.array([e.sensor for e in episodes])
        for loop in loops:
            if ids is None:
                loop.start(references, noise=noise, sensor=sensor)
            else:
                loop.restart(ids, references, noise=noise, sensor=sensor)
        self._observer.start(rows, [e.plant for e in episodes], references)
        return self._observer(self.loop, rows)

    def start_info(self, ids: NDArray[np.intp]) -> dict[str, dict[str, NDArray[np.float64]]]:
        """What reset's info says of the episodes of simulations `ids`: "task" (q0, qg: (len(ids), n) rad;
        duration: (len(ids),) s) and, on perturbed plants, "plant" (`plant_info`)."""
        tasks = [self.tasks[i] for i in ids]
        out = {"task": {"q0": np.array([t.q0 for t in tasks]), "qg": np.array([t.qg for t in tasks]),  # type: ignore
                        "duration": np.array([t.duration for t in tasks])}}  # type: ignore[union-attr]
        plant = self.plant_info(ids)
        return {**out, "plant": plant} if plant else out

    def plant_info(self, ids: NDArray[np.intp]) -> dict[str, NDArray[np.float64]]:
        """The plants of simulations `ids` as info columns (payload_kg, mass_scale_j, inertia_scale_j, damping_j,
        friction_j), name -> (len(ids),); empty without plant randomisation."""
        if self.plant is None:
            return {}
        rows = [(p if p is not None else no_perturbation(self.settings.n)).as_dict() for p in
                (self.plants[i] for i in ids)]
        return {name: np.array([r[name] for r in rows]) for name in rows[0]}

    def action(self, action: npt.ArrayLike) -> NDArray[np.float64] | None:
        """Validate a (B, n) action (real, finite; clipped to [-1, 1]) and scale it to torque, N m; None in pid mode,
        where the action is checked and then ignored."""
        if self.settings.action_mode == "pid":
            check_action(action, self.limit.shape)  # checked in every mode, then ignored
            return None
        return scale_action(action, self.limit)

    def step(self, action: npt.ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                   NDArray[np.bool_], dict[str, Any]]:
        """One control period for every simulation: (observation (B, d), reward (B,), terminated (B,), info)."""
        torque = self.action(action)
        mode = self.settings.action_mode
        step = self.loop.step(residual=torque if mode == "residual" else None,
                              override=torque if mode == "torque" else None)
        c = step.control
        tracking, effort = step_cost(step.e, step.ed, c.dtau, self._q_diag, self._r_diag)
        baseline = np.zeros(self.num)
        if self.shadow is not None:
            alone = self.shadow.step()
            alone_tracking, alone_effort = step_cost(alone.e, alone.ed, alone.control.dtau, self._q_diag, self._r_diag)
            baseline = -(alone_tracking + alone_effort)
        info = {"tau_ff": c.tau_ff.copy(), "tau_fb": c.tau_fb, "dtau": c.dtau, "saturated": c.saturated,
                "e": step.e.copy(), "reward_tracking": -tracking, "reward_effort": -effort,
                "reward_baseline": baseline}
        return self.observe(), -tracking - effort - baseline, self.loop.done, info

    def observe(self) -> NDArray[np.float64]:
        """Observations of every simulation (see `Observer`); advances their history."""
        return self._observer(self.loop)

    def metrics(self, ids: NDArray[np.intp]) -> dict[str, NDArray[np.float64]]:
        """The episode Metrics of simulations `ids` (NaN for a diverged one): name -> shape (len(ids),). An episode
        cut short (a time limit) is scored over the periods it ran: J_exec summed over them (so it equals minus its
        return), terminal_err at the pose it reached against the reference's sample there. Episodes of several
        lengths (the aggressive family's) are scored a length at a time. With a settle window the metrics cover the
        whole episode and SETTLE_METRICS follow (NaN for an episode cut short or diverged)."""
        names = (*METRIC_NAMES, *SETTLE_METRICS) if self.settings.settle_steps else METRIC_NAMES
        ends = self.loop.ends[ids]
        if np.any(ends != ends[0]):
            parts = {int(end): np.flatnonzero(ends == end) for end in np.unique(ends)}
            merged = {name: np.empty(len(ids)) for name in names}
            for where in parts.values():
                scored = self.metrics(ids[where])
                for name in names:
                    merged[name][where] = scored[name]
            return merged
        rollout = self.loop.rollout(ids)
        arrays = metrics_arrays(rollout, self._q_diag[ids], self._r_diag[ids])  # rms_tau_total: NaN (see pipeline)
        out = {name: np.where(rollout.diverged, np.nan, arrays[name]) for name in METRIC_NAMES}
        periods = self.loop.periods[ids]
        q_ref, _ = self.loop.reference()
        for j in np.flatnonzero((periods > 0) & (periods < ends) & ~rollout.diverged):
            row, k = ids[j], int(periods[j])
            one = rollout.scenario(int(j))
            q, qd = self.loop.positions[row][None].copy(), self.loop.velocities[row][None].copy()
            cut = Rollout(**{name: getattr(one, name)[:, :k] for name in RECORDED}, q_final=q, qd_final=qd,
                          e_final=q_ref[row][None] - q, diverged_step=one.diverged_step, dt=one.dt)
            partial = metrics_arrays(cut, self._q_diag[row], self._r_diag[row])
            for name in METRIC_NAMES:
                out[name][j] = partial[name][0]
        if self.settings.settle_steps:
            out.update(self._settle_metrics(ids, rollout, periods >= ends))
        return out

    def holding(self) -> NDArray[np.bool_]:
        """(num,): True where a simulation's motion has ended and it holds its goal (the settle window; False
        everywhere without one)."""
        motion = np.array([int(r.info.get("motion_steps", r.steps)) if r is not None else 0 for r in self.references])
        return (self.loop.periods >= motion) & (self.settings.settle_steps > 0)  # type: ignore[no-any-return]

    def _settle(self, row: int) -> Settle:
        """Simulation `row`'s settle window (its task's goal and move, its reference's motion)."""
        task, reference = self.tasks[row], self.references[row]
        assert task is not None and reference is not None
        return Settle.of(task, int(reference.info["motion_steps"]), self.settings.settle_steps)

    def _settle_metrics(self, ids: NDArray[np.intp], rollout: Rollout, complete: NDArray[np.bool_]
                        ) -> dict[str, NDArray[np.float64]]:
        """SETTLE_METRICS of simulations `ids` (one length, `rollout` theirs): NaN where the episode is not
        `complete` or diverged."""
        arrays = settle_arrays(rollout, self._q_diag[ids], self._r_diag[ids], [self._settle(int(i)) for i in ids])
        keep = complete & ~rollout.diverged
        return {name: np.where(keep, arrays[name], np.nan) for name in SETTLE_METRICS}

    def settled(self, ids: NDArray[np.intp], values: dict[str, NDArray[np.float64]]) -> list[str]:
        """Why each ended episode of simulations `ids`, with metrics `values` (name -> (len(ids),)), is not at rest
        at its goal when its settle window ends ('' where it is; 'diverged' where it diverged)."""
        return ["diverged" if not np.isfinite(values["end_err"][j]) else
                unsettled(float(values["end_err"][j]), float(values["end_speed"][j]), self._settle(int(row)))
                for j, row in enumerate(ids)]

    def floors(self, ids: NDArray[np.intp], costs: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """The clairvoyant floors of the episodes of simulations `ids` (`mjtraj.domain.floor.floors_of`: their
        reference, weights and plant, the laws' executions as starts; measurement noise does not reach a torque
        sequence; with a settle window protocol v2's floor, J_settle at rest at the goal), and their scores `costs`
        (len(ids),) over them: "floor" and "cost_over_floor", (len(ids),), NaN where the floor failed."""
        from mjtraj.domain import Floor, floors_of

        window = self.settings.settle_steps
        jobs = [Job(self.references[i], (self._q_diag[i].copy(), self._r_diag[i].copy()),  # type: ignore[arg-type]
                    self.plants[i], settle=self._settle(int(i)) if window else None) for i in ids]
        moves = [float(np.max(np.abs(self.tasks[i].displacement))) for i in ids]  # type: ignore[union-attr]
        plant = self.plant if any(job.perturbation is not None for job in jobs) else None
        if plant is not None:  # a batch is all perturbed or all nominal: a nominal episode is the null perturbation
            jobs = [job if job.perturbation is not None else dataclasses.replace(job, perturbation=no_perturbation(
                self.settings.n)) for job in jobs]
        found = floors_of(self.model, self.settings.loop, jobs, plant=plant, displacements=moves)
        floor = np.array([f.cost if isinstance(f, Floor) else np.nan for f in found])
        return {"floor": floor, "cost_over_floor": costs / floor}

    def goal_missed(self, ids: NDArray[np.intp], terminal_err: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Whether the episodes of simulations `ids`, ending with `terminal_err` (rad, (len(ids),)), missed their goal
        by the benchmark's goal rule (GOAL_TOLERANCE of the task's largest joint displacement), shape (len(ids),)."""
        moves = np.array([float(np.max(np.abs(self.tasks[i].displacement))) for i in ids])  # type: ignore[union-attr]
        return missed_goal(terminal_err, moves)

    def reference_pose(self, row: int) -> NDArray[np.float64]:
        """The reference sample simulation `row` tracks next (the ghost arm), rad."""
        return self.loop.reference()[0][row]
