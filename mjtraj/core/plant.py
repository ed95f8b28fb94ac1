"""The simulated plant: B copies of the model stepped together on mujoco.batch.Batch."""

from __future__ import annotations

import copy
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt
from mujoco.batch import Batch
from numpy.typing import NDArray

from mjtraj.checks import choice, positive_int

GRAVITY_COMP = ("native", "zoh")


class BatchPlant:
    """`nsim` simulations of `model` advanced one control period at a time, torque tau = G(q) + dtau.

    Gravity compensation 'native' is MuJoCo's body gravcomp routed to the actuators, evaluated inside every
    integrator stage (the paper's continuous-time model); 'zoh' evaluates G(q_k) of the controller's `nominal`
    model at the start of each period and holds it (applied through qfrc_applied; the total still respects
    the joints' actuatorfrcrange). The control period is `model.opt.timestep`; each period runs `substeps`
    integrator steps of period/substeps.

    One simulation steps a plain MjData with mj_step (the batch's per-call overhead is a tenth of a step);
    several step on mujoco.batch.Batch. Both run the same mj_step: results are bit-identical (tested).

    `fields` gives model fields per-simulation values (MjModel names, arrays of shape (nsim, ...)): the plant
    perturbations of sweeps. mj_setConst then recomputes what derives from them. Under 'zoh' gravity
    compensation a given body_gravcomp is ignored (the plant's own gravcomp is off).
    """

    def __init__(self, model: mujoco.MjModel, nsim: int, *, nominal: mujoco.MjModel | None = None,
                 gravity_comp: str = "native", substeps: int = 1, nthread: int = 0,
                 fields: dict[str, NDArray[np.float64]] | None = None) -> None:
        self.gravity_comp = choice("gravity_comp", gravity_comp, GRAVITY_COMP)
        self.substeps = positive_int("substeps", substeps)
        self.nsim = positive_int("nsim", nsim)
        self.dt = float(model.opt.timestep)
        self._args = (model, nominal, nthread)
        plant = copy.copy(model)  # a copy of its own: set_fields writes into it when nsim == 1
        plant.opt.timestep = self.dt / self.substeps
        if gravity_comp == "zoh":
            plant.body_gravcomp[:] = 0.0
            probe_model = copy.copy(nominal if nominal is not None else model)
            self._probe = Batch(probe_model, self.nsim, nthread=nthread)
            self._probe_qpos = self._probe.bind("qpos")
            self._probe_gravity = self._probe.bind("qfrc_gravcomp")
            limited = plant.jnt_actfrclimited.astype(bool)
            self._frc_lo = np.where(limited, plant.jnt_actfrcrange[:, 0], -np.inf)
            self._frc_hi = np.where(limited, plant.jnt_actfrcrange[:, 1], np.inf)
        self.model = plant
        self._fields: dict[str, NDArray[np.float64]] = {}
        """The per-simulation field values set so far, name -> (nsim, ...) (kept for pickling)."""
        if self.nsim == 1:
            self.data: mujoco.MjData | None = mujoco.MjData(plant)
            self.batch: Batch | None = None
            self._qpos, self._qvel = self.data.qpos[None, :], self.data.qvel[None, :]
            self._ctrl, self._applied = self.data.ctrl[None, :], self.data.qfrc_applied[None, :]
        else:
            self.data = None
            self.batch = Batch(plant, self.nsim, nthread=nthread)
            self._qpos, self._qvel = self.batch.bind("qpos"), self.batch.bind("qvel")
            self._ctrl, self._applied = self.batch.bind("ctrl"), self.batch.bind("qfrc_applied")
        if fields:
            self.set_fields(fields)

    def set_fields(self, fields: dict[str, NDArray[np.float64]], ids: npt.ArrayLike | None = None) -> None:
        """Give simulations `ids` (all if None) their own values of model fields (MjModel names, arrays of shape
        (len(ids), ...)), then recompute what derives from them (mj_setConst). Call it before `reset`: the
        simulations' state is not kept. Under 'zoh' gravity compensation body_gravcomp is ignored."""
        rows = np.arange(self.nsim) if ids is None else np.asarray(ids, dtype=np.intp).reshape(-1)
        for name, given in fields.items():
            if self.gravity_comp == "zoh" and name == "body_gravcomp":
                continue
            values = np.asarray(given, dtype=np.float64)
            if name not in self._fields:
                self._fields[name] = np.repeat(np.asarray(getattr(self.model, name), dtype=np.float64)[None],
                                               self.nsim, axis=0)
            self._fields[name][rows] = values
            if self.batch is not None:
                self.batch.expand(name)[rows] = values
            else:
                getattr(self.model, name)[:] = values[0]
        if self.batch is not None:
            self.batch.set_const(ids=rows)
        else:
            mujoco.mj_setConst(self.model, self.data)

    STATE = ("time", "qpos", "qvel", "act", "qacc_warmstart", "ctrl", "qfrc_applied")
    """The MjData fields that carry a simulation on from one step to the next (with the model's fields)."""

    def __getstate__(self) -> dict[str, Any]:
        """What rebuilds this plant exactly: its arguments, the per-simulation fields and every simulation's state
        (mujoco's Batch itself cannot be pickled)."""
        if self.batch is not None:
            state = {name: self.batch.bind(name).copy() for name in self.STATE}
        else:
            state = {name: np.atleast_1d(np.array(getattr(self.data, name)))[None] for name in self.STATE}
        model, nominal, nthread = self._args
        return {"args": (model, self.nsim), "nominal": nominal, "gravity_comp": self.gravity_comp,
                "substeps": self.substeps, "nthread": nthread, "fields": self._fields, "state": state}

    def __setstate__(self, saved: dict[str, Any]) -> None:
        model, nsim = saved["args"]
        BatchPlant.__init__(self, model, nsim, nominal=saved["nominal"], gravity_comp=saved["gravity_comp"],
                            substeps=saved["substeps"], nthread=saved["nthread"], fields=saved["fields"])
        for name, values in saved["state"].items():
            if self.batch is not None:
                self.batch.bind(name)[:] = values
            elif self.data is not None:
                if name == "time":
                    self.data.time = float(values[0, 0])
                else:
                    getattr(self.data, name)[:] = values[0]

    def reset(self, q: NDArray[np.float64], qd: NDArray[np.float64], ids: NDArray[np.intp] | None = None) -> None:
        """Set positions (rad) and velocities (rad/s), shape (len(ids), n), of simulations `ids` (all if None)."""
        rows = slice(None) if ids is None else ids
        if self.batch is not None:
            self.batch.reset(ids=ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        else:
            mujoco.mj_resetData(self.model, self.data)
        self._qpos[rows] = q
        self._qvel[rows] = qd
        self._ctrl[rows] = 0.0
        self._applied[rows] = 0.0

    def unstable(self) -> NDArray[np.bool_]:
        """Shape (nsim,): MuJoCo flagged the simulation numerically unstable (bad qacc, qpos or qvel; it then
        resets the state by itself) since its last reset."""
        bad = [int(mujoco.mjtWarning.mjWARN_BADQACC), int(mujoco.mjtWarning.mjWARN_BADQPOS),
               int(mujoco.mjtWarning.mjWARN_BADQVEL)]
        if self.batch is not None:
            return np.any(self.batch.warning[:, bad, 1] > 0, axis=1)
        assert self.data is not None
        return np.array([any(self.data.warning[i].number > 0 for i in bad)])

    def state(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Copies of (q, qd), shape (nsim, n) each."""
        return self._qpos.copy(), self._qvel.copy()

    @property
    def qpos(self) -> NDArray[np.float64]:
        """Live view of the positions, shape (nsim, n), rad; changes with every step."""
        return self._qpos

    @property
    def qvel(self) -> NDArray[np.float64]:
        """Live view of the velocities, shape (nsim, n), rad/s; changes with every step."""
        return self._qvel

    def step(self, dtau: NDArray[np.float64]) -> None:
        """Apply the corrective torque dtau (N m, shape (nsim, n)) for one control period."""
        self._ctrl[:] = dtau
        if self.gravity_comp == "zoh":
            self._probe_qpos[:] = self._qpos
            self._probe.forward(stage=mujoco.mjtStage.mjSTAGE_VEL)
            clipped = np.clip(dtau, self.model.actuator_ctrlrange[:, 0], self.model.actuator_ctrlrange[:, 1])
            self._applied[:] = np.clip(self._probe_gravity + clipped, self._frc_lo, self._frc_hi) - clipped
        if self.data is not None:
            mujoco.mj_step(self.model, self.data, self.substeps)
        elif self.batch is not None:
            self.batch.step(None, self.substeps)
