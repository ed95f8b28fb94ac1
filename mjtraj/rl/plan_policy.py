"""A learned plan that computed torque tracks: the policy reads no state to choose its motion, only to track it.

At an episode's first observation the policy recovers the task from the observation (`task_of`), plans the held
cubic as the env does, and evaluates its network once on every sample of the episode (the motion's N periods, the
settle window's S and the end): the network gives the plan's offset from the held cubic in position, velocity and
acceleration, over the move squared (`plan_features`, `offset_scale`), tapered to zero over the settle window, and
the tracker's gains at every sample (`mjtraj.rl.plan_tracker`). Every period it then commands what the project's
computed-torque law commands at that plan's sample with that sample's gains, with the tracker's estimate of the
torque disturbance subtracted (the anchor): dtau = clip(D(q) (qdd_p + kp_k e_p + kd_k ed_p) + h(q, qd) - d,
+-limit), e_p = q_p - q, on the measured state, as a torque-mode action (dtau over the saturation).
`mjtraj.rl.plan_train` fits the network to `mpc`'s executions on the nominal plant.

The policy acts in UR5Track-v2's observation with a preview of one sample, the move and the time to the end
(observe_task): PLAN_ENV; with the mpc_filter anchor also `mpc`'s disturbance estimate (observe_disturbance).
Inference is NumPy and MuJoCo only (no torch).
"""

from __future__ import annotations

import functools
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.core import ComputedTorque, DynamicsProbe, Task, held
from mjtraj.exceptions import InvalidInputError, PolicyError
from mjtraj.files import atomic_path
from mjtraj.rl.plan_tracker import DisturbanceObserver, Tracker, tapered

PLAN_POLICY = "mjtraj-plan-policy/2"
"""The format of a plan policy file (an .npz of the network's arrays and the run record, with its tracker). Files of
format 1 (written before trackers) are tracked as they were: CT_RULE's fixed gains, no taper, mpc_filter's
anchor."""
PLAN_FORMATS = ("mjtraj-plan-policy/1", PLAN_POLICY)
PLAN_ENV: dict[str, Any] = {"planner": "cubic", "controller": "computed_torque", "action_mode": "torque",
                            "preview": 1, "preview_frame": "absolute", "observe_task": True,
                            "observe_measured": True}
"""The env settings a plan policy acts in (the rest are UR5Track-v1's; rl eval's protocol v2 adds the window); with
the mpc_filter anchor, observe_disturbance too (`plan_env`)."""
TRACKED = {"computed_torque": "plan tracked by computed torque", "lqr": "plan tracked with LQR gains"}
"""How a plan policy's name begins, by its tracker's rule; the tracker's fields that depart from the rule's follow
(`Tracker.departures`), so that fits of one configuration and one tracker pool as seeds."""
SHIFTS = (-10, -5, 0, 5, 10, 15, 20, 30, 40, 50)
"""Samples at which the cubic's inverse-dynamics torque enters the features of a sample, relative to it (clipped to
the episode): what the plan must prepare for and what it follows from."""


def plan_env(tracker: Tracker) -> dict[str, Any]:
    """The env settings a plan policy with `tracker` acts in."""
    return {**PLAN_ENV, "observe_disturbance": True} if tracker.anchor == "mpc_filter" else dict(PLAN_ENV)


@functools.lru_cache(maxsize=8)
def _resolved(observe_disturbance: bool, window_steps: int) -> Any:
    from mjtraj.envs import resolve

    env = {**PLAN_ENV, "observe_disturbance": observe_disturbance}
    return resolve(**env, settle=window_steps * resolve(**env).dt)


def plan_settings(tracker: Tracker, window_steps: int) -> Any:
    """The resolved env settings (`mjtraj.envs.resolve`) of a plan policy with `tracker` and a settle window of
    `window_steps` periods (made once for each)."""
    return _resolved(tracker.anchor == "mpc_filter", int(window_steps))


def start_mass(task: Task, probe: DynamicsProbe) -> NDArray[np.float64]:
    """(n, n) kg m^2: the mass matrix at the task's start, D(q0): what an acceleration costs in torque there (the
    fit's weights, the tracker's control weight)."""
    return probe.mass_and_bias(task.q0[None], np.zeros((1, task.q0.size)))[0][0]  # type: ignore[no-any-return]


def offset_scale(task: Task) -> float:
    """rad^2: the move squared, max_i |qg_i - q0_i|^2; the network's outputs are the offsets over it."""
    return float(np.max(np.abs(task.qg - task.q0))) ** 2


def held_cubic(task: Task, planner: Any, model: Any, window: int) -> Any:
    """The reference the env tracks: `planner`'s plan of `task` followed by `window` periods at the goal at rest."""
    return held(planner.plan(task, model), window, task.qg)


def plan_features(task: Task, target: Any, probe: DynamicsProbe) -> NDArray[np.float64]:
    """(N + S + 1, (n - 1) + n + 4 + 3n + 1 + n len(SHIFTS)) features of every sample of an episode of `task` whose held
    cubic is `target` (a Reference of N + S + 1 samples): q0 without the pan joint (the UR5's first axis is
    vertical: the dynamics do not depend on it), the displacement qg - q0, T, t, t - T, min(t / T, 1), the cubic's
    q, qd, qdd, log of the move, then the cubic's inverse-dynamics torque (N m, gravity compensated) at SHIFTS."""
    t = target.t
    T = task.duration
    ones = np.ones_like(t)
    torque = probe.inverse(target.q, target.qd, target.qdd)
    index = np.arange(t.size)
    shifted = [torque[np.clip(index + s, 0, t.size - 1)] for s in SHIFTS]
    return np.column_stack([np.outer(ones, task.q0[1:]), np.outer(ones, task.qg - task.q0), ones * T, t, t - T,
                            np.minimum(t / T, 1.0), target.q, target.qd, target.qdd,
                            ones * 0.5 * np.log(offset_scale(task)), *shifted])


class PlanNetwork:
    """The plan's multilayer perceptron in NumPy: standardised inputs, tanh hidden layers, a linear output.

    Attributes:
      layers: [(W (inputs, outputs), b (outputs,)), ...] float64.
      mean, std: (inputs,) the features' standardisation.
    """

    def __init__(self, layers: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
                 mean: NDArray[np.float64], std: NDArray[np.float64]) -> None:
        self.layers = [(np.asarray(w, dtype=np.float64), np.asarray(b, dtype=np.float64)) for w, b in layers]
        self.mean, self.std = np.asarray(mean, dtype=np.float64), np.asarray(std, dtype=np.float64)

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """(rows, inputs) features to (rows, outputs)."""
        h = (x - self.mean) / self.std
        for w, b in self.layers[:-1]:
            h = np.tanh(h @ w + b)
        w, b = self.layers[-1]
        return h @ w + b  # type: ignore[no-any-return]

    def arrays(self) -> dict[str, NDArray[np.float64]]:
        """The network as named arrays (what `save_plan` writes)."""
        out = {"mean": self.mean, "std": self.std}
        for i, (w, b) in enumerate(self.layers):
            out[f"w{i}"], out[f"b{i}"] = w, b
        return out

    @classmethod
    def from_arrays(cls, arrays: Any) -> PlanNetwork:
        count = sum(1 for k in arrays if str(k).startswith("w"))
        return cls([(arrays[f"w{i}"], arrays[f"b{i}"]) for i in range(count)], arrays["mean"], arrays["std"])


def task_of(obs: NDArray[np.float64], n: int, dt: float) -> Task:
    """The task of an episode from its first observation in PLAN_ENV (phase 0): q0 = q_ref,0, N from the time to
    the motion's end, and the displacement from the first preview sample, q_ref,1 - q0 = (qg - q0) p(1/N) with the
    cubic's p(s) = 3 s^2 - 2 s^3."""
    q0 = obs[2 * n:3 * n]
    steps = round(float(obs[-1]) / dt)
    if obs[6 * n] != 0.0 or steps < 1:
        raise PolicyError(f"plan policy: an episode's first observation must be at phase 0 with a motion ahead, got "
                          f"phase {obs[6 * n]} and {obs[-1]} s to the motion's end")
    s = 1.0 / steps
    displacement = (obs[6 * n + 1:7 * n + 1] - q0) / (3 * s * s - 2 * s ** 3)
    return Task(q0.copy(), q0 + displacement, steps * dt, dt)


class PlanPolicy:
    """The batched, stateful torque policy of a plan network (see the module docstring); `rl eval` scores it.

    Args:
      network: the plan's network (features to offsets over the move squared, 3n).
      record: the run record it was trained with (saved beside it): its settle window (window_steps) and tracker.
      streams: the seeds of its training tasks (rl eval refuses to score it on them).
      tracker: how it follows its plan (default the record's, `Tracker.of_record`; `Tracker()` if it names
        none).

    Attributes:
      env: the env settings it acts in (`plan_env`); settings: them resolved, with the window.
    """

    batched = True

    def __init__(self, network: PlanNetwork, record: dict[str, Any], streams: list[Any] | None = None,
                 files: list[str] | None = None, tracker: Tracker | None = None) -> None:
        self.network, self.record = network, record
        self.streams, self.files = streams, files or []
        self.tracker = tracker or (Tracker.of_record(record["tracker"]) if "tracker" in record else Tracker())
        self.window = int(record["window_steps"])
        self.tracker.check_window(self.window)
        self.env = plan_env(self.tracker)
        self.settings = settings = plan_settings(self.tracker, self.window)
        # rl eval pools seeds by name: the tracker's rule and any field that departs from the rule's
        self.name = ", ".join([TRACKED[self.tracker.rule], *self.tracker.departures()]) + \
            f" ({record.get('label', 'plan')})"
        self.n, self.dt, self.obs_size = settings.n, settings.dt, settings.obs_size
        self.probe = DynamicsProbe(settings.model, serial=True)  # one MjData: the cheaper for a few rows
        self.limit = settings.torque_limit
        self.observer = (DisturbanceObserver(settings.model, settings.loop.gravity_comp, settings.loop.substeps,
                                             self.tracker.anchor_gain) if self.tracker.anchor == "nominal" else None)
        self._plans: list[NDArray[np.float64]] = []  # each row's episode plan (empty before its first observation)
        self._fresh = np.zeros(0, dtype=bool)

    def offsets(self, task: Task, target: Any) -> NDArray[np.float64]:
        """(N + S + 1, 3n): the learned offsets of the plan of `task` from its held cubic `target` (rad, rad/s,
        rad/s^2)."""
        return self.network(plan_features(task, target, self.probe)) * offset_scale(task)

    def plan(self, task: Task) -> NDArray[np.float64]:
        """(N + S + 1, 5n): the episode's plan q_p, qd_p, qdd_p (the held cubic plus the `offsets`, tapered with the
        tracker's taper) and the tracker's gains kp, kd at its every sample."""
        target = held_cubic(task, self.settings.planner, self.settings.model, self.window)
        offsets = self.offsets(task, target)
        if self.tracker.taper:
            offsets = tapered(offsets, target.t, task.duration, target.t[-1])
        kp, kd = self.tracker.gains(self.settings.weights(task), start_mass(task, self.probe), task.steps,
                                    self.window, self.dt)
        return np.concatenate([target.q + offsets[:, :self.n], target.qd + offsets[:, self.n:2 * self.n],
                               target.qdd + offsets[:, 2 * self.n:], kp, kd], axis=1)

    def reset(self, starts: NDArray[np.bool_]) -> None:
        """Episodes `starts` (bool (B,)) begin: their next observation is their first."""
        starts = np.asarray(starts, dtype=bool)
        if self._fresh.size != starts.size:
            self._plans = [np.empty((0, 5 * self.n))] * starts.size
            self._fresh = np.ones(starts.size, dtype=bool)
        self._fresh |= starts
        if self.observer is not None:
            self.observer.reset(starts)

    def __call__(self, obs: NDArray[np.float64]) -> NDArray[np.float64]:
        """(B, d) observations to (B, n) torque-mode actions (dtau over the saturation)."""
        obs = np.asarray(obs, dtype=np.float64)
        n, count = self.n, obs.shape[0]
        if obs.ndim != 2 or obs.shape[1] != self.obs_size:
            raise PolicyError(f"plan policy: expected observations (B, {self.obs_size}) of its env "
                              f"(PLAN_ENV), got shape {obs.shape}")
        if self._fresh.size != count:
            self.reset(np.ones(count, dtype=bool))
        if self._fresh.any():
            for fresh in np.flatnonzero(self._fresh):
                self._plans[fresh] = self.plan(task_of(obs[fresh], n, self.dt))
            self._fresh[:] = False
        # the period k of each row from the time to its motion's end, (N - k) dt: N - (N - k) in its plan
        samples = np.array([plan[min(max(len(plan) - 1 - self.window - round(left / self.dt), 0), len(plan) - 1)]
                            for plan, left in zip(self._plans, obs[:, -1].tolist(), strict=True)])
        q, qd = obs[:, :n], obs[:, n:2 * n]
        if self.observer is None:
            d = obs[:, 8 * n + 1:9 * n + 1] * self.limit  # after the preview sample: mpc's filtered disturbance
        else:
            d = self.observer.estimate(q, qd)
        none = np.zeros((count, n))
        law = ComputedTorque(samples[:, 3 * n:4 * n], samples[:, 4 * n:])
        dynamics = self.probe.mass_and_bias(q, qd)
        out = law(samples[:, :n] - q, samples[:, n:2 * n] - qd, none, none, samples[:, 2 * n:3 * n], dynamics,
                  self.limit, self.dt, residual=-d)
        if self.observer is not None:
            self.observer.remember(q, qd, out.dtau, dynamics[0])
        return out.dtau / self.limit  # type: ignore[no-any-return]


def save_plan(network: PlanNetwork, record: dict[str, Any], path: Path) -> None:
    """Write a plan policy file (atomically): the network's arrays and the record as JSON."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        arrays: dict[str, Any] = {**network.arrays(), "record": np.array(json.dumps({**record, "format": PLAN_POLICY}))}
        np.savez(f, **arrays)


def load_plan(path: str | Path) -> PlanPolicy:
    """The plan policy saved at `path`.

    Raises:
      InvalidInputError: not a plan policy file.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as saved:
            arrays = {k: saved[k] for k in saved.files}
        record = json.loads(str(arrays.pop("record")))
        if record.get("format") not in PLAN_FORMATS:
            raise ValueError(f"format {record.get('format')!r}, expected one of {', '.join(PLAN_FORMATS)}")
        if record["format"] == PLAN_FORMATS[0]:  # before trackers
            record = {**record, "tracker": Tracker.of_rule("computed_torque").as_dict()}
        return PlanPolicy(PlanNetwork.from_arrays(arrays), record, streams=record.get("streams"),
                          files=[str(path.resolve())])
    except (OSError, ValueError, KeyError, TypeError) as e:  # InvalidInputError is a ValueError
        raise InvalidInputError(f"policy: {path} is not a plan policy file ({type(e).__name__}: {e})") from e
