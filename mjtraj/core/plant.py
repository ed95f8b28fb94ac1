"""The simulated plant: B copies of the model stepped together on mujoco.batch.Batch."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
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
        plant = copy.copy(model)
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
        fields = {name: np.asarray(values, dtype=np.float64) for name, values in (fields or {}).items()
                  if not (gravity_comp == "zoh" and name == "body_gravcomp")}
        if self.nsim == 1:
            if fields:
                plant = self.model = copy.deepcopy(plant)
                for name, values in fields.items():
                    getattr(plant, name)[:] = values[0]
            self.data: mujoco.MjData | None = mujoco.MjData(plant)
            if fields:
                mujoco.mj_setConst(plant, self.data)
            self.batch: Batch | None = None
            self._qpos, self._qvel = self.data.qpos[None, :], self.data.qvel[None, :]
            self._ctrl, self._applied = self.data.ctrl[None, :], self.data.qfrc_applied[None, :]
        else:
            self.data = None
            self.batch = Batch(plant, self.nsim, nthread=nthread)
            for name, values in fields.items():
                self.batch.expand(name)[:] = values
            if fields:
                self.batch.set_const()
            self._qpos, self._qvel = self.batch.bind("qpos"), self.batch.bind("qvel")
            self._ctrl, self._applied = self.batch.bind("ctrl"), self.batch.bind("qfrc_applied")

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
