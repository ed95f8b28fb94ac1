"""Fitting a plan policy (`mjtraj.rl.plan_policy`) to `mpc`'s executions: labels, then a weighted regression.

Labels. Training tasks are drawn from the training streams (`mjtraj.rl.streams`: family f's task i from
[seed, TRAIN_STREAM, f tasks + i], never an evaluation scenario) by each family's rules, and `mpc` executes each on
the nominal plant, tracking the held cubic with the settle window, as protocol v2 runs it. A task's label at every
sample of its episode is `mpc`'s execution minus the held cubic: the position, the velocity and the acceleration
(forward differences of the velocity; 0 at the end), over the move squared.

Fit. A tanh network maps `plan_features` to the labels, minimising a weighted mean square: each output's weight is
the score's weight on what it moves (Bryson's Q on the positions and velocities; R times the squared diagonal of
the mass matrix at q0 on the accelerations, the torque an acceleration costs) times the move to the fourth (undoing
the labels' scale), divided by a cost (`weighting`): `task`, the task's own J_settle and its number of samples,
so that every task counts alike relative to what it costs; `family`, the mean of `mpc`'s J_settle over the task's
family, so that the loss is each family's score error over its mean score, the ratio of means the benchmark reads.
Adam with a cosine schedule.

Stages: labels.npz is written once labelled and reused when the run is started again on the same folder with the
same settings; policy.npz and run.json when fitted. Every setting, the streams and both stages' seconds are
recorded.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import choice, positive, positive_int
from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path, write_text_atomic
from mjtraj.rl.plan_policy import (
    PLAN_ENV,
    PlanNetwork,
    held_cubic,
    load_plan,
    offset_scale,
    plan_env,
    plan_features,
    save_plan,
    start_mass,
)
from mjtraj.rl.plan_tracker import TRACKER_RULES, Tracker
from mjtraj.rl.streams import TRAIN_STREAM, check_seed

PLAN_RUN = "mjtraj-plan-run/1"
FAMILIES = ("nominal", "aggressive", "mismatch")
WEIGHTINGS = ("task", "family")
LABEL_CHUNK = 64
"""Tasks of one length that `mpc` executes together (one batched loop)."""


@dataclass(frozen=True)
class PlanSettings:
    """One plan fit: the training tasks, the network and the optimiser."""

    families: tuple[str, ...] = FAMILIES
    """Whose rules draw the training tasks (every one executed on the nominal plant)."""
    tasks: int = 2000
    """Training tasks per family."""
    epochs: int = 160
    batch: int = 512
    learning_rate: float = 1e-3
    hidden: tuple[int, ...] = (256, 256, 256)
    window: float = 0.5
    """The settle window, s (protocol v2's)."""
    seed: int = 0
    """The training streams' seed and the fit's."""
    threads: int = 1
    """PyTorch CPU threads."""
    workers: int = 1
    """Processes that run `mpc` for the labels (the labels do not depend on it)."""
    weighting: str = "task"
    """What each task's squared errors are divided by: task (its own J_settle under `mpc` and its samples) or family
    (its family's mean J_settle). On the validation scenarios task scored lower on aggressive motions."""
    tracker: str = "lqr"
    """How the policy follows its plan (`mjtraj.rl.plan_tracker`): lqr (the score's weights' gains, the taper, its
    own disturbance estimate) or computed_torque (CT_RULE's gains, no taper, mpc_filter's estimate, observed: plan
    files of format 1). It does not change the fit."""

    def __post_init__(self) -> None:
        if not self.families:
            raise InvalidInputError("families: expected at least one of " + ", ".join(FAMILIES) + ", got none")
        for family in self.families:
            choice("families", family, FAMILIES)
        for name in ("tasks", "epochs", "batch", "threads", "workers"):
            positive_int(name, getattr(self, name))
        choice("weighting", self.weighting, WEIGHTINGS)
        choice("tracker", self.tracker, TRACKER_RULES)
        positive("learning_rate", self.learning_rate)
        positive("window", self.window)
        if any(isinstance(h, bool) or not isinstance(h, int) or h < 1 for h in self.hidden):
            raise InvalidInputError(f"hidden: expected layer widths >= 1 (none: a linear map), got {self.hidden!r}")
        check_seed("seed", self.seed)

    def streams(self) -> list[list[int]]:
        """The entropy of every training task, in order (family by family)."""
        return [[self.seed, TRAIN_STREAM, f * self.tasks + i] for f in range(len(self.families))
                for i in range(self.tasks)]

    def label_settings(self) -> dict[str, Any]:
        """What decides the labels (a saved labels.npz is reused only if these match)."""
        from mjtraj.versions import library_version

        return {"families": list(self.families), "tasks": self.tasks, "window": self.window, "seed": self.seed,
                "run": PLAN_RUN, "mjtraj": library_version("mjtraj")}

    def fit_settings(self) -> dict[str, Any]:
        """What decides the fitted network (a saved policy's network is reused only if these match): every setting
        but the label workers and the tracker."""
        return {**dataclasses.asdict(self), "workers": None, "tracker": None, **self.label_settings()}


@dataclass
class Labels:
    """Every training sample: features x (rows, F), labels y (rows, 3n), the score's weights on them w (rows, 3n;
    before `weighting`), and each task's first row (tasks + 1,), `mpc`'s J_settle (tasks,) and family's index in
    the settings' families (tasks,); the seconds the labelling took."""

    x: NDArray[np.float64]
    y: NDArray[np.float64]
    w: NDArray[np.float64]
    starts: NDArray[np.intp]
    cost: NDArray[np.float64]
    family: NDArray[np.intp]
    seconds: float = 0.0

    def weights(self, weighting: str) -> NDArray[np.float64]:
        """(rows, 3n) the fit's weights under `weighting` (PlanSettings.weighting), over their mean."""
        samples = np.diff(self.starts)
        if weighting == "task":
            divisor = self.cost * samples
        else:
            means = np.array([self.cost[self.family == f].mean() if np.any(self.family == f) else 1.0
                              for f in range(int(self.family.max()) + 1)])
            divisor = means[self.family]
        w = self.w / np.repeat(divisor, samples)[:, None]
        return w / w.mean()  # type: ignore[no-any-return]


@functools.lru_cache(maxsize=4)
def env_settings(window: float) -> Any:
    """The env settings of a plan policy with a settle window of `window` s (made once per window)."""
    from mjtraj.envs import resolve

    return resolve(**PLAN_ENV, settle=window)


def training_tasks(settings: PlanSettings, model: Any, dt: float) -> list[Any]:
    """The training tasks in `streams` order (`mjtraj.domain.families.draw_scenario` on TRAIN_STREAM)."""
    from mjtraj.study import draw_scenario

    out = []
    for f, family in enumerate(settings.families):
        for i in range(settings.tasks):
            out.append(draw_scenario(family, settings.seed, f * settings.tasks + i, model, dt,
                                     stream=TRAIN_STREAM).task)
    return out


def label(settings: PlanSettings, tasks: list[Any] | None = None, progress: bool = False) -> Labels:
    """`mpc`'s executions of the training tasks (or of `tasks`, whose family index is then that of the position each
    would have among the training tasks) on the nominal plant, as labels. Tasks of one length run together in
    chunks of LABEL_CHUNK, in a fixed order; with `settings.workers` > 1 the chunks are shared among that many
    processes, each chunk run as one would run it (the same labels, bit for bit)."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    env = env_settings(settings.window)
    tasks = training_tasks(settings, env.model, env.dt) if tasks is None else tasks
    by_length: dict[int, list[int]] = defaultdict(list)
    for i, task in enumerate(tasks):
        by_length[task.steps].append(i)
    chunks = [members[start:start + LABEL_CHUNK] for _, members in sorted(by_length.items())
              for start in range(0, len(members), LABEL_CHUNK)]
    parts: list[Any] = [None] * len(tasks)
    cost = np.zeros(len(tasks))
    done, clock = 0, time.perf_counter()
    work = [(settings.window, [tasks[i] for i in chunk]) for chunk in chunks]
    pool = (ProcessPoolExecutor(settings.workers, mp_context=get_context("spawn")) if settings.workers > 1
            else None)
    try:
        results = pool.map(_label_chunk, work) if pool is not None else map(_label_chunk, work)
        for chunk, (rows, costs) in zip(chunks, results, strict=True):
            for i, row, value in zip(chunk, rows, costs, strict=True):
                parts[i], cost[i] = row, value
            done += len(chunk)
            if progress:
                print(f"labels: {done}/{len(tasks)} tasks ({time.perf_counter() - clock:.0f} s)", flush=True)
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    bad = [i for i, p in enumerate(parts) if not (np.isfinite(cost[i]) and np.isfinite(p[1]).all())]
    if bad:
        raise InvalidInputError(f"tasks: mpc's execution of {len(bad)} of the {len(tasks)} training tasks is not "
                                f"finite (the first: task {bad[0]}, stream {settings.streams()[bad[0]]}); expected "
                                "every label finite")
    x, y, w = (np.concatenate([p[k] for p in parts]) for k in range(3))
    starts = np.concatenate([[0], np.cumsum([p[0].shape[0] for p in parts])]).astype(np.intp)
    family = np.repeat(np.arange(len(settings.families)), settings.tasks)[:len(tasks)]
    return Labels(x, y, w, starts, cost, family, time.perf_counter() - clock)


def _label_chunk(work: tuple[float, list[Any]]) -> tuple[list[tuple[NDArray[np.float64], ...]], list[float]]:
    """`mpc`'s executions of tasks of one length together (the settle window `work[0]` s, the tasks `work[1]`):
    each task's rows (`_task_rows`) and J_settle."""
    from mjtraj.core import DynamicsProbe, Settle, settle_arrays
    from mjtraj.domain import Job, execute_batch

    window_s, tasks = work
    env = env_settings(window_s)
    model, dt, window = env.model, env.dt, env.settle_steps
    probe = DynamicsProbe(model)
    steps = tasks[0].steps
    targets = [held_cubic(task, env.planner, model, window) for task in tasks]
    weights = [env.weights(task) for task in tasks]
    settles = [Settle.of(task, steps, window) for task in tasks]
    jobs = [Job(t, w, None, None, s) for t, w, s in zip(targets, weights, settles, strict=True)]
    rollout, _ = execute_batch(model, dataclasses.replace(env.loop, controller="mpc"), jobs)
    metrics = settle_arrays(rollout, np.array([w[0] for w in weights]), np.array([w[1] for w in weights]), settles)
    total = metrics["cost_position"] + metrics["cost_velocity"] + metrics["cost_torque"]
    rows = []
    for b, task in enumerate(tasks):
        q = np.concatenate([rollout.q[b], rollout.q_final[b:b + 1]])
        qd = np.concatenate([rollout.qd[b], rollout.qd_final[b:b + 1]])
        rows.append(_task_rows(task, targets[b], q, qd, weights[b], probe, dt))
    return rows, [float(v) for v in total]


def _task_rows(task: Any, target: Any, q: NDArray[np.float64], qd: NDArray[np.float64], weights: Any,
               probe: Any, dt: float) -> tuple[NDArray[np.float64], ...]:
    """One task's features, labels and weights (see the module docstring)."""
    qdd = np.zeros_like(qd)
    qdd[:-1] = np.diff(qd, axis=0) / dt
    scale = offset_scale(task)
    y = np.concatenate([q - target.q, qd - target.qd, qdd - target.qdd], axis=1) / scale
    mass = start_mass(task, probe)
    row = np.concatenate([weights[0], weights[1] * np.diag(mass) ** 2]) * scale ** 2
    return plan_features(task, target, probe), y, np.tile(row, (q.shape[0], 1))


def fit(labels: Labels, settings: PlanSettings, progress: bool = False) -> tuple[PlanNetwork, list[float]]:
    """The network minimising the weighted mean square (module docstring) and the loss of every epoch (relative
    to the labels' own weighted mean square: 1 is the zero plan)."""
    import torch

    torch.set_num_threads(settings.threads)
    torch.manual_seed(settings.seed)
    mean, std = labels.x.mean(axis=0), labels.x.std(axis=0)
    std = np.where(std < 1e-9 * (1.0 + np.abs(mean)), 1.0, std)  # a feature constant in training: centred only
    x = torch.tensor((labels.x - mean) / std, dtype=torch.float32)
    y = torch.tensor(labels.y, dtype=torch.float32)
    w = torch.tensor(labels.weights(settings.weighting), dtype=torch.float32)
    sizes = (x.shape[1], *settings.hidden, y.shape[1])
    layers: list[Any] = []
    for a, b in zip(sizes[:-1], sizes[1:], strict=True):
        layers += [torch.nn.Linear(a, b), torch.nn.Tanh()]
    net = torch.nn.Sequential(*layers[:-1])
    optimiser = torch.optim.Adam(net.parameters(), settings.learning_rate)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, settings.epochs)
    generator = torch.Generator().manual_seed(settings.seed)
    zero = float(torch.mean(w * y ** 2))
    losses, clock = [], time.perf_counter()
    for epoch in range(settings.epochs):
        order, total = torch.randperm(x.shape[0], generator=generator), 0.0
        for i in range(0, x.shape[0], settings.batch):
            rows = order[i:i + settings.batch]
            loss = torch.mean(w[rows] * (net(x[rows]) - y[rows]) ** 2)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += float(loss.detach()) * rows.numel()
        schedule.step()
        losses.append(total / x.shape[0] / zero)
        if progress:
            print(f"fit: epoch {epoch + 1}/{settings.epochs}, loss {losses[-1]:.4g} of the zero plan's "
                  f"({time.perf_counter() - clock:.0f} s)", flush=True)
    linear = [m for m in net if isinstance(m, torch.nn.Linear)]
    network = PlanNetwork([(m.weight.detach().double().numpy().T.copy(), m.bias.detach().double().numpy().copy())
                           for m in linear], mean, std)
    return network, losses


def _save_labels(labels: Labels, settings: PlanSettings, path: Path) -> None:
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, settings=np.array(json.dumps(settings.label_settings())), **dataclasses.asdict(labels))


def _saved_labels(settings: PlanSettings, path: Path) -> Labels | None:
    """The labels saved at `path` if they were made with these settings."""
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as saved:
            made = json.loads(str(saved["settings"]))
            arrays = {f.name: saved[f.name] for f in dataclasses.fields(Labels)}
    except (OSError, ValueError, KeyError) as e:
        raise InvalidInputError(f"out: {path} is not a labels file of mjtraj rl plan ({e}); use another folder") from e
    if made != settings.label_settings():
        raise InvalidInputError(f"out: {path} holds labels of other settings ({made}, this run's "
                                f"{settings.label_settings()}): use another folder")
    return Labels(**{**arrays, "seconds": float(arrays["seconds"])})


def configuration(settings: PlanSettings) -> str:
    """How tables name a fit's configuration: every setting that shapes the network but the seed (fits of one
    configuration pool as seeds in `rl eval`; the policy's name adds its tracker, `TRACKED`)."""
    default = PlanSettings()
    parts = [f"{settings.weighting} weighting", f"{settings.tasks} tasks", f"{settings.epochs} epochs"]
    for name in ("families", "batch", "learning_rate", "hidden"):
        value = getattr(settings, name)
        if value != getattr(default, name):
            parts.append(f"{name} {'/'.join(map(str, value)) if isinstance(value, tuple) else value}")
    return ", ".join(parts)


@dataclass(frozen=True)
class PlanReport:
    """Where a plan fit wrote its policy and record, and what it cost."""

    policy: Path
    record: dict[str, Any]


def _saved_fit(settings: PlanSettings, path: Path) -> tuple[PlanNetwork, dict[str, Any]] | None:
    """The network and record of the policy saved at `path` if its fit had these settings (`fit_settings`)."""
    if not path.is_file():
        return None
    saved = load_plan(path)
    made = saved.record.get("fit_settings")
    return (saved.network, saved.record) if made == json.loads(json.dumps(settings.fit_settings())) else None


def train_plan(settings: PlanSettings, out: str | Path, *, progress: bool = True, command: str = "") -> PlanReport:
    """Label (or reuse out/labels.npz of the same settings), fit (or reuse the network of out/policy.npz fitted
    with the same settings: a run started again with another tracker only rewrites the policy), and write
    out/policy.npz and out/run.json."""
    from mjtraj.rl.extra import rl_versions

    tracker, env = Tracker.of_rule(settings.tracker), env_settings(settings.window)
    if tracker.settle_periods > env.settle_steps:  # refused before hours of labels and fit
        raise InvalidInputError(f"window: expected a settle window of at least the tracker's {tracker.settle_periods} "
                                f"end periods, got {env.settle_steps} periods ({settings.window} s)")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    labels = _saved_labels(settings, out / "labels.npz")
    if labels is None:
        labels = label(settings, progress=progress)
        _save_labels(labels, settings, out / "labels.npz")
    saved = _saved_fit(settings, out / "policy.npz")
    if saved is None:
        clock = time.perf_counter()
        network, losses = fit(labels, settings, progress=progress)
        seconds, first = round(time.perf_counter() - clock, 1), command
    else:
        network, losses = saved[0], saved[1]["loss"]
        seconds, first = saved[1]["seconds"]["fit"], saved[1]["fit_command"]
    record = {"run": PLAN_RUN, "settings": dataclasses.asdict(settings), "command": command, "fit_command": first,
              "fit_settings": settings.fit_settings(), "tracker": tracker.as_dict(), "versions": rl_versions(),
              "dt": env.dt, "window_steps": env.settle_steps, "env": plan_env(tracker),
              "label": configuration(settings), "streams": settings.streams(),
              "samples": int(labels.x.shape[0]), "mpc_mean_cost": float(labels.cost.mean()),
              "seconds": {"labels": round(labels.seconds, 1), "fit": seconds},
              "loss": [round(v, 6) for v in losses]}
    save_plan(network, record, out / "policy.npz")
    write_text_atomic(out / "run.json", json.dumps({k: v for k, v in record.items() if k != "streams"}, indent=1)
                      + "\n")
    return PlanReport(out / "policy.npz", record)
