"""The deployable policy of a batched run (mjtraj.rl.batched) and its settings: what `mjtraj rl eval --policy
RUN/best.pt` loads, without skrl."""

from __future__ import annotations

import functools
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mjtraj.checks import choice, positive, positive_int
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.streams import check_seed
from mjtraj.study import FAMILIES

BATCHED_RUN = "mjtraj-batched-run/1"
"""The format of a batched run's record (run.json, and inside policy.pt and best.pt)."""

OUTPUTS = ("linear", "cubic")
"""How a policy's network output becomes its action (`BatchedSettings.output`)."""
FEATURES = ("none", "error_over_move")
"""What a policy's network reads besides the observation (`BatchedSettings.features`)."""
ANCHORS = ("none", "disturbance")
"""What a policy's action adds to its network's (`BatchedSettings.anchor`)."""
STRUCTURES = ("none", "gain", "gain_beyond", "gain_full")
"""How a policy's network output is formed from the observation (`BatchedSettings.structure`)."""
GAIN_RANGE = 3.0
"""Standard deviations of the data's e and ed within which a gain-structured policy's output is affine in them; the
gain acts on them clipped to this range (beyond it the response is held, as a saturating command's is, and the
rare large errors of a student's failed episodes do not steer the gain that the small ones decide)."""


@dataclass(frozen=True)
class BatchedSettings:
    """One batched training run: the recipe of mjtraj.rl.batched's module docstring, every setting recorded."""

    steps: int = 10_000_000
    num_envs: int = 512
    rollouts: int = 32
    epochs: int = 5
    minibatches: int = 4
    learning_rate: float = 3e-4
    discount: float = 0.99
    gae_lambda: float = 0.95
    initial_std: float = 0.1
    residual_scale: float = 6.0
    controller: str = "adaptive_computed_torque"
    action_mode: str = "residual"
    """residual: the action adds `residual_scale` N m per unit to the law's command; torque: it replaces the
    command, the saturation per unit (the law then only labels and scores: `reward_baseline`)."""
    families: tuple[str, ...] = ("nominal", "aggressive", "mismatch")
    hidden: tuple[int, ...] = (64, 64)
    seed: int = 0
    threads: int = 1
    evaluations: int = 20
    validation: int = 32
    preview: int = 0
    """Future reference samples the policy observes (the env's `preview`)."""
    preview_frame: str = "absolute"
    """absolute, relative (the preview's samples minus the observed q and qd) or reference (minus q_ref and qd_ref
    now): the env's `preview_frame`."""
    observe_control: bool = False
    """The policy also observes the law's integral state and the next feedforward torque (the env's option)."""
    patience: int = 0
    """Stop once this many validation points in a row have not improved the best worst-family ratio (0: never)."""
    observe_task: bool = False
    """The policy also observes the move and the time to the motion's end (the env's option; UR5Track-v2's)."""
    observe_plant: str = "none"
    """none, or estimate: the policy also observes the adaptive law's estimate of the plant (the env's option; a
    memory of the disturbance)."""
    observe_disturbance: bool = False
    """The policy also observes the torque disturbance `mpc`'s filter estimates (the env's option: `mpc_filter`
    shadows the loop; needs a settle window)."""
    history: int = 0
    """Previous observations the policy also observes (the env's option)."""
    output: str = "linear"
    """How the network's output, clipped to [-1, 1], becomes the action: linear (as it is) or cubic (its cube: the
    same range, finer near 0, where a command of 1 % of the authority is the output 0.22; distillation only)."""
    features: str = "none"
    """What the network also reads, computed from the observation: none, or error_over_move (the position error e
    over the task's move, the unit of the score's weights and of the settling band, 2 % of it: a ratio a tanh network
    would otherwise have to form itself; needs observe_task; distillation only)."""
    anchor: str = "none"
    """What the action adds to the network's: none, or disturbance (the torque that cancels the disturbance `mpc`'s
    filter estimates, -d over the saturation, observed with observe_disturbance; torque mode): the network then
    learns the rest of the command, which at rest is a correction of a few N m where the command itself holds a
    payload of tens (an offset-free anchor, as `mpc`'s own prediction is; distillation only). The network's output
    stays within [-1, 1] of the anchor, the sum within the saturation: a command farther from the anchor than the
    saturation is out of reach (its label is clipped so)."""
    structure: str = "none"
    """How the network forms its output: none (a function of the whole standardised observation), gain,
    gain_beyond or gain_full (distillation only). gain: an offset k and a gain matrix K (n x 2n), both functions of
    the observation without the measured entries q, qd, e and ed; the output is k + K [e; ed], e and ed standardised
    and clipped to GAIN_RANGE: affine in e and ed given the rest (which may hold memories of the measurement: a
    filtered disturbance, the PID integral), as a predictive law's answer is along its reference where no limit
    binds, so that the response to a velocity error, an alternating one included, is one learned gain; needs a
    linear output, a preview frame that does not read the measurement (absolute or reference), no features and no
    history. gain_beyond: as gain, k and K also reading how far e and ed lie beyond GAIN_RANGE (0 within it): affine
    within the range, free beyond it (the same needs). gain_full: the same output, k and K functions of the whole
    observation (a network beside a gain path, nonlinear in e and ed where the data asks it; any output, frame,
    features or history). With any of them the distillation's loss does not push the output past a label at the
    action's limit."""
    settle: float = 0.0
    """The episodes' settle window, s, in training and validation (0: protocol v1's episodes scored by J_exec; 0.5:
    protocol v2's, scored by J_settle, held to the at-rest rule, the measured state observed)."""
    init: str = ""
    """A policy file (a batched run's or a distillation's policy.pt or best.pt) whose mean network and observation
    standardisation start the policy ('' : the law alone, the mean's last layer zeroed); its observation, action and
    network settings must be these."""

    def __post_init__(self) -> None:
        for name in ("steps", "num_envs", "rollouts", "epochs", "minibatches", "threads", "evaluations",
                     "validation"):
            positive_int(name, getattr(self, name))
        for name in ("preview", "patience", "history"):
            if not isinstance(getattr(self, name), int) or getattr(self, name) < 0:
                raise InvalidInputError(f"{name}: expected an integer >= 0, got {getattr(self, name)!r}")
        if not (isinstance(self.settle, (int, float)) and self.settle >= 0 and self.settle < float("inf")):
            raise InvalidInputError(f"settle: expected a window >= 0 s, got {self.settle!r}")
        if not isinstance(self.init, str):
            raise InvalidInputError(f"init: expected a policy file's path, got {self.init!r}")
        for name in ("learning_rate", "initial_std", "residual_scale"):
            positive(name, getattr(self, name))
        for name in ("discount", "gae_lambda"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise InvalidInputError(f"{name}: expected a number in (0, 1], got {getattr(self, name)!r}")
        if not self.families:
            raise InvalidInputError("families: expected at least one family, got none")
        for family in self.families:
            choice("families", family, FAMILIES)
        if self.num_envs < len(self.families):
            raise InvalidInputError(f"num_envs: expected at least one sub-env per family ({len(self.families)}), got "
                                    f"{self.num_envs}")
        if any(int(h) < 1 for h in self.hidden):
            raise InvalidInputError(f"hidden: expected layer widths >= 1 (none: a linear network), got "
                                    f"{self.hidden!r}")
        check_seed("seed", self.seed)
        self._check_policy()
        from mjtraj.core import controller_names
        from mjtraj.envs import PREVIEW_FRAMES

        choice("controller", self.controller, controller_names())
        choice("preview_frame", self.preview_frame, PREVIEW_FRAMES)

    def _check_policy(self) -> None:
        """The action's and the observation's settings, and what each needs of the others."""
        if self.observe_disturbance and not self.settle > 0:
            raise InvalidInputError(f"observe_disturbance: mpc's filter runs in protocol v2's episodes; expected "
                                    f"settle > 0, got {self.settle!r}")
        choice("observe_plant", self.observe_plant, ("none", "estimate"))
        choice("action_mode", self.action_mode, ("residual", "torque"))
        choice("output", self.output, OUTPUTS)
        choice("features", self.features, FEATURES)
        choice("anchor", self.anchor, ANCHORS)
        if self.anchor != "none" and not (self.observe_disturbance and self.action_mode == "torque"):
            raise InvalidInputError(f"anchor: {self.anchor} cancels the observed disturbance with the whole torque; "
                                    f"expected observe_disturbance true and action_mode torque, got "
                                    f"{self.observe_disturbance} and {self.action_mode!r}")
        if self.features != "none" and not self.observe_task:
            raise InvalidInputError(f"features: {self.features} reads the task's move, which the policy observes with "
                                    f"observe_task; expected observe_task true, got false")
        choice("structure", self.structure, STRUCTURES)
        if self.structure in ("gain", "gain_beyond"):
            wanted = {"output": "linear", "features": "none", "history": 0}
            wrong = [f"{k} {getattr(self, k)!r}" for k, v in wanted.items() if getattr(self, k) != v]
            if self.preview_frame == "relative":
                wrong.append("preview_frame 'relative'")
            if wrong:
                raise InvalidInputError(f"structure: {self.structure} reads the measured state through e and ed "
                                        f"alone; expected output linear, features none, history 0 and a preview "
                                        f"frame absolute or reference, got {', '.join(wrong)}")
        if self.action_mode == "torque" and self.observe_plant != "none":
            raise InvalidInputError(f"observe_plant: a torque policy cannot observe the adaptive law's estimate (the "
                                    f"law does not run under its torque), expected none, got {self.observe_plant!r}")

    def extra_inputs(self, n: int) -> int:
        """How many values `features` adds to the network's input for n joints."""
        return n if self.features == "error_over_move" else 0

    def network_outputs(self, n: int) -> int:
        """The network's outputs for n joints: n, or with a gain structure n + 2 n^2 (k, then K row by row)."""
        return n if self.structure == "none" else n + 2 * n * n

    @property
    def iterations(self) -> int:
        """PPO updates: steps / (num_envs x rollouts), rounded up."""
        return -(-self.steps // (self.num_envs * self.rollouts))

    def split(self) -> list[int]:
        """Sub-envs per family, as even as possible (the first families take the remainder)."""
        base, extra = divmod(self.num_envs, len(self.families))
        return [base + (k < extra) for k in range(len(self.families))]

    def env_kwargs(self, family: str) -> dict[str, Any]:
        """The UR5Track arguments of the sub-envs of `family`."""
        return {"action_mode": self.action_mode, "residual_scale": self.residual_scale, "controller": self.controller,
                "task": "random", "family": family, "reward_baseline": "controller", **self.observation(),
                **({"settle": self.settle, "observe_measured": True} if self.settle else {})}

    def observation(self) -> dict[str, Any]:
        """The env options that shape what the policy observes (a deployed policy declares them: `env`)."""
        optional = (("observe_task", False), ("observe_plant", "none"), ("observe_disturbance", False), ("history", 0),
                    ("preview_frame", "absolute"))
        extra = {name: getattr(self, name) for name, default in optional if getattr(self, name) != default}
        return {"preview": self.preview, "observe_control": self.observe_control, **extra}


def mlp(inputs: int, outputs: int, hidden: tuple[int, ...]) -> Any:
    """The networks of a batched run: tanh layers of `hidden` widths, then a linear layer to `outputs` (no `hidden`:
    that layer alone, a linear function of the standardised observation)."""
    import torch

    layers: list[Any] = []
    width = inputs
    for size in hidden:
        layers += [torch.nn.Linear(width, int(size)), torch.nn.Tanh()]
        width = int(size)
    return torch.nn.Sequential(*layers, torch.nn.Linear(width, outputs))


@functools.cache
def batched_policy_class() -> type:
    """The deployable policy's class: standardise the observation as training did, the mean network (with the gain
    `structure`, k + K [e; ed]), clip to [-1, 1], cube if its `output` is cubic, add its anchor (made on first use:
    PyTorch is imported only here)."""
    import torch

    class BatchedPolicy(torch.nn.Module):
        batched = True

        def __init__(self, inputs: int, outputs: int, settings: BatchedSettings) -> None:
            super().__init__()
            extra = settings.extra_inputs(outputs)
            n = outputs
            # gain structure: the network reads the observation without q, qd (entries 0..2n) and e, ed (4n..6n),
            # which enter as K [e; ed] alone (gain_beyond: and their excess beyond the range; gain_full: the whole
            # observation, and K [e; ed] beside)
            self.fast = None if settings.structure == "none" else (4 * n, 6 * n)
            self.beyond = settings.structure == "gain_beyond"
            context = torch.ones(inputs + extra, dtype=torch.bool)
            if settings.structure in ("gain", "gain_beyond"):
                context[:2 * n] = False
                context[4 * n:6 * n] = False
            self.register_buffer("context", torch.nonzero(context).ravel(), persistent=False)
            self.n = n
            self.net = mlp(int(context.sum()) + 2 * n * self.beyond, settings.network_outputs(n), settings.hidden)
            for name in ("mean", "std"):
                self.register_buffer(name, torch.zeros(inputs + extra))
            # error_over_move: e (the observation's entries 4n..5n) over the move (observe_task's next to last entry
            # of the current observation, before any history)
            one = inputs // (1 + settings.history)
            self.scaled = (4 * outputs, 5 * outputs, one - 2) if extra else None
            # anchor: the observed disturbance's entries (before observe_task's two, of the current observation)
            end = one - 2 * settings.observe_task
            self.anchored = (end - outputs, end) if settings.anchor != "none" else None
            self.register_buffer("epsilon", torch.zeros(()))
            self.register_buffer("clip", torch.zeros(()))
            self.cubic = settings.output == "cubic"
            self.env = {"planner": "cubic", "controller": settings.controller, "action_mode": settings.action_mode,
                        "residual_scale": settings.residual_scale, **settings.observation()}

        def inputs(self, obs: Any) -> Any:
            """The network's input before standardisation: the observation (B, d), then the `features`."""
            if self.scaled is None:
                return obs
            start, stop, move = self.scaled
            return torch.cat([obs, obs[:, start:stop] / torch.clamp(obs[:, move:move + 1], min=1e-6)], dim=1)

        def raw(self, x: Any) -> Any:
            """(B, n): the output before the clip for standardised inputs x (B, d + features): net(x), or with a
            gain structure k + K [e; ed], (k, K) the network's output at x's context (gain: x without q, qd, e and
            ed; gain_beyond: that and the excess of e and ed beyond GAIN_RANGE; gain_full: all of x), e and ed within
            GAIN_RANGE."""
            if self.fast is None:
                return self.net(x)
            fast = x[:, self.fast[0]:self.fast[1]]
            errors = torch.clamp(fast, -GAIN_RANGE, GAIN_RANGE)
            context = x[:, self.context]  # type: ignore[index]
            out = self.net(torch.cat([context, fast - errors], dim=1) if self.beyond else context)
            n = self.n
            gain = out[:, n:].reshape(-1, n, 2 * n)
            return out[:, :n] + torch.einsum("bij,bj->bi", gain, errors)

        def forward(self, obs: Any) -> Any:
            mean, std, epsilon, clip = self.mean, self.std, self.epsilon, self.clip
            x = torch.clamp((self.inputs(obs) - mean) / (std + epsilon), -clip, clip)  # type: ignore[operator,arg-type]
            action = torch.clamp(self.raw(x), -1.0, 1.0)
            action = action**3 if self.cubic else action
            return action if self.anchored is None else torch.clamp(action + self.anchor(obs), -1.0, 1.0)

        def anchor(self, obs: Any) -> Any:
            """(B, n): what the action adds to the network's for observations (B, d): -d over the saturation."""
            assert self.anchored is not None
            return -obs[:, self.anchored[0]:self.anchored[1]]

    return BatchedPolicy


POLICY_FORMAT = "mjtraj-batched-policy/1"
"""What policy.pt and best.pt hold: the BatchedPolicy's state and the run's record."""
ENSEMBLE_FORMAT = "mjtraj-ensemble-policy/1"
"""What an ensemble's file holds (`mjtraj.rl.ensemble`): each member's module state and run record, and the
ensemble's record."""


def save_policy(module: Any, path: Path, record: dict[str, Any]) -> None:
    """Write a BatchedPolicy and its run's `record` (plain JSON-like values) to `path`, atomically."""
    save_payload({"format": POLICY_FORMAT, "state": module.state_dict(), "record": record}, path)


def save_payload(payload: dict[str, Any], path: Path) -> None:
    """torch.save `payload` (tensors and plain JSON-like values) to `path`, atomically."""
    import torch

    from mjtraj.files import atomic_path

    buffer = io.BytesIO()
    torch.save(payload, buffer)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(buffer.getvalue())


def policy_settings(record: dict[str, Any]) -> BatchedSettings:
    """The BatchedSettings a policy file's `record` holds (JSON's lists back to tuples)."""
    fields: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in record["settings"].items()}
    return BatchedSettings(**fields)


def load_batched(path: str | Path) -> Any:
    """A BatchedPolicy saved by a batched run (policy.pt or best.pt), with its run's record as `record`.

    Raises:
      InvalidInputError: not such a file (an ensemble's file is named so).
    """
    file = Path(path)
    saved = read_saved(file)
    if saved.get("format") == ENSEMBLE_FORMAT:
        raise InvalidInputError(f"policy: {file} is an ensemble (mjtraj rl ensemble); expected one policy saved by "
                                f"mjtraj rl train --batched or mjtraj rl distill")
    if saved.get("format") != POLICY_FORMAT:
        raise InvalidInputError(f"policy: {file} is not a policy saved by mjtraj rl train --batched")
    return module_from_state(saved["state"], saved["record"])


def read_saved(file: Path) -> dict[str, Any]:
    """What torch saved in a policy `file` ({} when it is not a dict).

    Raises:
      InvalidInputError: no such file, or not one torch can read with weights only.
    """
    import torch

    if not file.is_file():
        raise InvalidInputError(f"policy: file not found: {file}")
    try:
        saved = torch.load(file, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - torch raises many kinds for a file that is not its own
        raise InvalidInputError(f"policy: {file} is not a policy saved by mjtraj rl train --batched ({e})") from e
    return saved if isinstance(saved, dict) else {}


def module_from_state(state: dict[str, Any], record: dict[str, Any]) -> Any:
    """The BatchedPolicy of a saved module `state` and its run's `record` (as `record`)."""
    settings = policy_settings(record)
    outputs = state[[k for k in state if k.endswith("bias")][-1]].numel()
    if settings.structure != "none":  # n + 2 n^2 outputs
        outputs = (math.isqrt(1 + 8 * outputs) - 1) // 4
    module = batched_policy_class()(state["mean"].numel() - settings.extra_inputs(outputs), outputs, settings)
    module.load_state_dict(state)
    module.record = record
    return module


def label(record: dict[str, Any]) -> str:
    """How tables name a batched run's configuration (its seeds share it): planner+LAW+residual PPO, the residual
    scale, the families trained on and the initial std."""
    from mjtraj.rl import law_label

    s = record["settings"]
    if s.get("action_mode", "residual") == "torque":
        return f"cubic+torque batched PPO ({'+'.join(s['families'])}, std {s['initial_std']:g})"
    return (f"cubic+{law_label(s['controller'])}+residual batched PPO ({s['residual_scale']:g} N m, "
            f"{'+'.join(s['families'])}, std {s['initial_std']:g})")
