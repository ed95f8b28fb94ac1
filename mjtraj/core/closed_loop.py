"""The closed loop (docs/design.md, "Controller"), once: plant + the configured control law (feedforward + PID by
default, or computed torque, or a plug-in's), batched; compare, sweeps, rl eval and the envs all run it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj.checks import vector
from mjtraj.core.adaptive import ADAPTATION_RATE
from mjtraj.core.controller import ANTI_WINDUP, Controller, ControlOutput, PIDGains
from mjtraj.core.dynamics import DynamicsProbe
from mjtraj.core.feedforward import FEEDFORWARD_ACCEL, FEEDFORWARD_MODES, feedforward_many, reference_accelerations
from mjtraj.core.laws import ESTIMATORS, controller_names, make_controller
from mjtraj.core.model import JointInfo
from mjtraj.core.options import check_options, option
from mjtraj.core.plant import GRAVITY_COMP, BatchPlant
from mjtraj.core.reference import Reference
from mjtraj.core.rollout import Rollout
from mjtraj.exceptions import InvalidInputError


@dataclass(frozen=True)
class LoopConfig:
    """Everything about the controller that is held identical across planners: the PID gains and the declared
    options below (`mjtraj.core.options`: each is validated, read from scenario files and env arguments, and
    given a command-line flag from its declaration here)."""

    gains: PIDGains
    controller: str = option("pid", "control law: pid = feedforward + PID with the gains (the paper's); "
                             "computed_torque = inverse dynamics of the nominal model at the measured state with PD "
                             "on the error (gains by the stated rule; ff_accel picks its reference acceleration; "
                             "feedforward and the PID gains are unused); adaptive_computed_torque = computed torque "
                             "with an online estimate of a payload, damping and friction; mpc = model-predictive "
                             "tracking with the reference's preview; adaptive_mpc = mpc on the adaptive estimate",
                             choices=controller_names)
    feedforward: str = option("inverse", "feedforward torque: inverse = ID(q_ref, qd_ref, qdd_ref) - G(q_ref) on the "
                              "nominal model, planned = the planner's own u_plan, none = 0",
                              choices=FEEDFORWARD_MODES, flag="--ff")
    ff_accel: str = option("sample", "reference acceleration of the inverse feedforward: sample = qdd_ref(t_k), "
                           "step_average = (qd_ref,k+1 - qd_ref,k)/dt", choices=FEEDFORWARD_ACCEL)
    gravity_comp: str = option("native", "gravity compensation: native = G(q) inside every integrator stage, zoh = "
                               "G(q_k) held over the period", choices=GRAVITY_COMP)
    anti_windup: str = option("none", "anti-windup: none, or clamp = stop integrating on a saturated joint",
                              choices=ANTI_WINDUP)
    adaptation_rate: float = option(ADAPTATION_RATE, "adaptive_computed_torque's adaptation rate gamma, 1/(N m rad): "
                                    "Gamma = gamma diag(theta_max^2) (0 freezes the estimate at the nominal model)",
                                    minimum=0.0)
    substeps: int = option(1, "integrator steps per control period", minimum=1)
    divergence_bound: float = option(float(np.pi), "|e| above this on any joint marks an execution diverged, rad",
                                     positive=True, scenario=False)
    delay: int = option(0, "actuation delay in control periods: with 1 the plant receives in period k the torque "
                        "computed in period k-1 (zero in period 0)", choices=(0, 1), scenario=False)

    def __post_init__(self) -> None:
        check_options(self)


RECORDED = ("q", "qd", "e", "ed", "tau_ff", "tau_fb", "dtau", "saturated")


@dataclass
class _LoopState:
    """Per-simulation progress of a running loop (private to ClosedLoop, mutable). Arrays are time-major.

    q_ref, qd_ref: shape (N+1, B, n); tau_ff: (N, B, n); qdd_ref: (N, B, n) for a law that reads it (by the
    ff_accel rule), else None; integral: (B, n), rad s; noise: measurement
    noise (N, B, 2n) added to [q; qd] before control, or None; held: the torque the delayed actuator applies
    next, (B, n), or None without delay; law_state: a stateful law's state (B, state_size), else None;
    diverged_step: (B,), -1 while running; records: name -> (N, B, n)
    for each of RECORDED (NaN where not reached); q_final, qd_final: (B, n) state after period N-1 (NaN until
    then).
    sync: the common next period while every simulation is live and in step (the fast path), else None; k:
    (B,) each simulation's next period, kept only while sync is None (read `periods`).
    ends: (B,) each simulation's own N (references of several lengths run side by side: the arrays above are as long
    as the longest, a shorter reference padded with its last sample, its records NaN past its end); horizon: the
    least of them, where the fast path stops.
    """

    q_ref: NDArray[np.float64]
    qd_ref: NDArray[np.float64]
    tau_ff: NDArray[np.float64]
    qdd_ref: NDArray[np.float64] | None
    k: NDArray[np.intp]
    integral: NDArray[np.float64]
    diverged_step: NDArray[np.int64]
    records: dict[str, NDArray[Any]]
    q_final: NDArray[np.float64]
    qd_final: NDArray[np.float64]
    noise: NDArray[np.float64] | None = None
    held: NDArray[np.float64] | None = None
    law_state: NDArray[np.float64] | None = None
    teachers: dict[str, _TeacherState] = field(default_factory=dict)
    sync: int | None = 0
    ends: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    rows: NDArray[np.intp] = field(init=False)
    horizon: int = field(init=False)

    def __post_init__(self) -> None:
        self.rows = np.arange(self.k.size)
        if self.ends.size == 0:
            self.ends = np.full(self.k.size, self.steps, dtype=np.intp)
        self.horizon = int(self.ends.min())

    @property
    def uniform(self) -> bool:
        """Every simulation runs a reference of the arrays' full length."""
        return self.horizon == self.steps

    @property
    def steps(self) -> int:
        """N, the number of control periods."""
        return self.tau_ff.shape[0]

    @property
    def periods(self) -> NDArray[np.intp]:
        """Each simulation's next control period, shape (B,); its N once it has ended or diverged."""
        return np.full(self.k.size, self.sync, dtype=np.intp) if self.sync is not None else self.k.copy()

    def set_ends(self, rows: slice | NDArray[np.intp], steps: NDArray[np.intp]) -> None:
        """Simulations `rows` now run references of `steps` periods (one each)."""
        self.ends[rows] = steps
        self.horizon = int(self.ends.min())

    def desync(self) -> None:
        """Leave the fast path: write the common period into k."""
        if self.sync is not None:
            self.k[:] = self.sync
            self.sync = None

    def resync(self) -> None:
        """Re-enter the fast path when every simulation is live and at the same period."""
        k = self.k
        self.sync = int(k[0]) if np.all(k == k[0]) and np.all(self.diverged_step < 0) else None


@dataclass
class _TeacherState:
    """A teacher's own PID integral (B, n) and law state (B, state_size, or None), and its output of the period
    it last answered (`ClosedLoop.teach`), kept until the loop steps past that period."""

    integral: NDArray[np.float64]
    law_state: NDArray[np.float64] | None
    answered: tuple[NDArray[np.intp], ControlOutput] | None = None


class Step(NamedTuple):
    """What one period did, for a batch: measured state and errors before control (shapes (B, n)), the control.

    A NamedTuple, as it is built every control period; q, qd, e, ed are the loop's records (do not write them).
    """

    q: NDArray[np.float64]
    qd: NDArray[np.float64]
    e: NDArray[np.float64]
    ed: NDArray[np.float64]
    control: ControlOutput
    diverged: NDArray[np.bool_]
    """Shape (B,): the scenario is (now or already) diverged."""


class ClosedLoop:
    """B scenarios of the plant under the configured control law, advanced one control period at a time.

    `model` is the nominal model (planner, feedforward, zoh gravity); `plant` the simulated one (default: the
    nominal one), with per-simulation `plant_fields` (see BatchPlant). Use `run` for whole references, or
    `start` (all simulations) / `restart` (some) then `step` to act in between, reading the queries below.

    The records hold the true state and error (the metrics score them); with measurement noise the controller
    sees the noisy ones. With an actuation delay, `dtau` records the torque the plant received.

    `teachers` names other control laws that shadow the loop's own (for imitation: `teach` gives what one of them
    would command now, at what the loop's law measures), or estimators (`mjtraj.core.laws.ESTIMATORS`: `mpc_filter`,
    whose state a policy observes). Each runs as the loop's law would, on the same references
    and measurements, with its own integral and state, advanced every period as its own loop would advance them
    had it commanded what the loop applied: a predictive law's protocol-v2 prediction counts the loop's command (its
    `applied_state`; else its filter would take the difference for a disturbance and its answers would drift from
    what it commands in its own loop). The other states follow the teacher's own command where they depend on it at
    all, through its saturation: PID's integral under anti_windup='clamp', `adaptive_mpc`'s adaptation in protocol
    v1's episodes. Where the loop's law is the teacher's, its answers are the loop's commands, bit for bit.
    """

    def __init__(self, model: mujoco.MjModel, config: LoopConfig, *, nsim: int = 1,
                 plant: mujoco.MjModel | None = None, plant_fields: dict[str, NDArray[np.float64]] | None = None,
                 nthread: int = 0, teachers: Sequence[str] = ()) -> None:
        self.model = model
        self.config = config
        self.dt = float(model.opt.timestep)
        self.limit = JointInfo.of(model).torque_limit
        """Corrective-torque saturation per joint, shape (n,), N m."""
        self._plant = BatchPlant(plant if plant is not None else model, nsim, nominal=model,
                                 gravity_comp=config.gravity_comp, substeps=config.substeps, nthread=nthread,
                                 fields=plant_fields)
        self._state: _LoopState | None = None
        self._law: Controller = make_controller(config, self.dt, model.nv, nsim, model)
        self._stateful = int(getattr(self._law, "state_size", 0)) > 0
        self._dynamics = DynamicsProbe(model, size=nsim) if self._law.needs_dynamics else None
        self._limit = np.tile(self.limit, (nsim, 1))
        self._none_diverged = np.zeros(nsim, dtype=bool)
        self._none_diverged.setflags(write=False)
        self._probe: DynamicsProbe | None = None
        self._teachers: dict[str, Controller] = {}
        known = (*controller_names(), *ESTIMATORS)
        for name in teachers:
            if not isinstance(name, str) or name not in known:
                raise InvalidInputError(f"teachers: expected control laws or estimators among {', '.join(known)}, "
                                        f"got {name!r}")
            self._teachers[name] = (ESTIMATORS[name](config, self.dt, model.nv, nsim, model) if name in ESTIMATORS
                                    else make_controller(replace(config, controller=name), self.dt, model.nv, nsim,
                                                         model))
        self._teacher_dynamics = (DynamicsProbe(model, size=nsim)
                                  if any(law.needs_dynamics for law in self._teachers.values()) else None)

    # -- queries -------------------------------------------------------------------------------------------------

    @property
    def nsim(self) -> int:
        """B, the number of simulations."""
        return self._plant.nsim

    @property
    def started(self) -> bool:
        """Whether `start` has been called."""
        return self._state is not None

    @property
    def steps(self) -> int:
        """N, the control periods of the running references (of the longest, where a restart gave some simulations
        references of another length: `ends` gives each its own)."""
        return self._running().steps

    @property
    def _previewer(self) -> str:
        """The first of the loop's law and its teachers that previews the reference ('' if none): what an error
        names."""
        laws = [(f"the control law {self.config.controller!r}", self._law),
                *((f"the teacher {name!r}", law) for name, law in self._teachers.items())]
        return next((what for what, law in laws if getattr(law, "track", None) is not None), "")

    @property
    def previews(self) -> bool:
        """Whether the control law or a teacher previews the reference (the model-predictive ones): the loop runs
        references of one length per batch."""
        return any(getattr(law, "track", None) is not None for law in (self._law, *self._teachers.values()))

    @property
    def ends(self) -> NDArray[np.intp]:
        """Each simulation's own N, shape (B,) (read-only use)."""
        return self._running().ends

    @property
    def periods(self) -> NDArray[np.intp]:
        """Each simulation's next control period, shape (B,); its N once it has ended or diverged."""
        return self._running().periods

    @property
    def done(self) -> NDArray[np.bool_]:
        """Shape (B,): the simulation has run its N periods or diverged."""
        s = self._running()
        if s.sync is not None:
            return np.full(self.nsim, s.sync >= s.steps) if s.uniform else s.sync >= s.ends
        return s.k >= s.ends

    @property
    def diverged(self) -> NDArray[np.bool_]:
        """Shape (B,): the simulation diverged (|e| above the bound, or a non-finite state)."""
        return self._running().diverged_step >= 0

    @property
    def positions(self) -> NDArray[np.float64]:
        """Joint positions now, shape (B, n), rad (a live view: read it, do not keep or write it)."""
        return self._plant.qpos

    @property
    def velocities(self) -> NDArray[np.float64]:
        """Joint velocities now, shape (B, n), rad/s (a live view: read it, do not keep or write it)."""
        return self._plant.qvel

    def measured(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """What the control law will measure at each simulation's next period: the positions (rad) and velocities
        (rad/s) now plus that period's measurement noise (the last period's once the reference ended), shape (B, n)
        each; without noise, `positions` and `velocities` themselves (read-only use)."""
        s = self._running()
        if s.noise is None:
            return self.positions, self.velocities
        n = self.model.nv
        ks = np.minimum(s.periods, s.ends - 1)
        noise = s.noise[ks, s.rows]
        return self.positions + noise[:, :n], self.velocities + noise[:, n:]

    def reference(self, offset: int = 0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each simulation's reference sample at its next period + `offset` (held at N): q_ref and qd_ref, shape
        (B, n) each, rad and rad/s (read-only use)."""
        s = self._running()
        if s.sync is not None and s.uniform:
            now = min(s.sync + offset, s.steps)
            return s.q_ref[now], s.qd_ref[now]
        ks = np.minimum(s.periods + offset, s.ends)
        return s.q_ref[ks, s.rows], s.qd_ref[ks, s.rows]

    def controller_state(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each simulation's PID integral now (rad s) and the feedforward torque of its next period (N m, held at
        the last period once the reference ends), shape (B, n) each (read-only use)."""
        s = self._running()
        if s.sync is not None and s.uniform:
            return s.integral, s.tau_ff[min(s.sync, s.steps - 1)]
        return s.integral, s.tau_ff[np.minimum(s.periods, s.ends - 1), s.rows]

    def unstable(self) -> NDArray[np.bool_]:
        """Shape (B,): MuJoCo flagged the simulation numerically unstable since its last start."""
        return self._plant.unstable()

    def _running(self) -> _LoopState:
        if self._state is None:
            raise InvalidInputError("loop: call start(references) first")
        return self._state

    def set_plant_fields(self, fields: dict[str, NDArray[np.float64]], ids: npt.ArrayLike | None = None) -> None:
        """Give simulations `ids` (all if None) of the plant their own model fields (MjModel names, arrays of shape
        (len(ids), ...); see BatchPlant.set_fields), before (re)starting them: a new episode's perturbed plant."""
        self._plant.set_fields(fields, ids)

    # -- control -------------------------------------------------------------------------------------------------

    def _check(self, references: Sequence[Reference], *, one_length: bool = True) -> None:
        if len(references) == 0:
            raise InvalidInputError("references: expected at least one reference, got none")
        shape = (references[0].steps, references[0].n)
        for ref in references:
            if one_length and (ref.steps, ref.n) != shape:
                raise InvalidInputError(f"references: expected all of shape N={shape[0]}, n={shape[1]}; "
                                        f"{ref.planner!r} has N={ref.steps}, n={ref.n}")
            if ref.n != self.model.nv:
                raise InvalidInputError(f"references: expected {self.model.nv} joints, got {ref.n}")
            if abs(ref.dt - self.dt) > 1e-12:
                raise InvalidInputError(f"references: expected the control period dt={self.dt} s of the model, "
                                        f"got {ref.dt} s from {ref.planner!r}")

    def _prepare(self, references: Sequence[Reference], count: int, noise: npt.ArrayLike | None
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None,
                            NDArray[np.float64] | None, NDArray[np.intp]]:
        """q_ref, qd_ref (N+1, count, n), the feedforward (N, count, n), the checked noise and the reference
        accelerations (N, count, n; None unless the control law reads them) of `references`, and each one's N,
        shape (count,). References of several lengths are padded to the longest N (`_LoopState`)."""
        self._check(references, one_length=False)
        if len(references) != count:
            raise InvalidInputError(f"references: expected {count} (one per simulation), got {len(references)}")
        lengths = np.array([r.steps for r in references], dtype=np.intp)
        longest, n = int(lengths.max()), self.model.nv
        mixed = bool(np.any(lengths != lengths[0]))
        if mixed and self.previews:
            raise InvalidInputError(f"references: {self._previewer} previews the "
                                    "reference; give it references of one length per batch, got N from "
                                    f"{lengths.min()} to {lengths.max()}")
        checked = None
        if noise is not None:
            checked = np.asarray(noise, dtype=np.float64)
            if checked.shape != (longest, count, 2 * n) or not np.all(np.isfinite(checked)):
                which = " (the longest reference's N)" if mixed else ""
                raise InvalidInputError(f"noise: expected finite values of shape ({longest}, {count}, {2 * n})"
                                        f"{which}, got shape {checked.shape}")
        q_ref, qd_ref, ff, qdd = (self._prepare_mixed(references, lengths) if mixed
                                  else self._prepare_one(references))
        return q_ref, qd_ref, ff, checked, qdd, lengths

    def _prepare_mixed(self, references: Sequence[Reference], lengths: NDArray[np.intp]
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                                  NDArray[np.float64] | None]:
        """`_prepare_one` of each length's references, padded to the longest N (`_padded`) and put back in order."""
        longest, count, n = int(lengths.max()), len(references), self.model.nv
        q_ref, qd_ref = np.empty((longest + 1, count, n)), np.empty((longest + 1, count, n))
        ff, qdd = np.empty((longest, count, n)), None
        for length in np.unique(lengths):
            rows = np.flatnonzero(lengths == length)
            q, qd, f, a = self._prepare_one([references[int(i)] for i in rows])
            q, qd, f, a, _ = _padded(longest, q, qd, f, a, None)
            q_ref[:, rows], qd_ref[:, rows], ff[:, rows] = q, qd, f
            if a is not None:
                qdd = np.empty((longest, count, n)) if qdd is None else qdd
                qdd[:, rows] = a
        return q_ref, qd_ref, ff, qdd

    def _prepare_one(self, references: Sequence[Reference]
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                                NDArray[np.float64] | None]:
        """q_ref, qd_ref, the feedforward and the reference accelerations (`_prepare`) of references of one
        length."""
        q_ref = np.stack([r.q for r in references], axis=1)
        qd_ref = np.stack([r.qd for r in references], axis=1)
        unique = {id(r): r for r in references}  # a reference shared by many simulations is computed once
        if self._probe is None:
            self._probe = DynamicsProbe(self.model, size=q_ref.shape[0] * len(unique))
        ff_unique = feedforward_many(self.model, list(unique.values()), mode=self.config.feedforward,
                                     accel=self.config.ff_accel, probe=self._probe)
        column = {key: b for b, key in enumerate(unique)}
        ff = ff_unique[:, [column[id(r)] for r in references]]
        reads = self._law.needs_dynamics or self._stateful or any(
            law.needs_dynamics or _stateful(law) for law in self._teachers.values())
        qdd = reference_accelerations(references, self.config.ff_accel) if reads else None
        return q_ref, qd_ref, ff, qdd

    def start(self, references: Sequence[Reference], *, noise: npt.ArrayLike | None = None,
              sensor: npt.ArrayLike = 0.0) -> None:
        """(Re)start every simulation at its reference's first sample, with I_{-1} = 0.

        Args:
          references: one per simulation, of the model's dt; of one length N, or of several for a law that does not
            preview the reference (each simulation ends at its own N, `ends`).
          noise: measurement noise added to [q; qd] before control, shape (N, B, 2n) in rad and rad/s (N the
            longest reference's); None for exact measurements.
          sensor: the standard deviation of the position noise declared to the control law, rad, one for all or
            (B,) (0: exact measurements); a law may design its estimator for it (the predictive laws' filter,
            `mjtraj.core.estimator`), none reads `noise` itself.
        """
        declared = self._declared(sensor, self.nsim)
        q_ref, qd_ref, ff, checked, qdd, lengths = self._prepare(references, self.nsim, noise)
        N, B, n = ff.shape
        records: dict[str, NDArray[Any]] = {name: np.full((N, B, n), np.nan) for name in RECORDED}
        records["saturated"] = np.zeros((N, B, n), dtype=bool)
        self._state = _LoopState(q_ref, qd_ref, ff, qdd, np.zeros(B, dtype=np.intp), np.zeros((B, n)),
                                 np.full(B, -1, dtype=np.int64), records, np.full((B, n), np.nan),
                                 np.full((B, n), np.nan), noise=checked,
                                 held=np.zeros((B, n)) if self.config.delay else None,
                                 law_state=self._initial_law_state(B), ends=lengths,
                                 teachers={name: _TeacherState(np.zeros((B, n)), _initial_state(law, B))
                                           for name, law in self._teachers.items()})
        self._track(slice(None), q_ref, qd_ref, ff, references, declared)
        self._plant.reset(q_ref[0], qd_ref[0])

    def restart(self, ids: npt.ArrayLike, references: Sequence[Reference], *,
                noise: npt.ArrayLike | None = None, sensor: npt.ArrayLike = 0.0) -> None:
        """Restart simulations `ids` (the vector env's autoreset) on `references`; the others go on. Restarting every
        simulation on references of another N starts the batch afresh (`start`); restarting some on references of
        another length runs references of several lengths side by side (`start`), which a law that previews the
        reference refuses.

        Args:
          noise: as in `start`, shape (N, len(ids), 2n) (N the longest of `references`).
          sensor: as in `start`, one for all or (len(ids),).
        """
        s = self._running()
        rows = np.asarray(ids, dtype=np.intp).reshape(-1)
        declared = self._declared(sensor, rows.size)
        if (len(references) and references[0].steps != s.steps
                and np.array_equal(np.sort(rows), np.arange(self.nsim))):
            order = np.argsort(rows)
            self.start([references[i] for i in order], noise=None if noise is None else np.asarray(noise)[:, order],
                       sensor=declared[order])
            return
        q_ref, qd_ref, ff, checked, qdd, lengths = self._prepare(references, rows.size, noise)
        if q_ref.shape[0] != s.q_ref.shape[0] and self.previews:
            raise InvalidInputError(f"references: {self._previewer} previews the reference; "
                                    f"a restart needs references of the running N={s.steps}, got "
                                    f"N={q_ref.shape[0] - 1}; start all simulations instead")
        if q_ref.shape[0] > s.q_ref.shape[0]:
            _lengthen(s, q_ref.shape[0] - 1)
        elif q_ref.shape[0] < s.q_ref.shape[0]:
            q_ref, qd_ref, ff, qdd, checked = _padded(s.steps, q_ref, qd_ref, ff, qdd, checked)
        N, n = s.steps, self.model.nv
        s.desync()
        where = slice(None) if np.array_equal(rows, s.rows) else rows  # all of them, in order: slices are faster
        s.q_ref[:, where], s.qd_ref[:, where], s.tau_ff[:, where] = q_ref, qd_ref, ff
        if s.qdd_ref is not None:
            s.qdd_ref[:, where] = qdd
        s.k[where], s.integral[where], s.diverged_step[where] = 0, 0.0, -1
        for name, record in s.records.items():
            record[:, where] = False if name == "saturated" else np.nan
        s.q_final[where] = s.qd_final[where] = np.nan
        if checked is not None or s.noise is not None:
            if s.noise is None:
                s.noise = np.zeros((N, self.nsim, 2 * n))
            s.noise[:, where] = 0.0 if checked is None else checked
        if s.held is not None:
            s.held[where] = 0.0
        if s.law_state is not None:
            s.law_state[where] = self._initial_law_state(rows.size)
        for name, taught in s.teachers.items():
            taught.integral[where] = 0.0
            if taught.law_state is not None:
                taught.law_state[where] = _initial_state(self._teachers[name], rows.size)
            taught.answered = None
        s.set_ends(where, lengths)
        s.resync()
        self._track(where, q_ref, qd_ref, ff, references, declared)
        self._plant.reset(q_ref[0], qd_ref[0], rows)

    def step(self, *, residual: NDArray[np.float64] | None = None,
             override: NDArray[np.float64] | None = None) -> Step:
        """Advance every simulation by one control period (shapes (B, n) for residual/override, N m).

        A simulation past its last period, or diverged, gets zero corrective torque (it coasts under gravity
        compensation; a diverged one was stopped at its last pose) and records nothing more.
        """
        s = self._running()
        plant = self._plant
        n = self.model.nv
        if s.sync is not None and s.sync < s.horizon:  # every simulation live and at one period: views, no masks
            k = s.sync
            rec = s.records
            q, qd = rec["q"][k], rec["qd"][k]
            q[:], qd[:] = plant.qpos, plant.qvel
            e = np.subtract(s.q_ref[k], q, out=rec["e"][k])
            ed = np.subtract(s.qd_ref[k], qd, out=rec["ed"][k])
            if s.noise is None:
                out = self._control(e, ed, q, qd, s.integral, s.tau_ff[k],
                                    None if s.qdd_ref is None else s.qdd_ref[k], residual, override, s.law_state)
            else:
                out = self._control(e - s.noise[k, :, :n], ed - s.noise[k, :, n:], q + s.noise[k, :, :n],
                                    qd + s.noise[k, :, n:], s.integral, s.tau_ff[k],
                                    None if s.qdd_ref is None else s.qdd_ref[k], residual, override, s.law_state)
            s.integral = out.integral
            s.law_state = out.state
            if s.teachers:
                self._advance_teachers(None, out.dtau)
            if s.held is not None:
                out = out._replace(dtau=self._delayed(out.dtau, slice(None)))
            plant.step(out.dtau)
            rec["tau_ff"][k], rec["tau_fb"][k], rec["dtau"][k], rec["saturated"][k] = (
                out.tau_ff, out.tau_fb, out.dtau, out.saturated)
            if k + 1 == s.horizon:
                if s.uniform:
                    s.q_final[:], s.qd_final[:] = plant.qpos, plant.qvel
                else:
                    last = s.ends == k + 1
                    s.q_final[last], s.qd_final[last] = plant.qpos[last], plant.qvel[last]
            s.sync = k + 1
            error = s.q_ref[k + 1] - plant.qpos
            if np.abs(error).max() <= self.config.divergence_bound:  # False for NaN too
                return Step(q, qd, e, ed, out, self._none_diverged)
            bad = ~np.all(np.abs(error) <= self.config.divergence_bound, axis=1)
            self._diverge(bad, np.full(self.nsim, k), q, qd)
            return Step(q, qd, e, ed, out, s.diverged_step >= 0)
        s.desync()
        q, qd = plant.state()
        active = (s.diverged_step < 0) & (s.k < s.ends)
        ks = np.minimum(s.k, s.ends - 1)
        e = s.q_ref[ks, s.rows] - q
        ed = s.qd_ref[ks, s.rows] - qd
        seen_e, seen_ed = (e, ed) if s.noise is None else (e - s.noise[ks, s.rows, :n], ed - s.noise[ks, s.rows, n:])
        seen_q, seen_qd = (q, qd) if s.noise is None else (q + s.noise[ks, s.rows, :n], qd + s.noise[ks, s.rows, n:])
        out = self._control(seen_e, seen_ed, seen_q, seen_qd, s.integral, s.tau_ff[ks, s.rows],
                            None if s.qdd_ref is None else s.qdd_ref[ks, s.rows], residual, override, s.law_state)
        dtau = np.where(active[:, None], out.dtau, 0.0)
        if s.teachers:
            self._advance_teachers(active, out.dtau)
        if s.held is not None:
            dtau = np.where(active[:, None], self._delayed(dtau, active), 0.0)
        s.integral = np.where(active[:, None], out.integral, s.integral)
        if s.law_state is not None and out.state is not None:
            s.law_state = np.where(active[:, None], out.state, s.law_state)
        plant.step(dtau)
        control = ControlOutput(out.tau_ff, out.tau_fb, dtau, out.saturated & active[:, None], out.integral)
        live, kl = s.rows[active], ks[active]
        for name, value in zip(RECORDED, (q, qd, e, ed, control.tau_ff, control.tau_fb, dtau, control.saturated),
                               strict=True):
            s.records[name][kl, live] = value[active]
        error = s.q_ref[np.minimum(s.k + 1, s.ends), s.rows] - plant.qpos
        bad = active & ~np.all(np.abs(error) <= self.config.divergence_bound, axis=1)
        s.k[:] = np.where(active, s.k + 1, s.k)
        ended = active & (s.k == s.ends)
        s.q_final[ended], s.qd_final[ended] = plant.qpos[ended], plant.qvel[ended]
        self._diverge(bad, ks, q, qd)
        s.resync()
        return Step(q, qd, e, ed, control, s.diverged_step >= 0)

    def _control(self, e: NDArray[np.float64], ed: NDArray[np.float64], q: NDArray[np.float64],
                 qd: NDArray[np.float64], integral: NDArray[np.float64], tau_ff: NDArray[np.float64],
                 qdd_ref: NDArray[np.float64] | None, residual: NDArray[np.float64] | None,
                 override: NDArray[np.float64] | None, law_state: NDArray[np.float64] | None, *,
                 law: Controller | None = None) -> ControlOutput:
        """A control law (the configured one, or a teacher `law`) on what the controller sees (errors, measured
        state q, qd), shapes (B, n)."""
        dynamics = None
        probe = self._dynamics if law is None else self._teacher_dynamics
        law = self._law if law is None else law
        if probe is not None and override is None and law.needs_dynamics:
            dynamics = probe.mass_and_bias(q, qd)
        if law_state is None:
            return law(e, ed, integral, tau_ff, qdd_ref, dynamics, self._limit, self.dt, residual=residual,
                       override=override)
        return law(e, ed, integral, tau_ff, qdd_ref, dynamics, self._limit, self.dt,  # type: ignore[call-arg]
                   residual=residual, override=override, state=law_state, q=q, qd=qd)

    # -- teachers ------------------------------------------------------------------------------------------------

    @property
    def teachers(self) -> tuple[str, ...]:
        """The control laws that shadow the loop's own (`teach`)."""
        return tuple(self._teachers)

    def teach(self, name: str) -> ControlOutput:
        """What teacher `name` commands this period for every simulation, at what the loop's law measures now
        (noise included): its ControlOutput, shapes (B, n) (dtau the saturated command, N m; `state` its state
        after the period). Repeated calls in one period give the same answer; the teacher's state advances when the
        loop steps. A simulation that has ended or diverged gets its last period's inputs (its answer is unused).

        Raises:
          InvalidInputError: `name` is not one of `teachers`, or the loop has not started.
        """
        if name not in self._teachers:
            raise InvalidInputError(f"name: expected one of the loop's teachers ({', '.join(self._teachers) or 'none'})"
                                    f", got {name!r}")
        s = self._running()
        taught = s.teachers[name]
        ks = np.minimum(s.periods, s.ends - 1)
        if taught.answered is not None and np.array_equal(taught.answered[0], ks):
            return taught.answered[1]
        n = self.model.nv
        q, qd = self._plant.state()
        e = s.q_ref[ks, s.rows] - q
        ed = s.qd_ref[ks, s.rows] - qd
        if s.noise is not None:
            noise = s.noise[ks, s.rows]
            e, ed, q, qd = e - noise[:, :n], ed - noise[:, n:], q + noise[:, :n], qd + noise[:, n:]
        out = self._control(e, ed, q, qd, taught.integral, s.tau_ff[ks, s.rows],
                            None if s.qdd_ref is None else s.qdd_ref[ks, s.rows], None, None, taught.law_state,
                            law=self._teachers[name])
        taught.answered = (ks, out)
        return out

    def _advance_teachers(self, active: NDArray[np.bool_] | None, applied: NDArray[np.float64]) -> None:
        """Every teacher's integral and state after this period (`active` (B,): the simulations that ran it, None:
        all): its own, but for a law with `applied_state` (the predictive laws' prediction), which counts the loop's
        command `applied` (B, n), N m, before any actuation delay, as the law's own loop counts a residual."""
        s = self._running()
        for name, taught in s.teachers.items():
            out = self.teach(name)
            heard = getattr(self._teachers[name], "applied_state", None)
            if heard is not None and out.state is not None:
                out = out._replace(state=heard(out.state, out.dtau, applied))
            if active is None:
                taught.integral, taught.law_state = out.integral, out.state
            else:
                taught.integral = np.where(active[:, None], out.integral, taught.integral)
                if taught.law_state is not None and out.state is not None:
                    taught.law_state = np.where(active[:, None], out.state, taught.law_state)
            taught.answered = None

    def _track(self, rows: slice | NDArray[np.intp], q_ref: NDArray[np.float64], qd_ref: NDArray[np.float64],
               ff: NDArray[np.float64], references: Sequence[Reference], declared: NDArray[np.float64]) -> None:
        """Give a law that previews the reference (one with `track`, the model-predictive ones) the references of
        simulations `rows`: q_ref, qd_ref (N+1, R, n), the feedforward (N, R, n); where they end with a settle
        window (`mjtraj.core.settle.held`), its periods (R,) as `windows`; where a sensor is declared noisy, the
        declared standard deviations `declared` (R,), rad, as `sensors`."""
        windows = np.array([int(r.info.get("settle_steps", 0)) for r in references], dtype=np.intp)
        extra: dict[str, NDArray[Any]] = {}
        if windows.any():
            extra["windows"] = windows
        if declared.any():
            extra["sensors"] = declared
        for law in (self._law, *self._teachers.values()):
            track = getattr(law, "track", None)
            if track is not None:
                track(rows, q_ref, qd_ref, ff, **_accepted(track, extra))

    @staticmethod
    def _declared(sensor: npt.ArrayLike, count: int) -> NDArray[np.float64]:
        """The declared sensors' standard deviations (count,), rad, from one for all or one each.

        Raises:
          InvalidInputError: not finite numbers >= 0 of that shape.
        """
        value = vector("sensor", sensor, count)
        if np.any(value < 0):
            raise InvalidInputError(f"sensor: expected standard deviations >= 0 (rad), got {value.tolist()}")
        return value

    def _initial_law_state(self, rows: int) -> NDArray[np.float64] | None:
        """A stateful law's initial state for `rows` simulations, (rows, state_size); None for other laws."""
        return self._law.initial_state(rows) if self._stateful else None  # type: ignore[attr-defined,no-any-return]

    def set_law_state(self, state: npt.ArrayLike, ids: npt.ArrayLike | None = None) -> None:
        """Set a stateful law's state of simulations `ids` (all if None), shape (len(ids), state_size), after their
        (re)start: an oracle that starts the adaptive law at the true parameters.

        Raises:
          InvalidInputError: the law has no state, or `state` has the wrong shape or non-finite values.
        """
        s = self._running()
        if s.law_state is None:
            raise InvalidInputError(f"state: the control law {self.config.controller!r} has no state to set")
        rows = s.rows if ids is None else np.asarray(ids, dtype=np.intp).reshape(-1)
        value = np.asarray(state, dtype=np.float64)
        if value.shape != (rows.size, s.law_state.shape[1]) or not np.all(np.isfinite(value)):
            raise InvalidInputError(f"state: expected finite values of shape ({rows.size}, {s.law_state.shape[1]}), "
                                    f"got shape {value.shape}")
        s.law_state[rows] = value

    def law_state(self) -> NDArray[np.float64] | None:
        """Each simulation's state of a stateful law now, (B, state_size) (the adaptive law's estimate: payload kg,
        damping N m s/rad and friction N m per joint); None for a law without state (read-only use)."""
        return self._running().law_state

    def _delayed(self, command: NDArray[np.float64], rows: slice | NDArray[np.bool_]) -> NDArray[np.float64]:
        """The delayed actuator: apply the held torque of `rows`, hold `command` for the next period."""
        s = self._running()
        assert s.held is not None
        applied = s.held.copy()
        s.held[rows] = command[rows]
        return applied

    def _diverge(self, bad: NDArray[np.bool_], k: NDArray[np.intp], q: NDArray[np.float64],
                 qd: NDArray[np.float64]) -> None:
        """Mark simulations `bad` diverged at period k, stop them at their last pose, blank what they recorded."""
        if not bad.any():
            return
        s = self._running()
        s.desync()
        rows = np.flatnonzero(bad)
        s.diverged_step[rows] = k[rows]
        s.k[rows] = s.ends[rows]
        s.q_final[rows] = s.qd_final[rows] = np.nan
        self._plant.reset(q[rows], np.zeros_like(qd[rows]), rows)

    def rollout(self, ids: npt.ArrayLike | None = None) -> Rollout:
        """What simulations `ids` (all if None) recorded since their start, as a Rollout (rows in `ids` order); they
        run references of one length.

        Raises:
          InvalidInputError: `ids` run references of several lengths (read each length's apart: `ends`).
        """
        s = self._running()
        rows = s.rows if ids is None else np.asarray(ids, dtype=np.intp).reshape(-1)
        ends = s.ends[rows]
        N = int(ends[0]) if rows.size else s.steps
        if np.any(ends != N):
            raise InvalidInputError(f"ids: expected simulations running references of one length, got N from "
                                    f"{ends.min()} to {ends.max()}")
        rec = {name: s.records[name][:N].swapaxes(0, 1)[rows] for name in RECORDED}  # one copy each, C-ordered
        q_final, qd_final = s.q_final[rows].copy(), s.qd_final[rows].copy()
        return Rollout(**rec, q_final=q_final, qd_final=qd_final, e_final=s.q_ref[ends, rows] - q_final,
                       diverged_step=s.diverged_step[rows].copy(), dt=self.dt)

    def run(self, references: Sequence[Reference], *, noise: npt.ArrayLike | None = None,
            sensor: npt.ArrayLike = 0.0) -> Rollout:
        """Execute one reference per simulation from its first sample to its end; all share N and dt.

        `noise`: measurement noise, shape (N, B, 2n), and `sensor` its declared standard deviation, as in `start`.
        """
        self._check(references)
        self.start(references, noise=noise, sensor=sensor)
        for _ in range(self.steps):
            self.step()
        return self.rollout()


def _accepted(track: Any, extra: dict[str, NDArray[Any]]) -> dict[str, NDArray[Any]]:
    """`extra` without `sensors` for a `track` that does not take it (a plug-in law written before sensors were
    declared ignores them); `windows` always (a law that previews the reference must plan through the window)."""
    import inspect

    if "sensors" not in extra:
        return extra
    parameters = inspect.signature(track).parameters
    if "sensors" in parameters or any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values()):
        return extra
    return {k: v for k, v in extra.items() if k != "sensors"}


def _stateful(law: Controller) -> bool:
    """The law keeps state per simulation (`state_size` > 0)."""
    return int(getattr(law, "state_size", 0)) > 0


def _initial_state(law: Controller, rows: int) -> NDArray[np.float64] | None:
    """A stateful law's initial state for `rows` simulations, else None."""
    return law.initial_state(rows) if _stateful(law) else None  # type: ignore[attr-defined,no-any-return]


def _padded(steps: int, q_ref: NDArray[np.float64], qd_ref: NDArray[np.float64], ff: NDArray[np.float64],
            qdd: NDArray[np.float64] | None, noise: NDArray[np.float64] | None
            ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None,
                       NDArray[np.float64] | None]:
    """Shorter references' arrays padded to `steps` periods: the reference and feedforward held at their last
    sample, no acceleration, no noise (never read past their end but by queries held there)."""
    extra = steps - ff.shape[0]
    q_ref = np.concatenate([q_ref, np.repeat(q_ref[-1:], extra, axis=0)])
    qd_ref = np.concatenate([qd_ref, np.repeat(qd_ref[-1:], extra, axis=0)])
    ff = np.concatenate([ff, np.repeat(ff[-1:], extra, axis=0)])
    if qdd is not None:
        qdd = np.concatenate([qdd, np.zeros((extra, *qdd.shape[1:]))])
    if noise is not None:
        noise = np.concatenate([noise, np.zeros((extra, *noise.shape[1:]))])
    return q_ref, qd_ref, ff, qdd, noise


def _lengthen(s: _LoopState, steps: int) -> None:
    """Give a running state room for references of `steps` periods (`_padded`; records NaN, not saturated)."""
    extra = steps - s.steps
    s.q_ref, s.qd_ref, s.tau_ff, s.qdd_ref, s.noise = _padded(steps, s.q_ref, s.qd_ref, s.tau_ff, s.qdd_ref, s.noise)
    for name, record in s.records.items():
        more = (np.zeros((extra, *record.shape[1:]), dtype=bool) if name == "saturated"
                else np.full((extra, *record.shape[1:]), np.nan))
        s.records[name] = np.concatenate([record, more])
    s.horizon = int(s.ends.min())
