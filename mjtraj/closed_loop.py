"""The closed loop of DESIGN §3, once: plant + feedforward + PID, batched; the executor, env and sweeps use it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj._validate import choice, positive, positive_int
from mjtraj.controller import ANTI_WINDUP, ControlOutput, PIDGains, control_law
from mjtraj.exceptions import InvalidInputError
from mjtraj.feedforward import FEEDFORWARD_ACCEL, FEEDFORWARD_MODES, feedforward
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
    """

    gains: PIDGains
    feedforward: str = "inverse"
    ff_accel: str = "sample"
    gravity_comp: str = "native"
    anti_windup: str = "none"
    substeps: int = 1
    divergence_bound: float = float(np.pi)

    def __post_init__(self) -> None:
        choice("feedforward", self.feedforward, FEEDFORWARD_MODES)
        choice("ff_accel", self.ff_accel, FEEDFORWARD_ACCEL)
        choice("gravity_comp", self.gravity_comp, GRAVITY_COMP)
        choice("anti_windup", self.anti_windup, ANTI_WINDUP)
        positive_int("substeps", self.substeps)
        positive("divergence_bound", self.divergence_bound)


@dataclass
class LoopState:
    """Per-simulation progress of a running loop (mutable; owned by ClosedLoop).

    q_ref, qd_ref: shape (B, N+1, n); tau_ff: (B, N, n); k: (B,) next period; integral: (B, n), rad s;
    diverged_step: (B,), -1 while running.
    """

    q_ref: NDArray[np.float64]
    qd_ref: NDArray[np.float64]
    tau_ff: NDArray[np.float64]
    k: NDArray[np.intp]
    integral: NDArray[np.float64]
    diverged_step: NDArray[np.int64]
    rows: NDArray[np.intp] = field(init=False)

    def __post_init__(self) -> None:
        self.rows = np.arange(self.k.size)


@dataclass(frozen=True)
class Step:
    """What one period did, for a batch: measured state and errors before control, and the control."""

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
    nominal one). Use `run` for whole references, or `start` then `step` (the env does) to act in between.
    """

    def __init__(self, model: mujoco.MjModel, config: LoopConfig, *, nsim: int = 1,
                 plant: mujoco.MjModel | None = None, nthread: int = 0) -> None:
        self.model = model
        self.config = config
        self.dt = float(model.opt.timestep)
        self.limit = JointInfo.of(model).torque_limit
        self.plant = BatchPlant(plant if plant is not None else model, nsim, nominal=model,
                                gravity_comp=config.gravity_comp, substeps=config.substeps, nthread=nthread)
        self.state: LoopState | None = None

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

    def start(self, references: Sequence[Reference], ids: NDArray[np.intp] | None = None) -> LoopState:
        """(Re)start simulations `ids` (all if None) at their references' first sample, with I_{-1} = 0."""
        self._check(references)
        rows = np.arange(self.nsim) if ids is None else np.asarray(ids, dtype=np.intp)
        if len(references) != rows.size:
            raise InvalidInputError(f"references: expected {rows.size} (one per simulation), got {len(references)}")
        q_ref = np.stack([r.q for r in references])
        qd_ref = np.stack([r.qd for r in references])
        unique = {id(r): r for r in references}  # a reference shared by many simulations is computed once
        ff_of = {key: feedforward(self.model, r, mode=self.config.feedforward, accel=self.config.ff_accel)
                 for key, r in unique.items()}
        ff = np.stack([ff_of[id(r)] for r in references])
        if self.state is None or ids is None or self.state.q_ref.shape[1:] != q_ref.shape[1:]:
            if ids is not None and rows.size != self.nsim:
                raise InvalidInputError("ids: a loop must first be started on all simulations")
            self.state = LoopState(q_ref, qd_ref, ff, np.zeros(self.nsim, dtype=np.intp),
                                   np.zeros((self.nsim, self.model.nv)), np.full(self.nsim, -1, dtype=np.int64))
        else:
            s = self.state
            s.q_ref[rows], s.qd_ref[rows], s.tau_ff[rows] = q_ref, qd_ref, ff
            s.k[rows], s.integral[rows], s.diverged_step[rows] = 0, 0.0, -1
        self.plant.reset(q_ref[:, 0], qd_ref[:, 0], None if ids is None else rows)
        return self.state

    def step(self, *, residual: NDArray[np.float64] | None = None,
             override: NDArray[np.float64] | None = None) -> Step:
        """Advance every simulation by one control period (shapes (B, n) for residual/override, N m).

        A simulation past its last period, or diverged, holds its state and gets zero corrective torque.
        """
        s = self.state
        if s is None:
            raise InvalidInputError("step: call start(references) first")
        N = s.tau_ff.shape[1]
        k = np.minimum(s.k, N - 1)
        q, qd = self.plant.state()
        e = s.q_ref[s.rows, k] - q
        ed = s.qd_ref[s.rows, k] - qd
        out = control_law(e, ed, s.integral, s.tau_ff[s.rows, k], self.config.gains, self.limit, self.dt,
                          anti_windup=self.config.anti_windup, residual=residual, override=override)
        active = (s.diverged_step < 0) & (s.k < N)
        dtau = np.where(active[:, None], out.dtau, 0.0)
        s.integral[:] = np.where(active[:, None], out.integral, s.integral)
        self.plant.step(dtau)
        q_new, qd_new = self.plant.state()
        k_next = np.minimum(s.k + 1, N)
        error = s.q_ref[s.rows, k_next] - q_new
        bad = active & ~(np.all(np.isfinite(q_new), axis=1) & np.all(np.isfinite(qd_new), axis=1)
                         & np.all(np.abs(error) <= self.config.divergence_bound, axis=1))
        if bad.any():
            s.diverged_step[bad] = s.k[bad]
            frozen = np.flatnonzero(bad)
            self.plant.reset(q[frozen], np.zeros_like(qd[frozen]), frozen)
        s.k[:] = np.where(active, s.k + 1, s.k)
        control = ControlOutput(out.tau_ff, out.tau_fb, dtau, out.saturated & active[:, None], out.integral)
        return Step(q, qd, e, ed, control, s.diverged_step >= 0)

    def run(self, references: Sequence[Reference]) -> Rollout:
        """Execute one reference per simulation from its first sample to its end; all share N and dt."""
        state = self.start(references)
        B, N, n = state.tau_ff.shape
        names = ("q", "qd", "e", "ed", "tau_ff", "tau_fb", "dtau")
        rec = {name: np.full((B, N, n), np.nan) for name in names}
        saturated = np.zeros((B, N, n), dtype=bool)
        for k in range(N):
            live = state.diverged_step < 0
            step = self.step()
            values = (step.q, step.qd, step.e, step.ed, step.control.tau_ff, step.control.tau_fb,
                      step.control.dtau)
            for name, value in zip(names, values):
                rec[name][live, k] = value[live]
            saturated[live, k] = step.control.saturated[live]
        q_final, qd_final = self.plant.state()
        diverged = state.diverged_step >= 0
        q_final[diverged] = np.nan
        qd_final[diverged] = np.nan
        return Rollout(**rec, saturated=saturated, q_final=q_final, qd_final=qd_final,
                       e_final=state.q_ref[:, N] - q_final, diverged_step=state.diverged_step.copy(), dt=self.dt)
