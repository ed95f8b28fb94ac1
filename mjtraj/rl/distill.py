"""Imitation of a control law (behaviour cloning, then DAgger) on mjtraj's native vector env.

The student is a residual on the env's control law (`controller`, the adaptive law by default) with the authority
`residual_scale` N m per unit (60 by default: up to the saturation). Its label at a state is what makes the loop
apply the teacher's command there: a* = clip((tau_teacher - tau_law) / residual_scale, -1, 1), with tau_teacher the
teacher's saturated command and tau_law the law's own command before the saturation, both asked of the env's
teachers (`ClosedLoop.teach`: the teacher, and the law itself, each shadowing the loop on the same measured states).

Round 0 runs the teacher's labels as the actions (behaviour cloning on the teacher's own states); each later round
runs the student, labels the states it visits, adds them to the data set and trains again on all of it (DAgger,
Ross et al. 2011). Sub-envs are split over `families`; round r's sub-env i starts from the training stream
[seed, 16, r B + i] (`mjtraj.rl.streams`, B sub-envs) and continues it across its episodes, never an evaluation
scenario. The network is the batched runs' (tanh layers, the observation standardised by the data's mean and std,
the output clipped to [-1, 1]), saved in their format (`mjtraj.rl.batched_policy`): `mjtraj rl eval --policy
RUN/best.pt` scores it. After every round the student is validated as a batched run is
(`mjtraj.rl.batched.Validation`: the validation stream, paired with the law alone, or with the teacher alone:
`validate_versus`; learning_curve.csv), best.pt is the best round so far and policy.pt the last; the data set, the
rows, the network, the optimiser and the generators are saved (resume.pt), and `resume` continues bit for bit (every
round starts its sub-envs afresh from their streams, so no simulation state needs saving).
"""

from __future__ import annotations

import dataclasses
import io
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import choice, positive, positive_int
from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path, write_text_atomic
from mjtraj.rl.batched_policy import BATCHED_RUN, BatchedSettings, batched_policy_class, save_policy
from mjtraj.rl.extra import rl_versions
from mjtraj.rl.streams import TRAIN_STREAM, VALIDATION_STREAM, stream_seed

DISTILL_RUN = "mjtraj-distill-run/1"
"""The format of a distillation's own part of its record (`distill`); the record is otherwise a batched run's, so
that everything that reads a batched policy reads a distilled one."""


@dataclass(frozen=True)
class DistillSettings:
    """One distillation: the teacher, the student's action and network, and the DAgger schedule."""

    teacher: str = "mpc"
    controller: str = "adaptive_computed_torque"
    """The law the student's residual acts on."""
    residual_scale: float = 60.0
    """N m per unit of action: 60, the saturation, lets the student command anything the teacher does."""
    action_mode: str = "residual"
    """residual: the student adds to `controller`'s command; torque: it commands the whole corrective torque, the
    saturation per unit (its label the teacher's saturated command over the saturation; `controller` then only runs
    beside it, and a student cannot observe its estimate: `observe_plant` must be none)."""
    families: tuple[str, ...] = ("nominal", "aggressive", "mismatch")
    num_envs: int = 24
    rounds: int = 4
    """Data-collection rounds: the teacher's own (behaviour cloning), then the student's (DAgger)."""
    steps: int = 150
    """Steps of every sub-env per round."""
    epochs: int = 30
    """Passes over the aggregated data after each round."""
    batch: int = 512
    learning_rate: float = 1e-3
    hidden: tuple[int, ...] = (256, 256, 256)
    preview: int = 10
    """Future reference samples the student observes (the env's `preview`)."""
    preview_frame: str = "absolute"
    """absolute; relative: the preview's samples minus the observed q and qd; reference: minus q_ref and qd_ref now
    (the env's `preview_frame`)."""
    observe_task: bool = False
    """The student also observes the move and the time to the motion's end (UR5Track-v2's observation)."""
    observe_control: bool = False
    """The student also observes the loop's PID integral of e and the next feedforward torque (the env's option; the
    integral runs under `controller` pid, in torque mode too: a memory of a persistent error)."""
    observe_plant: str = "none"
    """none, or estimate: the student also observes the adaptive law's estimate of the plant (a memory of the
    disturbance: payload, damping, friction)."""
    observe_disturbance: bool = False
    """The student also observes the torque disturbance `mpc`'s filter estimates (`mpc_filter` shadowing the loop:
    the estimate `mpc` plans from, at the cost of a filter step), a memory of the disturbance for a torque student."""
    history: int = 0
    """Previous observations the student also observes."""
    features: str = "none"
    """What the student's network also reads (`BatchedSettings.features`): none, or error_over_move."""
    anchor: str = "none"
    """What the student's action adds to its network's (`BatchedSettings.anchor`): none, or disturbance."""
    structure: str = "none"
    """How the student's network forms its output (`BatchedSettings.structure`): none, gain (k + K [e; ed], k and K
    functions of the rest of the observation), gain_beyond (k and K also of the excess of e and ed beyond the range
    where the output is affine) or gain_full (k and K of the whole observation); with a gain structure the loss does
    not push the output past a label at the action's limit (any output beyond it makes the same command; the
    change term, `change_weight`, stays two-sided)."""
    output: str = "linear"
    """How the network's output becomes the action: linear, or cubic (its cube; the network then learns the labels'
    cube roots, so that a nominal motion's corrections of a few hundredths of the authority are fitted as finely,
    relative to their size, as an aggressive motion's tens of N m)."""
    mixing: float = 0.0
    """DAgger's beta (Ross et al. 2011): in round r >= 1 each sub-env's step applies the teacher's label with
    probability mixing^r (drawn from the run's generator), else the student's action; 0: the student alone."""
    action_noise: float = 0.0
    """N m: the standard deviation of a Gaussian torque added to every action the collection applies (where
    `noise_on` says), per joint and period (drawn from the run's generator; the action then clipped to [-1, 1]), in
    every round; the labels stay the teacher's at the states visited. DART (Laskey et al. 2017): the data then holds
    the teacher's answers to the deviations a student's errors cause, not only to the states its own motion visits.
    0: none."""
    noise_on: str = "all"
    """Which applied actions get `action_noise`: all, or teacher (only the teacher's: all of round 0, and in later
    rounds the steps where mixing lets the teacher act; DART's noise on the supervisor, the student's own errors
    perturbing the rest)."""
    change_weight: float = 0.0
    """Weight of a second loss term: the squared error of the network's change between a sub-env's consecutive
    labelled periods against its targets' change (what the network learns: the labels less the anchor, their cube
    roots with the cubic output; in the first term's units and weights), so that the student matches how the
    teacher's command moves with the state along the data, not only its value: a student whose gain is off commands
    a different change (its torque alternating from period to period where the teacher's barely does). 0: none (the
    first term alone)."""
    decay: bool = False
    """Anneal the learning rate by a cosine to a thousandth of `learning_rate` over each round's epochs (restarting
    each round); False: constant."""
    balance: str = "none"
    """How the loss weighs the families: none (every labelled state alike: the largest labels, an aggressive motion's,
    dominate), family (each state's squared error divided by its family's mean squared label in the data, so that
    each family's corrections count at their own scale), or family-hold (the same per family and phase: the states
    of the motion and those of the settle window, where the labels that bring the arm to rest are small, apart)."""
    settle: float = 0.5
    """The episodes' settle window, s (protocol v2's)."""
    validation: int = 24
    """Validation tasks per family scored after every round (the batched runs' validation: the validation stream,
    paired with the law alone; best.pt is the best round by `selection_key`); 0: none, best.pt is the last round."""
    validate_versus: str = "law"
    """What validation pairs the student with: law (the law alone, `controller`, as a batched run does) or teacher
    (the teacher alone: the ratios and missed episodes are then over the ruler the student imitates, and best.pt is
    the round closest to it)."""
    task: str = "random"
    """The envs' task: random (the families' draws) or paper (the paper's move every episode: a check that the
    student reproduces its teacher where it was trained)."""
    seed: int = 0
    threads: int = 1

    def __post_init__(self) -> None:
        from mjtraj.core import controller_names

        choice("teacher", self.teacher, controller_names())
        choice("controller", self.controller, controller_names())
        for name in ("num_envs", "rounds", "steps", "epochs", "batch", "threads"):
            positive_int(name, getattr(self, name))
        if not isinstance(self.validation, int) or self.validation < 0:
            raise InvalidInputError(f"validation: expected a number of tasks >= 0, got {self.validation!r}")
        for name in ("residual_scale", "learning_rate"):
            positive(name, getattr(self, name))
        if not (isinstance(self.mixing, (int, float)) and 0.0 <= self.mixing < 1.0):
            raise InvalidInputError(f"mixing: expected a probability in [0, 1), got {self.mixing!r}")
        _finite_nonnegative("action_noise", self.action_noise, "a finite standard deviation >= 0, N m")
        choice("noise_on", self.noise_on, NOISE_ON)
        if self.noise_on != "all" and not self.action_noise:
            raise InvalidInputError(f"noise_on: {self.noise_on} chooses where action_noise goes and needs some; "
                                    f"expected action_noise > 0, got {self.action_noise!r}")
        _finite_nonnegative("change_weight", self.change_weight, "a finite weight >= 0")
        choice("task", self.task, ("random", "paper"))
        choice("balance", self.balance, BALANCES)
        if self.balance == "family-hold" and not self.settle > 0:
            raise InvalidInputError(f"balance: family-hold weighs the settle window apart and needs one (settle > 0), "
                                    f"got settle={self.settle!r}")
        choice("action_mode", self.action_mode, ("residual", "torque"))
        choice("validate_versus", self.validate_versus, ("law", "teacher"))
        self.policy_settings()  # the batched runs' checks: families, sub-envs, widths, seed, preview, settle, ...

    def split(self) -> list[int]:
        """Sub-envs per family, as even as possible (the batched runs' split)."""
        return self.policy_settings().split()

    def env_kwargs(self, family: str) -> dict[str, Any]:
        """The UR5Track arguments of the sub-envs of `family`: the student's action on the law, the teacher beside
        it, the measured state observed (as protocol v2 gives it)."""
        return {"action_mode": self.action_mode, "residual_scale": self.residual_scale, "controller": self.controller,
                "task": self.task, **({"family": family} if self.task == "random" else {}),
                **self.policy_settings().observation(), "settle": self.settle,
                "observe_measured": True, "teacher": self.teacher}

    def policy_settings(self) -> BatchedSettings:
        """The deployable policy's settings in the batched runs' format (what `load_batched` rebuilds)."""
        return BatchedSettings(num_envs=self.num_envs, residual_scale=self.residual_scale, controller=self.controller,
                               families=self.families, hidden=self.hidden, seed=self.seed, threads=self.threads,
                               action_mode=self.action_mode, settle=self.settle, preview=self.preview,
                               preview_frame=self.preview_frame,
                               observe_task=self.observe_task, observe_control=self.observe_control,
                               observe_plant=self.observe_plant, observe_disturbance=self.observe_disturbance,
                               history=self.history, output=self.output, features=self.features,
                               anchor=self.anchor, structure=self.structure,
                               validation=max(self.validation, 1))

    def families_of_envs(self) -> NDArray[np.intp]:
        """(num_envs,): the position in `families` of each sub-env's family."""
        return np.repeat(np.arange(len(self.families)), self.split())


@dataclass(frozen=True)
class DistillReport:
    """Where a distillation wrote its policies and record, and how its rounds went."""

    out: Path
    policy: Path
    rounds: list[dict[str, Any]]
    best: Path
    """best.pt: the best validated round's policy (the last round's without validation)."""
    best_point: dict[str, float]
    """The best round's row ({} without validation)."""
    stopped: str = ""
    """Why it stopped before its last round ('' if it did not)."""


def _finite_nonnegative(name: str, value: object, expected: str) -> None:
    """Raise naming `name` and `expected` unless `value` is a finite int or float >= 0 (not a bool, not a str)."""
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and 0.0 <= value < float("inf")):
        raise InvalidInputError(f"{name}: expected {expected}, got {value!r}")


def distill_defaults() -> dict[str, Any]:
    """Every DistillSettings field's default (what a record written before a field existed meant)."""
    return {f.name: f.default for f in dataclasses.fields(DistillSettings) if f.default is not dataclasses.MISSING}


NOISE_ON = ("all", "teacher")
"""Which applied actions get the collection's noise (`DistillSettings.noise_on`)."""

BALANCES = ("none", "family", "family-hold")
"""How the distillation loss weighs its labelled states (`DistillSettings.balance`)."""


def labels(env: Any, teacher: str, controller: str, scale: float) -> NDArray[np.float64]:
    """The student's labels at the vector env's current states, (B, n) in [-1, 1]: the action that makes the loop
    apply the teacher's command; in residual mode (tau_teacher - tau_law) / scale, in torque mode tau_teacher over
    the saturation; clipped."""
    loop = env.loop
    wanted = loop.teach(teacher).dtau
    if env.settings.action_mode == "torque":
        return np.clip(wanted / env.settings.action_scale, -1.0, 1.0)  # type: ignore[no-any-return]
    own = loop.teach(controller)
    return np.clip((wanted - (own.tau_ff + own.tau_fb)) / scale, -1.0, 1.0)  # type: ignore[no-any-return]


class _Families:
    """Sub-envs of the families side by side (one native vector env per family, or per sub-env where a law
    previews references of one length: `mjtraj.rl.batched.MixedFamilies`), with their labels."""

    def __init__(self, settings: DistillSettings) -> None:
        from mjtraj.rl.batched import MixedFamilies

        self.settings = settings
        self.mixed = MixedFamilies(settings)  # type: ignore[arg-type]

    @property
    def actions(self) -> int:
        """n, the action's size."""
        shape = cast(tuple[int, ...], self.mixed.single_action_space.shape)  # a Box's, never None
        return int(shape[0])

    @property
    def action_scale(self) -> NDArray[np.float64]:
        """(n,) N m per unit of action (the envs' `action_scale`: the residual's authority, or the saturation)."""
        return self.mixed.envs[0].settings.action_scale  # type: ignore[no-any-return]

    def reset(self, round_: int) -> NDArray[np.float64]:
        """Every sub-env from its stream of round `round_`: [seed, TRAIN_STREAM, round_ B + i]."""
        s, m = self.settings, self.mixed
        seeds: list[int | None] = [stream_seed(s.seed, TRAIN_STREAM, round_ * s.num_envs + i)
                                   for i in range(s.num_envs)]
        bounds = m._bounds  # noqa: SLF001 - the mixture's own split
        return np.concatenate([env.reset(seed=seeds[a:b])[0]
                               for env, a, b in zip(m.envs, bounds, bounds[1:], strict=False)])

    def labels(self) -> NDArray[np.float64]:
        s = self.settings
        return np.concatenate([labels(env, s.teacher, s.controller, s.residual_scale) for env in self.mixed.envs])

    def holding(self) -> NDArray[np.bool_]:
        """(num_envs,): the sub-envs in their settle window now."""
        return np.concatenate([env.holding for env in self.mixed.envs])

    def step(self, actions: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.mixed.step(actions)[0]


def distill(settings: DistillSettings, out: str | Path, *, progress: bool = True, command: str = "",
            resume: bool = False, on_validation: Callable[[int, float], bool] | None = None) -> DistillReport:
    """Distil `settings.teacher` into a residual policy on `settings.controller` (the module docstring), writing
    policy.pt (the last round's), best.pt (the best validated round's), learning_curve.csv, run.json and resume.pt
    to `out`. `on_validation(samples, selection_value(row))`, called after each validated round, stops the
    distillation when it returns True (a search's pruner; run.json's "stopped" says so).

    Raises:
      InvalidInputError: `out` holds another run (without `resume`), or nothing to resume.
    """
    import torch

    from mjtraj.rl.batched import Validation, selection_key

    out = Path(out)
    saved = out / "resume.pt"
    if resume and not saved.is_file():
        raise InvalidInputError(f"out: nothing to resume in {out} (no resume.pt)")
    if not resume and (out / "run.json").exists():
        raise InvalidInputError(f"out: {out} holds a run already; give another folder or resume it")
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(settings.threads)
    torch.manual_seed(settings.seed)
    env = _Families(settings)
    policy_settings = settings.policy_settings()
    obs = env.reset(0)
    module = batched_policy_class()(obs.shape[1], env.actions, policy_settings)
    module.clip.fill_(10.0)
    module.epsilon.fill_(1e-8)
    optimiser = torch.optim.Adam(module.net.parameters(), lr=settings.learning_rate)
    rng = np.random.default_rng([settings.seed, TRAIN_STREAM, 99])
    versus = settings.teacher if settings.validate_versus == "teacher" else ""
    validation = Validation(policy_settings, versus) if settings.validation else None
    record = _record(settings, command, validation)
    run = _Progress()
    if resume:
        run = _resumed(saved, settings, module, optimiser, rng, record)
    clock = time.perf_counter()
    stopped = ""
    for r in range(run.round, settings.rounds):
        start = time.perf_counter()
        x, y, hold = _collect(env, module, settings, rng, r)
        run.x.append(x)
        run.y.append(y)
        run.hold.append(hold)
        collected = time.perf_counter() - start
        states = np.concatenate(run.x)  # every round's: the largest array a distillation holds, made once a round
        labels_now = np.concatenate(run.y)
        fitted = targets(_less_anchor(module, states, labels_now), settings.output)
        weights = sample_weights(fitted, settings, np.concatenate(run.hold))
        following = successors(states, settings, 6 * env.actions) if settings.change_weight else None
        bound = saturated(labels_now) if settings.structure != "none" else None
        loss = _train(module, optimiser, _inputs(module, states), fitted, weights, settings, rng, following, bound)
        row: dict[str, Any] = {"round": r, "samples": sum(len(x) for x in run.x), "collect_s": collected,
                               "train_s": time.perf_counter() - start - collected, "loss": loss}
        if validation is not None:
            row.update(validation.row(module))
            if selection_key(row) < selection_key(run.best):
                run.best = {k: float(v) for k, v in row.items()}
                save_policy(module, out / "best.pt", {**record, "timesteps": row["samples"], "point": run.best})
        run.history.append(row)
        run.round = r + 1
        _write_curve(out / "learning_curve.csv", run.history)
        if progress:
            print(f"round {r}: {row['samples']} labelled states, loss {loss:.3g}, {collected:.0f} s collecting, "
                  f"{row['train_s']:.0f} s training" + _validated_text(row, validation), flush=True)
        _save_resume(saved, module, optimiser, rng, run, record)
        if validation is not None and on_validation is not None:
            from mjtraj.rl.batched import selection_value

            if on_validation(row["samples"], selection_value(row)):
                stopped = "pruned by the search"
                break
    best = run.best if validation is not None else {}
    record.update(rounds=run.history, wall_s=time.perf_counter() - clock, timesteps=int(run.history[-1]["samples"]),
                  best=best, stopped=stopped)
    save_policy(module, out / "policy.pt", record)
    if validation is None:
        save_policy(module, out / "best.pt", record)
    write_text_atomic(out / "run.json", json.dumps(record, indent=1, default=float) + "\n")
    return DistillReport(out, out / "policy.pt", run.history, out / "best.pt", best, stopped)


@dataclass
class _Progress:
    """A distillation's state between rounds: the data (states, labels, phases per round), the rows, the best row
    and the next round."""

    x: list[NDArray[np.float64]] = dataclasses.field(default_factory=list)
    y: list[NDArray[np.float64]] = dataclasses.field(default_factory=list)
    hold: list[NDArray[np.bool_]] = dataclasses.field(default_factory=list)
    history: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    best: dict[str, float] = dataclasses.field(default_factory=lambda: {"worst_ratio": float("inf"),
                                                                        "missed": float("inf")})
    round: int = 0


def _record(settings: DistillSettings, command: str, validation: Any) -> dict[str, Any]:
    """The run record's settings part (run.json, and inside policy.pt and best.pt)."""
    policy_settings = settings.policy_settings()
    return {"format": BATCHED_RUN, "distill_format": DISTILL_RUN,
            "settings": dataclasses.asdict(policy_settings), "distill": dataclasses.asdict(settings),
            "command": command, "library": "torch (behaviour cloning, DAgger)", "versions": rl_versions(),
            "streams": {"train": {"stream": TRAIN_STREAM, "gym_seeds": [
                stream_seed(settings.seed, TRAIN_STREAM, i) for i in range(settings.rounds * settings.num_envs)]},
                "validation": {"stream": VALIDATION_STREAM,
                               "count": settings.validation * len(settings.families)}},
            **(validation.law_alone() if validation is not None else {})}


def _collect(env: _Families, module: Any, settings: DistillSettings, rng: np.random.Generator, r: int
             ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Round `r`'s states, labels and phases (steps x num_envs rows): the teacher acts in round 0, the student (or,
    with mixing, the teacher with probability mixing^r) after; with action_noise, plus its Gaussian torque (where
    `noise_on` says)."""
    import torch

    obs = env.reset(r)
    xs, ys, holds = [], [], []
    for _ in range(settings.steps):
        label = env.labels()
        xs.append(obs.copy())
        ys.append(label)
        holds.append(env.holding())
        teaching = np.full(len(label), r == 0)
        if r == 0:
            action = label
        else:
            with torch.no_grad():
                action = module(torch.as_tensor(obs, dtype=torch.float32)).numpy().astype(np.float64)
            if settings.mixing:
                teaching = rng.random(len(action)) < settings.mixing**r
                action = np.where(teaching[:, None], label, action)
        if settings.action_noise:
            noise = rng.normal(0.0, settings.action_noise, action.shape) / env.action_scale
            if settings.noise_on == "teacher":
                noise *= teaching[:, None]
            action = np.clip(action + noise, -1.0, 1.0)
        obs = env.step(action)
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(holds)


def _resumed(saved: Path, settings: DistillSettings, module: Any, optimiser: Any, rng: np.random.Generator,
             record: dict[str, Any]) -> _Progress:
    """Load resume.pt into the module, the optimiser and the generators; the distillation's progress.

    Raises:
      InvalidInputError: it holds a distillation with other settings.
    """
    import torch

    state = torch.load(saved, map_location="cpu", weights_only=False)
    saved_settings = state["record"]["distill"]
    theirs: dict[str, Any] = {**distill_defaults(), **{k: tuple(v) if isinstance(v, list) else v
                                                for k, v in saved_settings.items()}}
    if DistillSettings(**theirs) != settings:  # settings added since it was saved: their defaults
        raise InvalidInputError(f"out: {saved.parent} holds a distillation with other settings; give another folder")
    module.load_state_dict(state["module"])
    optimiser.load_state_dict(state["optimiser"])
    torch.set_rng_state(state["torch_rng"])
    rng.bit_generator.state = state["rng"]
    run = _Progress(state["x"], state["y"], [], state["history"], round=state["round"])
    # a resume point from before the phases were kept: its balance (none or family) does not read them
    run.hold = state.get("hold", [np.zeros(len(y), dtype=bool) for y in run.y])
    run.best = state.get("best", run.best)
    record["resumed"] = [*state["record"].get("resumed", []), {"round": run.round}]
    return run


def _validated_text(row: dict[str, Any], validation: Any) -> str:
    """A round's validation for its progress line ('' without one)."""
    if validation is None:
        return ""
    return (f"; validation: worst family {row['worst_ratio']:.4f} of {validation.reference()}, "
            f"{row['missed']:.0f} missed")


def _write_curve(path: Path, rows: list[dict[str, Any]]) -> None:
    """learning_curve.csv: one row per round (round, samples, collect_s, train_s, loss, then the validation's)."""
    import csv

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: repr(v) if isinstance(v, float) else v for k, v in r.items()} for r in rows)
    write_text_atomic(path, buffer.getvalue())


def _inputs(module: Any, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """The network's inputs (M, d + features) for observations x (M, d), as the module computes them."""
    import torch

    if module.scaled is None:
        return x
    return module.inputs(torch.as_tensor(x, dtype=torch.float64)).numpy()  # type: ignore[no-any-return]


def _less_anchor(module: Any, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """What the network's action is to be for labels y (M, n) at observations x (M, d): the labels less the
    module's anchor (`BatchedSettings.anchor`), within [-1, 1]."""
    import torch

    if module.anchored is None:
        return y
    return np.clip(y - module.anchor(torch.as_tensor(x)).numpy(), -1.0, 1.0)  # type: ignore[no-any-return]


def targets(y: NDArray[np.float64], output: str) -> NDArray[np.float64]:
    """What the network learns for actions y (M, n) in [-1, 1]: y itself (linear output) or its cube root (cubic)."""
    return np.cbrt(y) if output == "cubic" else y


def saturated(y: NDArray[np.float64]) -> NDArray[np.int8]:
    """(M, n): +1 where a label of y (M, n) is at the action's upper limit, -1 at the lower, 0 elsewhere (in torque
    mode the teacher's command saturated; in residual mode the command beyond the residual's authority)."""
    return np.where(y >= 1.0, 1, np.where(y <= -1.0, -1, 0)).astype(np.int8)


def one_sided(error: Any, bound: Any) -> Any:
    """The output's error (B, n) against its targets, 0 where a label at the limit (`bound` (B, n): +1 upper, -1
    lower) is met or passed: any output beyond it makes the same saturated command."""
    import torch

    return torch.where(bound > 0, torch.clamp(error, max=0.0), torch.where(bound < 0, torch.clamp(error, min=0.0),
                                                                           error))


def successors(x: NDArray[np.float64], settings: DistillSettings, phase: int) -> NDArray[np.intp]:
    """(M,): for each of the labelled states x (M, d) gathered round by round (a round's steps x num_envs rows,
    step-major), the row of its sub-env's next period in the same episode, or -1 (a round's last step, or an
    episode's last period: the next row's phase, column `phase` of x, is not later)."""
    rows = np.arange(len(x))
    step = settings.steps * settings.num_envs
    following = rows + settings.num_envs
    last = (rows % step) >= step - settings.num_envs
    following[last] = rows[last]  # a placeholder, refused below: the next round is another episode
    later = ~last & (x[following, phase] > x[rows, phase])
    return np.where(later, following, -1)


def _train(module: Any, optimiser: Any, x: NDArray[np.float64], y: NDArray[np.float64], w: NDArray[np.float64],
           settings: DistillSettings, rng: np.random.Generator, following: NDArray[np.intp] | None = None,
           bound: NDArray[np.int8] | None = None) -> float:
    """`settings.epochs` passes of mean-squared error of the network's output (`raw`, before the clip) over (x, y) in
    shuffled minibatches, each state weighted by w (`sample_weights`), the standardisation refitted to all of x
    first; with `following` ((M,): each row's successor row or -1, `successors`) and a change_weight, plus
    change_weight times the same error of the output's change from each state to its successor against y's change;
    with `bound` ((M, n), `saturated`) the error is `one_sided` where a label is at the limit; the last epoch's mean
    loss."""
    import torch

    module.mean.copy_(torch.as_tensor(x.mean(axis=0), dtype=torch.float32))
    module.std.copy_(torch.as_tensor(x.std(axis=0), dtype=torch.float32))
    inputs = torch.as_tensor(x, dtype=torch.float32)
    targets = torch.as_tensor(y, dtype=torch.float32)
    weights = torch.as_tensor(w, dtype=torch.float32)[:, None]
    normal = torch.clamp((inputs - module.mean) / (module.std + module.epsilon), -module.clip, module.clip)
    after = None if following is None or not settings.change_weight else torch.as_tensor(following)
    limits = None if bound is None else torch.as_tensor(bound)
    loss_sum = 0.0
    for epoch in range(settings.epochs):
        # with decay, a cosine from learning_rate to a thousandth of it over the round's epochs
        share = 1e-3 + (1 - 1e-3) * 0.5 * (1 + np.cos(np.pi * epoch / settings.epochs)) if settings.decay else 1.0
        for group in optimiser.param_groups:
            group["lr"] = settings.learning_rate * share
        order = torch.as_tensor(rng.permutation(len(x)))
        loss_sum, batches = 0.0, 0
        for k in range(0, len(x), settings.batch):
            pick = order[k:k + settings.batch]
            output = module.raw(normal[pick])
            error = output - targets[pick]
            if limits is not None:
                error = one_sided(error, limits[pick])
            loss = torch.mean(weights[pick] * error**2)
            if after is not None:
                following_pick = after[pick]
                pair = following_pick >= 0
                first, second = pick[pair], following_pick[pair]
                change = module.raw(normal[second]) - output[pair] - (targets[second] - targets[first])
                loss = loss + settings.change_weight * torch.sum(weights[first] * change**2) / (len(pick) * y.shape[1])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            loss_sum, batches = loss_sum + loss.item(), batches + 1
        loss_sum /= max(batches, 1)
    return loss_sum


def sample_weights(y: NDArray[np.float64], settings: DistillSettings, holding: NDArray[np.bool_] | None = None
                   ) -> NDArray[np.float64]:
    """(M,): each labelled state's weight in the loss, for labels y (M, n) gathered round by round, step-major (a
    round's states are steps x num_envs, sub-env i's family `families_of_envs()[i]`), `holding` (M,) True for the
    states of a settle window (needed by "family-hold"): 1 without balance; with balance "family", 1 / its family's
    mean squared label (mean over the group's states and joints), with "family-hold" 1 / that of its family and
    phase (motion or settle window); scaled so that the weights average 1. A group without states has no weight."""
    if settings.balance == "none":
        return np.ones(len(y))
    groups = np.tile(settings.families_of_envs(), len(y) // settings.num_envs)
    if settings.balance == "family-hold":
        if holding is None or len(holding) != len(y):
            raise InvalidInputError(f"holding: family-hold needs each labelled state's phase, expected {len(y)}, got "
                                    f"{None if holding is None else len(holding)}")
        groups = 2 * groups + holding.astype(int)
    scale = np.array([np.mean(y[groups == g] ** 2) if np.any(groups == g) else 0.0 for g in range(groups.max() + 1)])
    weights = 1.0 / np.maximum(scale, 1e-6 * scale.max(initial=1e-12))[groups]  # a group of zero labels: not 1e12
    return weights / weights.mean()  # type: ignore[no-any-return]


def _save_resume(path: Path, module: Any, optimiser: Any, rng: np.random.Generator, run: _Progress,
                 record: dict[str, Any]) -> None:
    """Everything a resumed distillation needs (the data: states, labels and phases; the rows and the best; the
    network, the optimiser, the generators), atomically."""
    import torch

    buffer = io.BytesIO()
    torch.save({"module": module.state_dict(), "optimiser": optimiser.state_dict(), "torch_rng": torch.get_rng_state(),
                "rng": rng.bit_generator.state, "x": run.x, "y": run.y, "hold": run.hold, "history": run.history,
                "best": run.best, "round": run.round, "record": record}, buffer)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(buffer.getvalue())


def resume_distill(out: str | Path, *, progress: bool = True) -> DistillReport:
    """Continue the distillation saved in `out` (its resume.pt) to its last round.

    Raises:
      InvalidInputError: nothing to resume in `out`.
    """
    import torch

    saved = Path(out) / "resume.pt"
    if not saved.is_file():
        raise InvalidInputError(f"out: nothing to resume in {out} (no resume.pt)")
    record = torch.load(saved, map_location="cpu", weights_only=False)["record"]
    fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in record["distill"].items()}
    return distill(DistillSettings(**fields), out, progress=progress, command=record["command"], resume=True)
