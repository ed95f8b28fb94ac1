"""Batched rigid-body dynamics of the nominal model on mujoco.batch.Batch: forward accelerations, the feedforward
torque ID(q, qd, qdd) - G(q), and gravity, for many states in one call."""

from __future__ import annotations

import copy
import threading
import weakref
from typing import Any

import mujoco
import numpy as np
from mujoco.batch import Batch
from numpy.typing import NDArray

CHUNK = 4096
"""Most states evaluated per Batch call (bounds the probe's memory; any size gives the same numbers)."""


_FIELDS = ("qpos", "qvel", "ctrl", "qacc", "qfrc_bias", "qfrc_passive", "qfrc_gravcomp", "M")
_NO_CONSTRAINTS = int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
"""Disable flags of the terms' model: D, bias, passive and gravity forces do not depend on contacts or constraints."""
_scratch = threading.local()


def _per_model(name: str) -> weakref.WeakKeyDictionary[mujoco.MjModel, Any]:
    """This thread's cache `name`, model -> an object of it, an entry kept while its model lives."""
    cache = getattr(_scratch, name, None)
    if cache is None:
        cache = weakref.WeakKeyDictionary()
        setattr(_scratch, name, cache)
    return cache


def _scratch_data(model: mujoco.MjModel) -> mujoco.MjData:
    """This thread's MjData of `model`, kept while the model lives. MjData reads the model at every call, so
    edits of the model's parameters are seen (a Batch copies its model when made)."""
    cache = _per_model("data")
    data = cache.get(model)
    if data is None:
        data = cache[model] = mujoco.MjData(model)
    return data


class _DataLoop:
    """The part of mujoco.batch.Batch a probe uses (`bind`, `forward`), on one MjData for every state in turn."""

    def __init__(self, model: mujoco.MjModel, size: int) -> None:
        self.model = model
        data = _scratch_data(model)
        self._arrays = {name: np.zeros((size, *getattr(data, name).shape)) for name in _FIELDS}

    def bind(self, name: str) -> NDArray[np.float64]:
        return self._arrays[name]

    def forward(self, *, ids: NDArray[np.intp], stage: mujoco.mjtStage) -> None:
        """mj_forward up to `stage` (VEL or ACC) for the states `ids`, outputs copied into the bound arrays."""
        model, data, arrays = self.model, _scratch_data(self.model), self._arrays
        qpos, qvel, ctrl = data.qpos, data.qvel, data.ctrl  # views, fetched once: each attribute read makes one
        sources = arrays["qpos"], arrays["qvel"], arrays["ctrl"]
        outputs = ("qacc",) if stage == mujoco.mjtStage.mjSTAGE_ACC else ("qfrc_bias", "qfrc_passive",
                                                                          "qfrc_gravcomp", "M")
        pairs = [(arrays[name], getattr(data, name)) for name in outputs]
        for i in ids.tolist():
            qpos[:], qvel[:], ctrl[:] = sources[0][i], sources[1][i], sources[2][i]
            if stage == mujoco.mjtStage.mjSTAGE_ACC:
                mujoco.mj_forward(model, data)
            else:
                mujoco.mj_fwdPosition(model, data)
                mujoco.mj_fwdVelocity(model, data)
            for out, value in pairs:
                out[i] = value


class DynamicsProbe:
    """Evaluates `model` at many states: arrays of shape (rows, n) in, (rows, n) out, `size` states per call.

    Each call runs MuJoCo's own pipeline per state (mj_forward up to the needed stage) on a Batch, or with
    `serial` on this thread's one MjData of the model, state after state: a Batch costs about 1 ms to make, more
    than a one-off evaluation of a few dozen states, while for repeated calls on many states it is the faster.
    The position- and velocity-stage terms (D, bias, passive and gravity forces) run on a Batch of a copy of the
    model with contacts and constraints disabled, which they do not depend on (about 30 % faster); accelerations on
    the model itself. The numbers are the same bits either way, and equal those of a loop over MjData (tested
    against mj_inverse and mj_forward). Each Batch is made at its first use.
    """

    def __init__(self, model: mujoco.MjModel, *, size: int = CHUNK, nthread: int = 1, serial: bool = False) -> None:
        self.model = model
        self.n = model.nv
        self.size = max(1, min(int(size), CHUNK))
        self.nthread = nthread
        self.serial = serial
        self._engines: dict[mujoco.mjtStage, Batch | _DataLoop] = {}
        rows, cols, index = [], [], []  # the dense D(q) from MuJoCo's lower-triangular CSR `M`
        for i in range(model.nv):
            start = model.M_rowadr[i]
            for a in range(start, start + model.M_rownnz[i]):
                j = model.M_colind[a]
                rows += [i, j]
                cols += [j, i]
                index += [a, a]
        self._dense = (np.array(rows), np.array(cols), np.array(index))

    def _engine(self, stage: mujoco.mjtStage) -> Batch | _DataLoop:
        """What evaluates states up to `stage` (ACC or VEL), made at its first use."""
        engine = self._engines.get(stage)
        if engine is None:
            if self.serial:  # one MjData of the model itself serves both stages
                engine = _DataLoop(self.model, self.size)
                self._engines = dict.fromkeys((mujoco.mjtStage.mjSTAGE_ACC, mujoco.mjtStage.mjSTAGE_VEL), engine)
            elif stage == mujoco.mjtStage.mjSTAGE_ACC:
                engine = Batch(self.model, self.size, nthread=self.nthread)
            else:
                terms = copy.copy(self.model)
                terms.opt.disableflags |= _NO_CONSTRAINTS
                engine = Batch(terms, self.size, nthread=self.nthread)
            self._engines[stage] = engine
        return engine

    def __getstate__(self) -> tuple[mujoco.MjModel, int, int, bool]:
        """The arguments: the probe is scratch space (mujoco's Batch itself cannot be pickled)."""
        return self.model, self.size, self.nthread, self.serial

    def __setstate__(self, state: tuple[mujoco.MjModel, int, int, bool]) -> None:
        model, size, nthread, serial = state
        DynamicsProbe.__init__(self, model, size=size, nthread=nthread, serial=serial)

    def _chunks(self, *arrays: NDArray[np.float64]):
        rows = arrays[0].shape[0]
        for start in range(0, rows, self.size):
            stop = min(start + self.size, rows)
            yield slice(start, stop), np.arange(stop - start), tuple(a[start:stop] for a in arrays)

    def accelerations(self, q: NDArray[np.float64], qd: NDArray[np.float64], u: NDArray[np.float64]
                      ) -> NDArray[np.float64]:
        """qacc of the gravity-compensated model under corrective torque u (ctrl); shapes (rows, n)."""
        out = np.empty_like(q)
        engine = self._engine(mujoco.mjtStage.mjSTAGE_ACC)
        qpos, qvel, ctrl, qacc = (engine.bind(name) for name in ("qpos", "qvel", "ctrl", "qacc"))
        for rows, ids, (qc, qdc, uc) in self._chunks(q, qd, u):
            qpos[ids], qvel[ids], ctrl[ids] = qc, qdc, uc
            engine.forward(ids=ids, stage=mujoco.mjtStage.mjSTAGE_ACC)
            out[rows] = qacc[ids]
        return out

    def inverse(self, q: NDArray[np.float64], qd: NDArray[np.float64], qdd: NDArray[np.float64]
                ) -> NDArray[np.float64]:
        """ID(q, qd, qdd) - G(q) = D(q) qdd + C(q, qd) qd - passive forces, N m; shapes (rows, n).

        This is mj_inverse's qfrc_inverse minus qfrc_gravcomp, for a model without constraints.
        """
        D, bias, passive, gravcomp = self.terms(q, qd)
        return np.einsum("bij,bj->bi", D, qdd) + bias - passive - gravcomp  # type: ignore[no-any-return]

    def mass_and_bias(self, q: NDArray[np.float64], qd: NDArray[np.float64]
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """D(q), shape (rows, n, n), kg m^2, and h(q, qd) = C(q, qd) qd - passive forces, shape (rows, n), N m: the
        gravity-compensated model's ID(q, qd, qdd) - G(q) = D qdd + h."""
        D, bias, passive, gravcomp = self.terms(q, qd)
        return D, bias - passive - gravcomp

    def terms(self, q: NDArray[np.float64], qd: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """D(q) (rows, n, n), kg m^2, and MuJoCo's qfrc_bias (C(q, qd) qd + gravity), qfrc_passive and
        qfrc_gravcomp (rows, n), N m, at (q, qd)."""
        D = np.zeros((q.shape[0], self.n, self.n))
        bias, passive, gravcomp = np.empty_like(q), np.empty_like(q), np.empty_like(q)
        i, j, a = self._dense
        if self.serial:  # straight on the MjData, without the engine's copies (a few states per call)
            model, data = self.model, _scratch_data(self.model)
            for row in range(q.shape[0]):
                data.qpos[:], data.qvel[:] = q[row], qd[row]
                mujoco.mj_fwdPosition(model, data)
                mujoco.mj_fwdVelocity(model, data)
                D[row, i, j] = data.M[a]
                bias[row], passive[row], gravcomp[row] = data.qfrc_bias, data.qfrc_passive, data.qfrc_gravcomp
            return D, bias, passive, gravcomp
        engine = self._engine(mujoco.mjtStage.mjSTAGE_VEL)
        qpos, qvel, M, qfrc_bias, qfrc_passive, qfrc_gravcomp = (engine.bind(name) for name in (
            "qpos", "qvel", "M", "qfrc_bias", "qfrc_passive", "qfrc_gravcomp"))
        for rows, ids, (qc, qdc) in self._chunks(q, qd):
            qpos[ids], qvel[ids] = qc, qdc
            engine.forward(ids=ids, stage=mujoco.mjtStage.mjSTAGE_VEL)
            D[rows, i, j] = M[ids][:, a]
            bias[rows], passive[rows], gravcomp[rows] = qfrc_bias[ids], qfrc_passive[ids], qfrc_gravcomp[ids]
        return D, bias, passive, gravcomp

    def gravity(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """G(q), the torque that holds the poses q still, N m; shapes (rows, n)."""
        zero = np.zeros_like(q)
        out = np.empty_like(q)
        engine = self._engine(mujoco.mjtStage.mjSTAGE_VEL)
        qpos, qvel, qfrc_bias = (engine.bind(name) for name in ("qpos", "qvel", "qfrc_bias"))
        for rows, ids, (qc,) in self._chunks(q):
            qpos[ids], qvel[ids] = qc, zero[: ids.size]
            engine.forward(ids=ids, stage=mujoco.mjtStage.mjSTAGE_VEL)
            out[rows] = qfrc_bias[ids]
        return out


def without_dry_friction(model: mujoco.MjModel) -> mujoco.MjModel:
    """`model` itself, or if any joint has friction loss a copy without it (kept while the model lives): what
    linearisations see. Dry friction has no derivative at rest; a finite difference across zero velocity reads
    it as an enormous viscous term (a 2 N m friction loss as about 10^6 N m s/rad). Viscous damping stays."""
    if not np.any(model.dof_frictionloss):
        return model
    cache = _per_model("smooth")
    smooth = cache.get(model)
    if smooth is None:
        smooth = cache[model] = copy.copy(model)
        smooth.dof_frictionloss[:] = 0.0
    return smooth  # type: ignore[no-any-return]


def serial_probe(model: mujoco.MjModel, size: int) -> DynamicsProbe:
    """This thread's serial probe of `model` for up to `size` states per call, kept while the model lives: one-off
    evaluations of a few states (a plan's linearisation) reuse it rather than make one each time (about 10 us)."""
    cache = _per_model("probes")
    probe = cache.get(model)
    if probe is None or probe.size < size:
        probe = cache[model] = DynamicsProbe(model, size=size, serial=True)
    return probe
