"""The closed loop of DESIGN §3, once: plant + feedforward + PID, batched; the executor, env and sweeps use it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import mujoco
import numpy as np
import numpy.typing as npt
from numpy.typing import NDArray

from mjtraj._validate import choice, positive, positive_int
from mjtraj.controller import ANTI_WINDUP, ControlOutput, PIDGains, control_law
from mjtraj.dynamics import DynamicsProbe
from mjtraj.exceptions import InvalidInputError
from mjtraj.feedforward import FEEDFORWARD_ACCEL, FEEDFORWARD_MODES, feedforward_many
from mjtraj.model import JointInfo
from mjtraj.plant import GRAVITY_COMP, BatchPlant
from mjtraj.reference import Reference
from mjtraj.rollout import Rollout


@dataclass(frozen=True)
class LoopConfig:
    """Everything about the controller that is held identical across planners.

    Attributes:
      gains: the PID gains.
      feedforward: 'inverse' | 'planned' | 'none' (see `mjtraj.feedforward.feedforward`).
      ff_accel: 'sample' | 'step_average'.
      gravity_comp: 'native' | 'zoh' (see `BatchPlant`).
      anti_windup: 'none' | 'clamp'.
      substeps: integrator steps per control period.
      divergence_bound: |e| above this (rad) on any joint marks a scenario diverged.
      delay: actuation delay in control periods, 0 or 1: with 1 the plant receives in period k the torque
        computed in period k-1 (zero in period 0).
    """

    gains: PIDGains
    feedforward: str = "inverse"
    ff_accel: str = "sample"
    gravity_comp: str = "native"
    anti_windup: str = "none"
    substeps: int = 1
    divergence_bound: float = float(np.pi)
    delay: int = 0

    def __post_init__(self) -> None:
        choice("feedforward", self.feedforward, FEEDFORWARD_MODES)
        choice("ff_accel", self.ff_accel, FEEDFORWARD_ACCEL)
        choice("gravity_comp", self.gravity_comp, GRAVITY_COMP)
        choice("anti_windup", self.anti_windup, ANTI_WINDUP)
        positive_int("substeps", self.substeps)
        positive("divergence_bound", self.divergence_bound)
        if self.delay not in (0, 1) or isinstance(self.delay, bool):
            raise InvalidInputError(f"delay: expected 0 or 1 control periods, got {self.delay!r}")


RECORDED = ("q", "qd", "e", "ed", "tau_ff", "tau_fb", "dtau", "saturated")


@dataclass
class LoopState:
    """Per-simulation progress of a running loop (mutable; owned by ClosedLoop). Arrays are time-major.

    q_ref, qd_ref: shape (N+1, B, n); tau_ff: (N, B, n); integral: (B, n), rad s; noise: measurement
    noise (N, B, 2n) added to [q; qd] before control, or None; held: the torque the delayed actuator applies
    next, (B, n), or None without delay; diverged_step: (B,), -1 while running; records: name -> (N, B, n)
    for each of RECORDED (NaN where not reached); q_final, qd_final: (B, n) state after period N-1 (NaN until
    then).
    sync: the common next period while every simulation is live and in step (the fast path), else None; k:
    (B,) each simulation's next period, kept only while sync is None (read `periods`).
    """

    q_ref: NDArray[np.float64]
    qd_ref: NDArray[np.float64]
    tau_ff: NDArray[np.float64]
    k: NDArray[np.intp]
    integral: NDArray[np.float64]
    diverged_step: NDArray[np.int64]
    records: dict[str, NDArray[Any]]
    q_final: NDArray[np.float64]
    qd_final: NDArray[np.float64]
    noise: NDArray[np.float64] | None = None
    held: NDArray[np.float64] | None = None
    sync: int | None = 0
    rows: NDArray[np.intp] = field(init=False)

    def __post_init__(self) -> None:
        self.rows = np.arange(self.k.size)

    @property
    def steps(self) -> int:
        """N, the number of control periods."""
        return self.tau_ff.shape[0]

    @property
    def periods(self) -> NDArray[np.intp]:
        """Each simulation's next control period, shape (B,); N once it has ended or diverged."""
        return np.full(self.k.size, self.sync, dtype=np.intp) if self.sync is not None else self.k.copy()

    def desync(self) -> None:
        """Leave the fast path: write the common period into k."""
        if self.sync is not None:
            self.k[:] = self.sync
            self.sync = None

    def resync(self) -> None:
        """Re-enter the fast path when every simulation is live and at the same period."""
        k = self.k
        self.sync = int(k[0]) if np.all(k == k[0]) and np.all(self.diverged_step < 0) else None


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
    """B scenarios of the plant under feedforward + PID, advanced one control period at a time.

    `model` is the nominal model (planner, feedforward, zoh gravity); `plant` the simulated one (default: the
    nominal one), with per-simulation `plant_fields` (see BatchPlant). Use `run` for whole references, or
    `start` then `step` (the env does) to act in between.

    The records hold the true state and error (the metrics score them); with measurement noise the controller
    sees the noisy ones. With an actuation delay, `dtau` records the torque the plant received.
    """

    def __init__(self, model: mujoco.MjModel, config: LoopConfig, *, nsim: int = 1,
                 plant: mujoco.MjModel | None = None, plant_fields: dict[str, NDArray[np.float64]] | None = None,
                 nthread: int = 0) -> None:
        self.model = model
        self.config = config
        self.dt = float(model.opt.timestep)
        self.limit = JointInfo.of(model).torque_limit
        self.plant = BatchPlant(plant if plant is not None else model, nsim, nominal=model,
                                gravity_comp=config.gravity_comp, substeps=config.substeps, nthread=nthread,
                                fields=plant_fields)
        self.state: LoopState | None = None
        self._gains = config.gains.tiled(nsim)
        self._limit = np.tile(self.limit, (nsim, 1))
        self._none_diverged = np.zeros(nsim, dtype=bool)
        self._none_diverged.setflags(write=False)
        self._probe: DynamicsProbe | None = None

    @property
    def nsim(self) -> int:
        """B, the number of simulations."""
        return self.plant.nsim

    def _check(self, references: Sequence[Reference]) -> None:
        if len(references) == 0:
            raise InvalidInputError("references: expected at least one reference, got none")
        shape = (references[0].steps, references[0].n)
        for ref in references:
            if (ref.steps, ref.n) != shape:
                raise InvalidInputError(f"references: expected all of shape N={shape[0]}, n={shape[1]}; "
                                        f"{ref.planner!r} has N={ref.steps}, n={ref.n}")
            if ref.n != self.model.nv:
                raise InvalidInputError(f"references: expected {self.model.nv} joints, got {ref.n}")
            if abs(ref.dt - self.dt) > 1e-12:
                raise InvalidInputError(f"references: expected the control period dt={self.dt} s of the model, "
                                        f"got {ref.dt} s from {ref.planner!r}")

    def start(self, references: Sequence[Reference], ids: npt.ArrayLike | None = None, *,
              noise: npt.ArrayLike | None = None) -> LoopState:
        """(Re)start simulations `ids` (all if None) at their references' first sample, with I_{-1} = 0.

        A restart of some simulations (the vector env's autoreset) needs references of the running N.

        Args:
          noise: measurement noise added to [q; qd] before control, shape (N, len(ids), 2n) in rad and rad/s;
            None for exact measurements.
        """
        self._check(references)
        rows = np.arange(self.nsim) if ids is None else np.asarray(ids, dtype=np.intp).reshape(-1)
        if len(references) != rows.size:
            raise InvalidInputError(f"references: expected {rows.size} (one per simulation), got {len(references)}")
        q_ref = np.stack([r.q for r in references], axis=1)
        qd_ref = np.stack([r.qd for r in references], axis=1)
        unique = {id(r): r for r in references}  # a reference shared by many simulations is computed once
        if self._probe is None:
            self._probe = DynamicsProbe(self.model, size=q_ref.shape[0] * len(unique))
        ff_unique = feedforward_many(self.model, list(unique.values()), mode=self.config.feedforward,
                                     accel=self.config.ff_accel, probe=self._probe)
        column = {key: b for b, key in enumerate(unique)}
        ff = ff_unique[:, [column[id(r)] for r in references]]
        N, n = ff.shape[0], self.model.nv
        if noise is not None:
            noise = np.asarray(noise, dtype=np.float64)
            if noise.shape != (N, rows.size, 2 * n) or not np.all(np.isfinite(noise)):
                raise InvalidInputError(f"noise: expected finite values of shape ({N}, {rows.size}, {2 * n}), "
                                        f"got shape {noise.shape}")
        s = self.state
        if s is None or ids is None or s.q_ref.shape[0] != q_ref.shape[0]:
            if ids is not None and rows.size != self.nsim:
                raise InvalidInputError(f"ids: a loop must first be started on all {self.nsim} simulations "
                                        f"with references of one length; got {rows.size} simulations")
            B = self.nsim
            records: dict[str, NDArray[Any]] = {name: np.full((N, B, n), np.nan) for name in RECORDED}
            records["saturated"] = np.zeros((N, B, n), dtype=bool)
            self.state = s = LoopState(q_ref, qd_ref, ff, np.zeros(B, dtype=np.intp), np.zeros((B, n)),
                                       np.full(B, -1, dtype=np.int64), records, np.full((B, n), np.nan),
                                       np.full((B, n), np.nan), noise=noise,
                                       held=np.zeros((B, n)) if self.config.delay else None)
        else:
            s.desync()
            s.q_ref[:, rows], s.qd_ref[:, rows], s.tau_ff[:, rows] = q_ref, qd_ref, ff
            s.k[rows], s.integral[rows], s.diverged_step[rows] = 0, 0.0, -1
            for name, record in s.records.items():
                record[:, rows] = False if name == "saturated" else np.nan
            s.q_final[rows] = s.qd_final[rows] = np.nan
            if noise is not None or s.noise is not None:
                if s.noise is None:
                    s.noise = np.zeros((N, self.nsim, 2 * n))
                s.noise[:, rows] = 0.0 if noise is None else noise
            if s.held is not None:
                s.held[rows] = 0.0
            s.resync()
        self.plant.reset(q_ref[0], qd_ref[0], None if ids is None else rows)
        return s

    def step(self, *, residual: NDArray[np.float64] | None = None,
             override: NDArray[np.float64] | None = None) -> Step:
        """Advance every simulation by one control period (shapes (B, n) for residual/override, N m).

        A simulation past its last period, or diverged, gets zero corrective torque (it coasts under gravity
        compensation; a diverged one was stopped at its last pose) and records nothing more.
        """
        s = self.state
        if s is None:
            raise InvalidInputError("step: call start(references) first")
        N, n = s.steps, self.model.nv
        if s.sync is not None and s.sync < N:  # every simulation live and at the same period: views, no masks
            k = s.sync
            rec = s.records
            q, qd = rec["q"][k], rec["qd"][k]
            q[:], qd[:] = self.plant.qpos, self.plant.qvel
            e = np.subtract(s.q_ref[k], q, out=rec["e"][k])
            ed = np.subtract(s.qd_ref[k], qd, out=rec["ed"][k])
            if s.noise is None:
                out = control_law(e, ed, s.integral, s.tau_ff[k], self._gains, self._limit, self.dt,
                                  anti_windup=self.config.anti_windup, residual=residual, override=override)
            else:
                out = control_law(e - s.noise[k, :, :n], ed - s.noise[k, :, n:], s.integral, s.tau_ff[k],
                                  self._gains, self._limit, self.dt, anti_windup=self.config.anti_windup,
                                  residual=residual, override=override)
            s.integral = out.integral
            if s.held is not None:
                out = out._replace(dtau=self._delayed(out.dtau, slice(None)))
            self.plant.step(out.dtau)
            rec["tau_ff"][k], rec["tau_fb"][k], rec["dtau"][k], rec["saturated"][k] = (
                out.tau_ff, out.tau_fb, out.dtau, out.saturated)
            if k + 1 == N:
                s.q_final[:], s.qd_final[:] = self.plant.qpos, self.plant.qvel
            s.sync = k + 1
            error = s.q_ref[k + 1] - self.plant.qpos
            if np.abs(error).max() <= self.config.divergence_bound:  # False for NaN too
                return Step(q, qd, e, ed, out, self._none_diverged)
            bad = ~np.all(np.abs(error) <= self.config.divergence_bound, axis=1)
            self._diverge(bad, np.full(self.nsim, k), q, qd)
            return Step(q, qd, e, ed, out, s.diverged_step >= 0)
        s.desync()
        q, qd = self.plant.state()
        active = (s.diverged_step < 0) & (s.k < N)
        k = np.minimum(s.k, N - 1)
        e = s.q_ref[k, s.rows] - q
        ed = s.qd_ref[k, s.rows] - qd
        seen_e, seen_ed = (e, ed) if s.noise is None else (e - s.noise[k, s.rows, :n], ed - s.noise[k, s.rows, n:])
        out = control_law(seen_e, seen_ed, s.integral, s.tau_ff[k, s.rows], self._gains, self._limit, self.dt,
                          anti_windup=self.config.anti_windup, residual=residual, override=override)
        dtau = np.where(active[:, None], out.dtau, 0.0)
        if s.held is not None:
            dtau = np.where(active[:, None], self._delayed(dtau, active), 0.0)
        s.integral = np.where(active[:, None], out.integral, s.integral)
        self.plant.step(dtau)
        control = ControlOutput(out.tau_ff, out.tau_fb, dtau, out.saturated & active[:, None], out.integral)
        live, kl = s.rows[active], k[active]
        for name, value in zip(RECORDED, (q, qd, e, ed, control.tau_ff, control.tau_fb, dtau, control.saturated),
                               strict=True):
            s.records[name][kl, live] = value[active]
        error = s.q_ref[np.minimum(s.k + 1, N), s.rows] - self.plant.qpos
        bad = active & ~np.all(np.abs(error) <= self.config.divergence_bound, axis=1)
        s.k[:] = np.where(active, s.k + 1, s.k)
        ended = active & (s.k == N)
        s.q_final[ended], s.qd_final[ended] = self.plant.qpos[ended], self.plant.qvel[ended]
        self._diverge(bad, k, q, qd)
        s.resync()
        return Step(q, qd, e, ed, control, s.diverged_step >= 0)

    def _delayed(self, command: NDArray[np.float64], rows: slice | NDArray[np.bool_]) -> NDArray[np.float64]:
        """The delayed actuator: apply the held torque of `rows`, hold `command` for the next period."""
        s = self.state
        assert s is not None and s.held is not None
        applied = s.held.copy()
        s.held[rows] = command[rows]
        return applied

    def _diverge(self, bad: NDArray[np.bool_], k: NDArray[np.intp], q: NDArray[np.float64],
                 qd: NDArray[np.float64]) -> None:
        """Mark simulations `bad` diverged at period k, stop them at their last pose, blank what they recorded."""
        if not bad.any():
            return
        s = self.state
        assert s is not None
        s.desync()
        rows = np.flatnonzero(bad)
        s.diverged_step[rows] = k[rows]
        s.k[rows] = s.steps
        s.q_final[rows] = s.qd_final[rows] = np.nan
        self.plant.reset(q[rows], np.zeros_like(qd[rows]), rows)

    def rollout(self, ids: npt.ArrayLike | None = None) -> Rollout:
        """What simulations `ids` (all if None) recorded since their start, as a Rollout (rows in `ids` order)."""
        s = self.state
        if s is None:
            raise InvalidInputError("rollout: call start(references) first")
        rows = s.rows if ids is None else np.asarray(ids, dtype=np.intp).reshape(-1)
        rec = {name: np.ascontiguousarray(s.records[name][:, rows].swapaxes(0, 1)) for name in RECORDED}
        q_final, qd_final = s.q_final[rows].copy(), s.qd_final[rows].copy()
        return Rollout(**rec, q_final=q_final, qd_final=qd_final, e_final=s.q_ref[s.steps, rows] - q_final,
                       diverged_step=s.diverged_step[rows].copy(), dt=self.dt)

    def run(self, references: Sequence[Reference], *, noise: npt.ArrayLike | None = None) -> Rollout:
        """Execute one reference per simulation from its first sample to its end; all share N and dt.

        `noise`: measurement noise, shape (N, B, 2n), as in `start`.
        """
        state = self.start(references, noise=noise)
        for _ in range(state.steps):
            self.step()
        return self.rollout()
