"""`mjtraj rl eval`: the benchmark protocol. Any policies, the planners and every control law on the same
held-out sweep scenarios, in one table with the field's statistics (docs/benchmark.md).

The scenarios are sweep families' (mjtraj.domain.families: seed streams [seed, FAMILY_ID, i]), which no training run
draws from (checked against each zip's recorded training and validation streams). The planners' rows are the
sweep's own (`run_unit`) under each control law; each policy tracks its planner's reference for the same scenario
on the same plant (perturbed per scenario in `mismatch`), on the control law it acts on, with the same saturation,
and is scored by the same metrics and weights. The reference method is cubic+PID. Rows are the sweep's format plus
the columns POLICY_COLUMNS; `eval.csv` holds them all, `summary.json` and `SUMMARY.md` the statistics
(mjtraj.rl.protocol_stats), `profiles.png` the performance profiles.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import json
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mjtraj.checks import choice, positive_int
from mjtraj.core import SETTLE_BAND, SETTLE_SPEED, LoopConfig, controller_names
from mjtraj.exceptions import InvalidInputError, PolicyError
from mjtraj.files import write_text_atomic
from mjtraj.rl import law_label
from mjtraj.rl.adapters import ScoredPolicy, check_settings, load_any
from mjtraj.rl.batched_policy import BATCHED_RUN, ENSEMBLE_FORMAT
from mjtraj.rl.compute import StepCompute, compute_table, law_compute, policy_compute
from mjtraj.rl.ensemble import member_records
from mjtraj.rl.episodes import PolicyActor
from mjtraj.rl.extra import rl_versions
from mjtraj.rl.practice import execution_table, weighting_agreement
from mjtraj.rl.protocol import (
    NOISY_FAMILY,
    NOISY_SIGMA,
    PROTOCOL,
    REFERENCES,
    SCORE_NAMES,
    SETTLE,
    check_protocol,
    departures,
    sweep_family,
)
from mjtraj.rl.protocol_stats import (
    FAILURE_RULE,
    FloorSummary,
    Interval,
    MethodSummary,
    improvement,
    interval_figure,
    paired_against,
    profile_figure,
    ratio_of_means,
    summarize,
    summarize_floor,
)
from mjtraj.rl.streams import VALIDATION_STREAM, check_seed, family_entropies, shared_streams
from mjtraj.study import (
    FAMILIES,
    FIGURE_FORMATS,
    ORACLE_LABEL,
    PAYLOAD_MASS,
    SWEPT,
    ActorSpec,
    SweepSettings,
    TrueParameters,
    columns,
    csv_text,
    numeric,
    run_unit,
)
from mjtraj.versions import describe

POLICY_COLUMNS = ("method", "policy", "policy_kind", "policy_sha256", "policy_timesteps", "policy_privileged",
                  "policy_env")
REFERENCE = REFERENCES["v1"]
"""Protocol v1's reference method: the cubic planner under feedforward + PID, the paper's baseline (protocol v2's is
the adaptive law, REFERENCES)."""
FAMILY_CHOICES = (*FAMILIES, NOISY_FAMILY)
"""The families an evaluation takes: the sweeps' and protocol v2's noisy one."""
LAW_OF = {"cubic+PID": "pid", "cubic+adaptive CT": "adaptive_computed_torque"}
"""The control law each protocol's reference method runs (it always runs, whatever `controllers` says)."""
LAW_SCENARIOS = {"pid": None, "computed_torque": "paper_computed_torque",
                 "adaptive_computed_torque": "paper_adaptive"}
"""The shipped base scenario of each built-in law (None: paper.toml); a plug-in law runs paper.toml with its
controller replaced, written into the output folder."""
TUNED_LABEL = "cubic+PID (tuned gains)"


def check_held_out(policy: Any, family: str, seed: int, scenarios: int) -> None:
    """InvalidInputError if any evaluation scenario's stream is one the policy (a zip: its record; a callable or
    module: its declared `streams`) trained or validated on; a policy that declares none is not checked."""
    if policy.record is None:
        declared = getattr(policy, "streams", None)
        if declared:
            shared = shared_streams(declared, family_entropies(sweep_family(family), seed, range(scenarios)))
            if shared:
                raise InvalidInputError(f"seed: {len(shared)} of the {family} scenarios under seed {seed} share a "
                                        f"seed stream with the streams {policy.label} declares it trained on; choose "
                                        f"another seed")
        return
    used: list[Any] = []
    for record in member_records(policy.record):  # an ensemble's members each trained on their own streams
        streams = record["streams"]
        train_seed = int(record["settings"]["seed"])
        used += list(streams["train"]["gym_seeds"]) + [[train_seed, VALIDATION_STREAM, i]
                                                       for i in range(int(streams["validation"]["count"]))]
    shared = shared_streams(used, family_entropies(sweep_family(family), seed, range(scenarios)))
    if shared:
        raise InvalidInputError(f"seed: {len(shared)} of the {family} scenarios under seed {seed} share a seed stream "
                                f"with {policy.path}'s training; choose another seed")




@dataclass
class EvalReport:
    """Where the evaluation wrote its files, and the summary table's text."""

    out: Path
    csv: Path
    summary_json: Path
    markdown: Path
    figure: Path
    table: str
    summaries: dict[str, dict[str, MethodSummary]]
    """family -> method -> its summary."""
    compact: str = ""
    """The short table: ratio of means and probability of improvement per family."""
    floor_table: str = ""
    """The table against the floor (with `floor=True`)."""
    intervals: Path | None = None
    """rliable's interval estimates of IQM improvement and P(improve) (intervals.png)."""
    executions: str = ""
    """Protocol v2's table of what the executions did (`mjtraj.rl.practice.execution_table`)."""
    weighting: str = ""
    """Protocol v2's ranking under J_settle and under a tracking-heavy weighting, with Kendall's tau."""
    protocol: str = PROTOCOL
    reference: str = REFERENCES[PROTOCOL]
    departures: tuple[str, ...] = ()
    """How the run departs from its protocol's scenarios and resamples (`mjtraj.rl.protocol.departures`)."""
    errors: dict[str, int] = field(default_factory=dict)
    """Rows whose evaluation raised (status error, under keep_going): reason -> count."""


def _labels(policies: Sequence[ScoredPolicy]) -> list[str]:
    """Each policy's table label: its own, and where labels repeat, its run folder and (unless it is the final
    policy.zip) the file's stem; the position in the list if even that repeats."""
    labels = [p.label for p in policies]
    where = [("" if p.path is None else p.path.parent.name if p.path.stem == "policy" else
              f"{p.path.parent.name}/{p.path.stem}") for p in policies]
    out = [f"{label} [{w}]" if labels.count(label) > 1 and w else label
           for label, w in zip(labels, where, strict=True)]
    return [f"{label} #{k + 1}" if out.count(label) > 1 else label for k, label in enumerate(out)]


def _training_settings(record: dict[str, Any]) -> dict[str, Any]:
    """A record's training settings with every default of the current TrainSettings filled in (records written
    before a setting existed group with those that write its default); a distilled policy's are its policy's settings
    and its distillation's (DistillSettings, its defaults filled in alike), so that students of distillations that
    differ in more than their seeds do not pool as seeds."""
    from mjtraj.rl.train import TrainSettings

    if record.get("format") == BATCHED_RUN:  # a batched run records every setting it has; a distillation its own too
        if "distill" not in record:
            return dict(record["settings"])
        from mjtraj.rl.distill import distill_defaults

        return {**distill_defaults(), **record["settings"], **record["distill"]}
    if record.get("format") == ENSEMBLE_FORMAT:  # its members' settings, and how many they are
        return {**record["settings"], "members": len(record["members"])}
    known = {f.name: f.default for f in dataclasses.fields(TrainSettings)
             if f.default is not dataclasses.MISSING}
    return {**known, **record["settings"]}


def _recipe(record: dict[str, Any]) -> dict[str, Any]:
    """A run record's training settings but its seed and threads: what its seeds share."""
    return {k: v for k, v in _training_settings(record).items() if k not in ("seed", "threads")}


def configurations(policies: Sequence[Any], labels: Sequence[str]) -> dict[str, list[str]]:
    """The policies' table labels grouped by configuration: for a zip everything of the training run but its seed
    and threads, and which of its saved policies it is (policy, best or a step checkpoint, by file name); for an
    ensemble the same of each member, as a multiset (ensembles of other member seeds pool as seeds); a policy
    without a record that names its configuration (a plan policy) pools with those that name the same; any other
    user's policy is a configuration of its own. The key is the configuration's label (with the file's stem unless
    it is the final policy), followed, where configurations share a label, by the settings in which they differ
    (such as [steps=200000])."""
    facts: dict[str, tuple[str, dict[str, Any]]] = {}
    groups: dict[str, list[str]] = {}
    for policy, label in zip(policies, labels, strict=True):
        if policy.record is None:
            named = getattr(policy, "configuration", None)
            key = json.dumps(["named", named] if named else ["object", label])
            facts[key] = named or label, {}
            groups.setdefault(key, []).append(label)
            continue
        settings = _recipe(policy.record)
        env = dict(getattr(policy, "env_kwargs", None) or policy.env)
        kind = policy.path.stem if policy.path is not None else "policy"
        kind = "step" if kind.startswith("step_") else kind
        recipes: list[str] = []
        if policy.record.get("format") == ENSEMBLE_FORMAT:  # the multiset of its members' recipes, whatever its name
            kind = "policy"
            recipes = sorted(json.dumps(_recipe(r), sort_keys=True, default=str) for r in member_records(policy.record))
        key = json.dumps([settings, env, kind, recipes], sort_keys=True, default=str)
        if key not in facts:
            base = policy.label.split(" [")[0]
            name = base if kind == "policy" else f"{base} {kind}"
            told = {"member recipes": hashlib.sha256(json.dumps(recipes).encode()).hexdigest()[:8]} if recipes else {}
            facts[key] = name, {**env, **settings, **told}
        groups.setdefault(key, []).append(label)
    names: dict[str, str] = {}
    for key, (name, mine) in facts.items():
        twins = [other for twin, other in facts.values() if twin == name]
        if len(twins) > 1:
            differ = sorted(k for k in set().union(*twins)
                            if len({json.dumps(t.get(k), sort_keys=True, default=str) for t in twins}) > 1)
            name = f"{name} [{', '.join(f'{k}={mine.get(k)}' for k in differ)}]"
        names[key] = name
    return {names[key]: members for key, members in groups.items()}


def _law_config(law: str, out: Path) -> str | None:
    """The base scenario of control law `law` (see LAW_SCENARIOS); a plug-in's written into `out`."""
    if law in LAW_SCENARIOS:
        return LAW_SCENARIOS[law]
    from mjtraj.study import load_scenario, scenario_text

    scenario = load_scenario().replace(loop={"controller": law}, name=f"paper_{law}")
    path = out / "scenarios" / f"paper_{law}.toml"
    write_text_atomic(path, scenario_text(scenario, f"paper.toml with the control law {law} (by mjtraj rl eval)"))
    return str(path)


def _check_loop(policy: ScoredPolicy, settings: SweepSettings) -> None:
    """InvalidInputError unless the policy's controller is the sweep's base scenario's (its law aside)."""
    mine, base = policy.settings().loop, settings.base.loop
    for f in dataclasses.fields(LoopConfig):
        if f.name in ("controller", *SWEPT):
            continue
        if not _same(getattr(mine, f.name), getattr(base, f.name)):
            raise InvalidInputError(f"policy: {policy.source} was trained with a different controller ({f.name}) "
                                    f"than the sweep's base scenario")
    for axis in SWEPT:
        if getattr(mine, axis) != getattr(base, axis):
            raise InvalidInputError(f"policy: {policy.source} acts with {axis}={getattr(mine, axis)!r}; the "
                                    f"benchmark's controller uses {getattr(base, axis)!r}")


def _same(a: Any, b: Any) -> bool:
    if hasattr(a, "kp"):
        return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("kp", "ki", "kd"))
    return bool(a == b)


def _blank_policy(row: dict[str, Any], method: str) -> dict[str, Any]:
    return {**row, "method": method, **{k: "" for k in POLICY_COLUMNS if k != "method"}}


def evaluate(policies: Sequence[Any], *, families: Sequence[str] | None = None, scenarios: int | None = None,
             seed: int | None = None, planners: Sequence[str] = ("cubic",), controllers: Sequence[str] = ("pid",),
             tuned_gains: str | Path | None = None, settings: Mapping[str, Any] | None = None,
             out: str | Path = "rl_eval", batch: int = 250, reps: int | None = None,
             threads: int | None = 1, command: str = "", progress: bool = False, floor: bool = False,
             figure_formats: Sequence[str] = ("png",), versus: str | Sequence[str] | None = None,
             protocol: str = PROTOCOL, keep_going: bool = False) -> EvalReport:
    """Score `policies` beside the `planners` under every law of `controllers` on scenarios 0..scenarios-1 of each
    of `families` under `seed`; writes eval.csv, summary.json, SUMMARY.md, profiles.png and intervals.png (in each
    of `figure_formats`: png, pdf, svg) into `out`. `families`, `scenarios`, `seed` and `reps` default to
    `protocol`'s (`mjtraj.rl.protocol`); other values are stamped off-protocol.

    Args:
      protocol: 'v2' (the default: each episode with its settle window, scored by J_settle, held to the at-rest
        rule, against the adaptive law) or 'v1' (J_exec over the motion, the goal rule, against cubic+PID).
      keep_going: a policy that raises or returns actions of the wrong shape or non-finite ones (PolicyError)
        becomes its rows' error status, counted in SUMMARY.md, instead of ending the evaluation.
      policies: zips from `mjtraj rl train`, "baseline:NAME", "MODULE:ATTR" / "FILE.py:ATTR", or the objects
        themselves (callables, torch modules; see mjtraj.rl.adapters). May be empty: the classical methods alone.
      controllers: control laws the planners run under; each policy runs on its own law (added if missing).
      tuned_gains: a scenario file with tuned PID gains (`mjtraj tune --gains`), scored as TUNED_LABEL.
      settings: env settings (adapters.ENV_KEYS) for policies that are not zips and do not declare them.
      reps: bootstrap resamples of every interval.
      threads: PyTorch CPU threads (mjtraj.rl.train.THREADS_RULE; None: PyTorch's default), recorded; without
        PyTorch installed (plain callables need none) there is nothing to set.
      command: the command line that regenerates the files (written into SUMMARY.md).
      floor: also compute each scenario's clairvoyant floor (`mjtraj.domain.floor`, of the cubic reference's
        execution, which the reference and every policy on cubic track): rows gain the columns floor and
        cost_over_floor, floor.csv holds the floors, and the summary reads every method against the floor and the
        strongest classical method (FloorSummary).
      versus: a method of this evaluation (e.g. "cubic+adaptive CT"), or several: every method is also paired
        against each on each family (mean J / its mean J, P(better), with intervals), a table of SUMMARY.md per
        method and "versus" in summary.json (one method: its pairing; several: a list of them).

    Raises:
      InvalidInputError: bad arguments, an unreadable policy, or scenarios not held out from a policy's training.
      PolicyError: a policy raised or returned unusable actions (unless `keep_going`).
      MissingExtraError: a policy (an SB3 zip, a baseline, a torch module) or `threads` needs the rl extra and it is
        not installed; plain callables need none of it.
    """
    request = _request(policies, families=families, scenarios=scenarios, seed=seed, planners=planners,
                       controllers=controllers, settings=settings, out=out, reps=reps, threads=threads,
                       figure_formats=figure_formats, protocol=protocol)
    _check_versus(versus, request, tuned_gains is not None)
    plans = _plans(request, tuned_gains, batch)
    rows = _executions(request, plans, progress=progress, keep_going=keep_going)
    floors = scenario_floors(request.families, request.scenarios, request.seed, request.out, progress,
                             settle=request.window) if floor else {}
    extra = _floor_columns(rows, floors)
    csv_path = request.out / "eval.csv"
    write_text_atomic(csv_path, csv_text([*columns(plans[0][2]), *POLICY_COLUMNS, *extra], rows))
    computes = _computes(request, plans)
    return _reports(request, rows, floors, csv_path, computes, tuned_gains=tuned_gains, progress=progress,
                    figure_formats=figure_formats, versus=versus, command=command)


def _check_versus(versus: str | Sequence[str] | None, request: _Request, tuned: bool) -> None:
    """InvalidInputError, before anything runs, if a `versus` method is none of the evaluation's (whether it is one
    run, not several seeds, is checked once the rows are in)."""
    methods = [f"{planner}+{law_label(law)}" for law in request.laws for planner in request.planners]
    methods += [TUNED_LABEL] * tuned + [ORACLE_LABEL] * ("adaptive_computed_torque" in request.laws)
    methods += list(configurations(request.loaded, request.labels))
    for method in [versus] if isinstance(versus, str) else list(versus or ()):
        if method not in methods:
            raise InvalidInputError(f"versus: expected a method of this evaluation, one of {', '.join(methods)}; "
                                    f"got {method!r}")


@dataclass(frozen=True)
class _Request:
    """An evaluation's checked arguments, with the protocol's defaults filled in: what every stage reads."""

    families: tuple[str, ...]
    scenarios: int
    seed: int
    reps: int
    protocol: str
    reference: str
    planners: list[str]
    laws: list[str]
    loaded: list[ScoredPolicy]
    labels: list[str]
    out: Path

    @property
    def window(self) -> float:
        """The protocol's settle window, s (0: none)."""
        return SETTLE[self.protocol]


def _request(policies: Sequence[Any], *, families: Sequence[str] | None, scenarios: int | None, seed: int | None,
             planners: Sequence[str], controllers: Sequence[str], settings: Mapping[str, Any] | None,
             out: str | Path, reps: int | None, threads: int | None, figure_formats: Sequence[str],
             protocol: str) -> _Request:
    """The arguments checked (InvalidInputError), the policies loaded and checked to act under the protocol and to
    be held out from what they trained on, PyTorch's threads set."""
    if threads is not None:
        positive_int("threads", threads)
        if importlib.util.find_spec("torch") is not None:  # without it no policy can run PyTorch
            import torch

            torch.set_num_threads(threads)
    for kind in figure_formats:
        choice("figure_formats", kind, FIGURE_FORMATS)
    defaults = check_protocol(protocol)
    families = tuple(defaults["families"] if families is None else families)
    scenarios = int(defaults["scenarios"] if scenarios is None else scenarios)
    seed = int(defaults["seed"] if seed is None else seed)
    reps = int(defaults["reps"] if reps is None else reps)
    for family in families:
        choice("family", family, FAMILY_CHOICES)
    if not families:
        raise InvalidInputError("family: expected at least one family, got none")
    positive_int("scenarios", scenarios)
    positive_int("reps", reps)
    check_seed("seed", seed)
    check_settings(settings)
    reference = REFERENCES[protocol]
    planner_list = list(dict.fromkeys(["cubic", *planners]))
    laws = list(dict.fromkeys(["pid", LAW_OF[reference], *controllers]))
    for law in laws:
        choice("controllers", law, controller_names())
    loaded = [load_any(p, settings=settings) for p in policies]
    for policy in loaded:
        acting_settings(policy, protocol)  # a policy that cannot act under the protocol, refused before any run
        for family in families:
            check_held_out(policy, family, seed, scenarios)
    laws = list(dict.fromkeys([*laws, *(p.controller for p in loaded)]))
    return _Request(families, scenarios, seed, reps, protocol, reference, planner_list, laws, loaded,
                    _labels(loaded), Path(out))


_Plan = tuple[str, str, SweepSettings, list[tuple[ScoredPolicy, str]]]
"""(family, law or 'tuned', the sweep that draws and runs it, the policies acting on that law with their labels)."""


def _plans(request: _Request, tuned_gains: str | Path | None, batch: int) -> list[_Plan]:
    """Per family, one sweep per control law (its planners and the policies acting on it) and the tuned gains'."""
    configs = {law: _law_config(law, request.out) for law in request.laws}
    plans: list[_Plan] = []
    for family in request.families:
        drawn: dict[str, Any] = {"families": (sweep_family(family),), "scenarios": request.scenarios,
                                 "seed": request.seed, "batch": batch, "settle": request.window,
                                 "sensor_noise": NOISY_SIGMA if family == NOISY_FAMILY else 0.0}
        for law in request.laws:
            mine = [(p, label) for p, label in zip(request.loaded, request.labels, strict=True)
                    if p.controller == law]
            names = tuple(dict.fromkeys([*request.planners, *(p.planner for p, _ in mine)]))
            sweep = SweepSettings(planners=names, config=configs[law], **drawn)
            for policy, _ in mine:
                _check_loop(policy, sweep)
            plans.append((family, law, sweep, mine))
        if tuned_gains is not None:
            tuned = SweepSettings(planners=("cubic",), config=str(tuned_gains), **drawn)
            if tuned.base.loop.controller != "pid":
                raise InvalidInputError(f"tuned_gains: {tuned_gains} runs the control law "
                                        f"{tuned.base.loop.controller!r}; expected tuned PID gains (mjtraj tune "
                                        f"--gains)")
            plans.append((family, "tuned", tuned, []))
    return plans


def _executions(request: _Request, plans: list[_Plan], *, progress: bool, keep_going: bool
                ) -> list[dict[str, Any]]:
    """Every plan's units run (the sweep's rows, each policy's and, under the adaptive law, the oracle's), each row
    named by its method."""
    rows: list[dict[str, Any]] = []
    units = [(plan, unit) for plan in plans for unit in plan[2].units()]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(units), unit="unit", desc="rl eval", dynamic_ncols=True)
    for (family, law, sweep, mine), unit in units:
        actors = [ActorSpec(label, p.planner, PolicyActor(p, acting_settings(p, request.protocol)),
                            {**p.columns(), "method": label}, () if keep_going else (PolicyError,))
                  for p, label in mine]
        if law == "adaptive_computed_torque":
            actors.append(ActorSpec(ORACLE_LABEL, "cubic", TrueParameters(),
                                    {**dict.fromkeys(POLICY_COLUMNS, ""), "method": ORACLE_LABEL,
                                     "policy_privileged": 1}))
        acting = {spec.label for spec in actors}
        for row in run_unit(sweep, unit, actors=actors).rows:
            row["family"] = family  # the noisy family runs the mismatch family's scenarios
            if row["planner"] in acting:
                rows.append(row)
            else:
                method = TUNED_LABEL if law == "tuned" else f"{row['planner']}+{law_label(law)}"
                rows.append(_blank_policy(row, method))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    return rows


def _computes(request: _Request, plans: list[_Plan]) -> dict[str, StepCompute]:
    """Each method's per-period compute (`mjtraj.rl.compute`): every law of the evaluation timed along its own
    execution of the first scenario of each family (cubic, the protocol's window), and every policy's inference
    (with the estimators it observes, e.g. `mpc_filter`, timed with it along those executions; a callable with
    episode state, `reset`, on the observations of those executions, each an episode it starts; not a privileged
    one, which could not be fed, a recurrent zip or module, whose state a call outside its episodes would disturb,
    nor one that raises)."""
    from mjtraj.core import held, window_steps
    from mjtraj.envs import Observer
    from mjtraj.study import draw_scenario

    out: dict[str, StepCompute] = {}

    def references(mine: list[tuple[str, Any]]) -> list[Any]:
        """The cubic plan of each family's first scenario, ending with the protocol's window."""
        base = mine[0][1].base
        window = window_steps(request.window, base.task.dt)
        refs = []
        for family, _ in mine:
            task = draw_scenario(sweep_family(family), request.seed, 0, base.model, base.task.dt).task
            refs.append(held(base.planner("cubic").plan(task, base.model), window, task.qg))
        return refs

    for law in request.laws:
        mine = [(family, sweep) for family, name, sweep, _ in plans if name == law]
        out[f"cubic+{law_label(law)}"] = law_compute(mine[0][1].base.loop, [], mine[0][1].base.model, None,
                                                     references=references(mine))
    for policy, label in zip(request.loaded, request.labels, strict=True):
        if policy.privileged or (policy.reset_hook is not None and (policy.env.get("history", 0) or policy.kind
                                                                     != "callable")):
            continue  # plants it cannot be fed, or a recurrent state a call outside its episodes would disturb
        settings = acting_settings(policy, request.protocol)
        shadows = settings.shadows()
        stateful = policy.reset_hook is not None  # a callable with episode state: timed on its own episodes
        mine = (list({family: (family, sweep) for family, _, sweep, _ in plans}.values()) if shadows or stateful
                else [])
        try:
            out[label] = policy_compute(policy.act_batch, settings.obs_size, shadows=shadows,
                                        config=settings.loop, model=settings.model,
                                        references=references(mine) if mine else (),
                                        observer=Observer(settings, 1) if stateful else None,
                                        reset=policy.reset_hook)
        except Exception:  # noqa: BLE001 - a broken policy (kept going) is not timed; its rows say why
            continue
    return out


def _floor_columns(rows: list[dict[str, Any]], floors: Mapping[str, NDArray[np.float64]]) -> list[str]:
    """Each row's scenario floor and its score over it (FLOOR_COLUMNS, added to the rows), where there are floors."""
    if not floors:
        return []
    for row in rows:
        value = float(floors[row["family"]][int(row["scenario"])])
        cost = numeric(row["cost"]) if row["status"] == "ok" else float("nan")
        row.update(floor=value, cost_over_floor=cost / value)
    return list(FLOOR_COLUMNS)


def _reports(request: _Request, rows: list[dict[str, Any]], floors: Mapping[str, NDArray[np.float64]],
             csv_path: Path, computes: Mapping[str, StepCompute], *, tuned_gains: str | Path | None, progress: bool,
             figure_formats: Sequence[str], versus: str | Sequence[str] | None, command: str) -> EvalReport:
    """The statistics (intervals, profiles, the floor's and the pairing's), the tables, summary.json and
    SUMMARY.md."""
    families, reference, reps, out = request.families, request.reference, request.reps, request.out
    groups = configurations(request.loaded, request.labels)
    costs = {family: method_costs(rows, groups, family, reference) for family in families}
    with _stage(progress, f"intervals: {reps} bootstrap resamples per method and family, and the figures"):
        summaries, scores = summarise(costs, reps=reps)
        against = {family: against_floor(costs[family], floors[family], groups, reps=reps) for family in floors}
        figure = profile_figure(scores, out / "profiles.png", reference=reference, reps=reps,
                                formats=figure_formats)
        intervals = interval_figure(summaries, out / "intervals.png", reference=reference, formats=figure_formats)
    against_methods = [versus] if isinstance(versus, str) else list(versus or ())
    paired = {method: versus_all(costs, method, reps=reps) for method in against_methods}
    table = summary_table(summaries, families, reference)
    compact = compact_table(summaries, families, reference)
    payload = payload_table(rows, costs["mismatch"], reference) if "mismatch" in families else ""
    window = request.window
    executions, execution_record = execution_table(rows, groups, families) if window else ("", {})
    weighting, weighting_record = weighting_agreement(rows, groups, families) if window else ("", {})
    off = departures(families, request.scenarios, request.seed, reps, request.protocol)
    protocol = request.protocol
    errors = error_counts(rows)
    record = {"format": "mjtraj-benchmark-summary/1", "reference": reference, "failure_rule": FAILURE_RULE,
              "protocol": f"off-protocol: {'; '.join(off)}" if off else protocol,
              "protocol_base": protocol, "score": SCORE_NAMES[protocol], "settle": window,
              "noisy_sigma": NOISY_SIGMA if NOISY_FAMILY in families else 0.0, "families": list(families),
              "scenarios": request.scenarios, "seed": request.seed, "reps": reps,
              "controllers": request.laws, "planners": request.planners, "tuned_gains": str(tuned_gains or ""),
              "policies": [{"label": label, **p.columns()}
                           for p, label in zip(request.loaded, request.labels, strict=True)],
              "configurations": groups, "versions": rl_versions(), "command": command,
              "torch_threads": _torch_threads(),
              "summary": {family: {m: s.as_dict() for m, s in per.items()} for family, per in summaries.items()},
              "floor": {family: {m: s.as_dict() for m, s in per.items()} for family, per in against.items()},
              "versus": _versus_record(paired, several=not isinstance(versus, str)) if paired else {},
              "executions": execution_record, "weightings": weighting_record,
              "compute": {method: c.as_dict() for method, c in computes.items()},
              "errors": errors}
    json_path = out / "summary.json"
    write_text_atomic(json_path, json.dumps(record, indent=1) + "\n")
    md_path = out / "SUMMARY.md"
    floors_md = floor_table(against, families) if against else ""
    versus_md = "\n\n".join(versus_table(per, families, method) for method, per in paired.items())
    write_text_atomic(md_path, summary_markdown(table, payload, record, request.labels, request.loaded, compact,
                                                floors_md, versus_md, executions, weighting,
                                                compute_table(dict(computes)) if computes else ""))
    return EvalReport(out, csv_path, json_path, md_path, figure, table, summaries, compact, floors_md, intervals,
                      executions, weighting, protocol, reference, tuple(off), errors)


def acting_settings(policy: ScoredPolicy, protocol: str) -> Any:
    """The env settings a policy acts in under `protocol`: its own; under protocol v2 it observes the measured state,
    as the control laws do (the noisy family's noise reaches policies and laws alike; without noise the measured state
    is the true one)."""
    settings = policy.settings()
    if settings.observe_disturbance and not SETTLE[protocol]:
        raise InvalidInputError(f"policy: {policy.label} observes mpc's filter, which runs in protocol v2's episodes "
                                f"alone; expected --protocol v2, got {protocol}")
    return dataclasses.replace(settings, observe_measured=True) if SETTLE[protocol] else settings


def error_counts(rows: Sequence[dict[str, Any]]) -> dict[str, int]:
    """Each reason of the rows whose status is error, with its count (most frequent first)."""
    counts: dict[str, int] = {}
    for row in rows:
        if row["status"] == "error":
            counts[row["reason"]] = counts.get(row["reason"], 0) + 1
    return dict(sorted(counts.items(), key=lambda item: -item[1]))


FLOOR_COLUMNS = ("floor", "cost_over_floor")
"""The columns `evaluate(floor=True)` adds: the scenario's floor (of the cubic reference's execution) and J / floor."""


def scenario_floors(families: Sequence[str], scenarios: int, seed: int, out: Path, progress: bool, *,
                    settle: float = 0.0) -> dict[str, NDArray[np.float64]]:
    """Each family's floors (K,), NaN where the floor failed (`mjtraj.study.floor.family_floors` on the shipped
    scenario, with the protocol's settle window, s), also written to out/floor.csv. The noisy family's are its
    mismatch scenarios' (noise does not reach a torque sequence: the floor bounds any law's execution on that
    plant), solved once."""
    from mjtraj.study import family_floors, load_scenario

    base = load_scenario()
    records: list[dict[str, Any]] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(families) * scenarios, unit="floor", desc="floors", dynamic_ncols=True)
    solved: dict[str, NDArray[np.float64]] = {}  # sweep family -> floors
    out_floors: dict[str, NDArray[np.float64]] = {}
    for family in families:
        drawn = sweep_family(family)
        if drawn in solved:
            out_floors[family] = solved[drawn]
            if bar is not None:
                bar.update(scenarios)
            continue
        values = np.full(scenarios, np.nan)
        for record in family_floors(base, drawn, seed=seed, scenarios=range(scenarios), settle=settle):
            records.append(record)
            if record["status"] == "ok":
                values[record["scenario"]] = record["floor"]
            if bar is not None:
                bar.update(1)
        out_floors[family] = solved[drawn] = values
    if bar is not None:
        bar.close()
    names = list(dict.fromkeys(k for r in records for k in r))
    write_text_atomic(out / "floor.csv", csv_text(names, [{k: r.get(k, "") for k in names} for r in records]))
    return out_floors


def against_floor(costs: tuple[NDArray[np.float64], Mapping[str, NDArray[np.float64]]], floor: NDArray[np.float64],
                  groups: Mapping[str, Sequence[str]], *, reps: int) -> dict[str, FloorSummary]:
    """Each method's FloorSummary on one family (`method_costs`' output, the family's floors (K,)); the strongest
    classical method is the planner+law or tuned-gains method of least mean J_exec (no policy, no oracle)."""
    ref, by_method = costs
    classical = {m: c for m, c in by_method.items() if m not in groups and m != ORACLE_LABEL
                 and not m.startswith(tuple(f"{label} " for label in groups)) and np.all(np.isfinite(c))}
    best = min(classical, key=lambda m: float(np.mean(classical[m]))) if classical else REFERENCE
    best_cost = by_method[best][0] if best in by_method else ref
    return {m: summarize_floor(c, ref, floor, best_cost, best, reps=reps) for m, c in by_method.items()}


def floor_table(against: Mapping[str, Mapping[str, FloorSummary]], families: Sequence[str]) -> str:
    """Markdown: per family and method, J / floor, the share of the headroom closed and the paired comparison with
    the strongest classical method, each with its 95 % interval."""
    present = [f for f in families if f in against]
    head = "| method | " + " | ".join(f"{f}: J / floor | {f}: headroom closed | {f}: J / {_best(against[f])}, "
                                      f"P(better)" for f in present) + " |"
    def cells(s: FloorSummary) -> list[str]:
        return [_cell(s.ratio_to_floor), _cell(s.headroom_closed, ".2f"),
                f"{_cell(s.versus_best)}, {s.beats_best.value:.2f}"]

    return "\n".join([head, "|---|" + "---|---|---|" * len(present), *_method_rows(against, present, 3, cells)])


def versus_all(costs: Mapping[str, tuple[NDArray[np.float64], Mapping[str, NDArray[np.float64]]]], versus: str, *,
               reps: int) -> dict[str, dict[str, tuple[Interval, Interval]]]:
    """Per family, every method paired against the method `versus` (`protocol_stats.paired_against`).

    Raises:
      InvalidInputError: `versus` is not a method of the evaluation (or a configuration of several seeds)."""
    out = {}
    for family, (_, by_method) in costs.items():
        other = by_method.get(versus)
        if other is None or other.shape[0] != 1:
            raise InvalidInputError(f"versus: expected a method of one run in this evaluation, one of "
                                    f"{', '.join(m for m, c in by_method.items() if c.shape[0] == 1)}; got {versus!r}")
        out[family] = {m: paired_against(c, other[0], reps=reps) for m, c in by_method.items()}
    return out


def _versus_record(paired: Mapping[str, Mapping[str, Mapping[str, tuple[Interval, Interval]]]], *, several: bool
                   ) -> dict[str, Any] | list[dict[str, Any]]:
    """summary.json's "versus": each method's pairing of every method on every family (a list where several were
    asked for; one method's alone where one was, as it always was)."""
    out = [{"method": method, **{family: {m: {"ratio": v.as_dict(), "beats": b.as_dict()} for m, (v, b) in per.items()}
                                 for family, per in by_family.items()}}
           for method, by_family in paired.items()]
    return out if several else out[0]


def versus_table(paired: Mapping[str, Mapping[str, tuple[Interval, Interval]]], families: Sequence[str],
                 versus: str) -> str:
    """Markdown: per family and method, mean J / `versus`'s mean J and P(better than it), with 95 % intervals."""
    present = [f for f in families if f in paired]

    def cells(pair: tuple[Interval, Interval]) -> list[str]:
        return [_cell(pair[0]), _cell(pair[1], ".2f")]

    return "\n".join(["| method | " + " | ".join(f"{f}: J / {versus} | {f}: P(better)" for f in present) + " |",
                      "|---|" + "---|---|" * len(present), *_method_rows(paired, present, 2, cells)])


def _method_rows(per_family: Mapping[str, Mapping[str, Any]], families: Sequence[str], width: int,
                 cells: Callable[[Any], list[str]]) -> list[str]:
    """Markdown rows, one per method of any of `families` in first-seen order: per family the `width` cells of its
    entry (`cells`), or "-" where the family has none."""
    methods = list(dict.fromkeys(m for f in families for m in per_family[f]))
    return [f"| {m} | " + " | ".join(cell for f in families for cell in
                                     (cells(per_family[f][m]) if m in per_family[f] else ["-"] * width)) + " |"
            for m in methods]


def _best(per: Mapping[str, FloorSummary]) -> str:
    return next(iter(per.values())).best if per else REFERENCE


@contextmanager
def _stage(progress: bool, what: str) -> Iterator[None]:
    """With `progress`, say on stderr that the stage `what` runs, then how long it took."""
    import sys
    import time

    if progress:
        print(f"rl eval: {what} ...", file=sys.stderr, flush=True)
    start = time.perf_counter()
    yield
    if progress:
        print(f"rl eval: {what}: done in {time.perf_counter() - start:.0f} s", file=sys.stderr, flush=True)


def _torch_threads() -> int | None:
    """PyTorch's CPU threads, or None where no policy loaded PyTorch (plain callables need none)."""
    import sys

    return int(sys.modules["torch"].get_num_threads()) if "torch" in sys.modules else None


def method_costs(rows: Sequence[dict[str, Any]], groups: Mapping[str, Sequence[str]], family: str,
                 reference: str = REFERENCE) -> tuple[NDArray[np.float64], dict[str, NDArray[np.float64]]]:
    """The `reference` method's score (the rows' cost: J_exec, or J_settle in protocol v2) per scenario (K,) and
    each method's (S, K) (NaN: failed) on `family`; a configuration's seeds are its rows, every other method
    (planner+law, tuned gains, a user's policy) one row."""
    by_method: dict[str, dict[int, float]] = {}
    for r in rows:
        if r["family"] == family:
            cost = numeric(r["cost"]) if r["status"] == "ok" else float("nan")
            by_method.setdefault(r["method"], {})[int(r["scenario"])] = cost
    order = sorted(by_method[reference])
    vector = {m: np.array([v[k] for k in order]) for m, v in by_method.items()}
    grouped = {member for members in groups.values() for member in members}
    out = {m: c[None, :] for m, c in vector.items() if m not in grouped}
    for name, members in groups.items():
        out[name] = np.stack([vector[m] for m in members])
    return vector[reference], out


def summarise(costs: Mapping[str, tuple[NDArray[np.float64], Mapping[str, NDArray[np.float64]]]], *, reps: int
              ) -> tuple[dict[str, dict[str, MethodSummary]], dict[str, dict[str, Any]]]:
    """Each family's method summaries and improvement scores (S, K) (mjtraj.rl.protocol_stats), from its
    `method_costs`: family -> (the reference's costs, method -> costs)."""
    summaries, scores = {}, {}
    for family, (ref, by_method) in costs.items():
        summaries[family] = {m: summarize(c, ref, reps=reps) for m, c in by_method.items()}
        scores[family] = {m: improvement(c, ref) for m, c in by_method.items()}
    return summaries, scores


def _cell(i: Any, digits: str = ".3g") -> str:
    return f"{i.value:{digits}} [{i.low:{digits}}, {i.high:{digits}}]"


def summary_table(summaries: Mapping[str, Mapping[str, MethodSummary]], families: Sequence[str],
                  reference: str = REFERENCE) -> str:
    """Markdown: one row per method, per family the ratio of mean score to the `reference`'s, the IQM of the
    per-episode improvement, the probability of improvement (each with its 95 % interval) and the failures."""
    methods = list(dict.fromkeys(m for family in families for m in summaries[family]))
    head = "| method | seeds | " + " | ".join(f"{f}: J / {reference} | {f}: IQM improvement | {f}: P(improve) | "
                                              f"{f}: failed" for f in families) + " |"
    lines = [head, "|---|---|" + "---|---|---|---|" * len(families)]
    for m in methods:
        cells = []
        seeds = max(summaries[f][m].seeds for f in families if m in summaries[f])
        for f in families:
            s = summaries[f].get(m)
            if s is None:
                cells += ["-"] * 4
            elif m == reference:
                cells += ["1 (reference)", "0 (reference)", "-", f"{s.failures} of {s.seeds * s.scenarios}"]
            else:
                cells += [_cell(s.ratio_of_means), _cell(s.iqm, ".2f"), _cell(s.probability_of_improvement, ".2f"),
                          f"{s.failures} of {s.seeds * s.scenarios}"]
        lines.append(f"| {m} | {seeds} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def compact_table(summaries: Mapping[str, Mapping[str, MethodSummary]], families: Sequence[str],
                  reference: str = REFERENCE) -> str:
    """Markdown: one row per method, per family its ratio of mean score to the `reference`'s (failures by
    FAILURE_RULE, so a method that failed anywhere reads inf) and its probability of improvement."""
    methods = list(dict.fromkeys(m for family in families for m in summaries[family]))
    lines = ["| method | " + " | ".join(f"{f}: J / {reference}, P(improve)" for f in families) + " |",
             "|---|" + "---|" * len(families)]
    for m in methods:
        cells = []
        for f in families:
            s = summaries[f].get(m)
            cells.append("-" if s is None else "1, -" if m == reference else
                         f"{s.ratio_of_means.value:.3g}, {s.probability_of_improvement.value:.2f}")
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


PAYLOAD_BINS = 5
"""Equal-width bins of the mismatch family's payload range (PAYLOAD_MASS) in the by-payload table."""


def payload_table(rows: Sequence[dict[str, Any]],
                  costs: tuple[NDArray[np.float64], Mapping[str, NDArray[np.float64]]],
                  reference: str = REFERENCE) -> str:
    """Markdown: on the mismatch family, each method's ratio of mean score to the reference's within bins of the
    scenario's payload (its seeds pooled; FAILURE_RULE); `costs` the family's `method_costs`."""
    ref, by_method = costs
    payload = {int(r["scenario"]): numeric(r["payload_kg"]) for r in rows
               if r["family"] == "mismatch" and r["method"] == reference}
    kg = np.array([payload[k] for k in sorted(payload)])
    edges = np.linspace(*PAYLOAD_MASS, PAYLOAD_BINS + 1)
    bins = np.clip(np.searchsorted(edges, kg, side="right") - 1, 0, PAYLOAD_BINS - 1)
    head = " | ".join(f"{lo:g}-{hi:g} kg ({np.sum(bins == b)})" for b, (lo, hi) in
                      enumerate(zip(edges[:-1], edges[1:], strict=True)))
    lines = [f"| method | {head} |", "|---|" + "---|" * PAYLOAD_BINS]
    for m, c in by_method.items():
        cells = []
        for b in range(PAYLOAD_BINS):
            inside = bins == b
            refs = np.broadcast_to(ref[inside], c[:, inside].shape)
            cells.append(f"{ratio_of_means(c[:, inside], refs)[0]:.3g}" if inside.any() else "-")
        lines.append(f"| {m} | {' | '.join(cells)} |")
    return "\n".join(lines)


def summary_markdown(table: str, payload: str, record: dict[str, Any], labels: Sequence[str],
                     policies: Sequence[ScoredPolicy], compact: str = "", floors: str = "", versus: str = "",
                     executions: str = "", weighting: str = "", compute: str = "") -> str:
    """SUMMARY.md: how to regenerate it, the protocol in brief, the table, the by-payload table, each method's
    per-period compute, the policies."""
    lines = [*_head(record), *_protocol_lines(record), table, ""]
    if compact:
        lines += ["In short (J / reference, then P(improve)):", "", compact, ""]
    if executions:
        lines += ["What the executions did (means over each method's episodes of the family, failed ones included "
                  "where they ran; `success` the share at rest at the goal; the score's position, velocity and torque "
                  "parts; errors, speeds and torques over the whole episode; `settle` the time after the motion's end "
                  "until every joint stayed within the band, over the episodes that settled):", "", executions, ""]
    if weighting:
        lines += [weighting, ""]
    if floors:
        lines += [_floor_words(record), "", floors, ""]
    if versus:
        lines += [_versus_words(record), "", versus, ""]
    if payload:
        lines += ["By payload on the mismatch family (J / reference, seeds pooled; scenarios per bin in brackets):",
                  "", payload, ""]
    if compute:
        lines += ["What each method computes per control period, for one simulation on one core (a law: its command, "
                  "timed along its own execution of each family's first scenario; a policy: its inference on one "
                  "observation, the law it acts on beside it; wall-clock on this run's machine, a record, not a "
                  "benchmark):", "", compute, ""]
    if record.get("errors"):
        lines += ["Rows whose evaluation raised (status error), by reason:", "",
                  *(f"- {count} x {reason}" for reason, count in record["errors"].items()), ""]
    lines += ["![performance profiles](profiles.png)", "", "Policies:", *_policy_lines(labels, policies)]
    return "\n".join(lines) + "\n"


def _head(record: dict[str, Any]) -> list[str]:
    """SUMMARY.md's title, its protocol (or what departs from it), the command and the provenance."""
    protocol = record.get("protocol", "v1")
    base = record.get("protocol_base", "v1")
    lines = ["# Benchmark summary" + ("" if protocol == base else " (OFF-PROTOCOL)"), ""]
    if protocol != base:
        lines += [f"**Off-protocol**: {protocol.removeprefix('off-protocol: ')}. These numbers cannot be compared "
                  f"with published ones; `mjtraj rl eval --protocol {base}` without --family, --scenarios, --seed and "
                  f"--reps runs protocol {base}.", ""]
    else:
        lines += [f"Protocol {base}.", ""]
    if record["command"]:
        lines += [f"Regenerate: `{record['command']}`", ""]
    if record.get("versions"):
        lines += [f"Computed with {describe(record['versions'])}.", ""]
    return lines


def _protocol_lines(record: dict[str, Any]) -> list[str]:
    """The protocol in brief: the settle window (v2), the scenarios, the statistics and the methods."""
    families = ", ".join(record["families"])
    reference = record.get("reference", REFERENCE)
    score = SCORE_NAMES[record.get("protocol_base", "v1")]
    lines = []
    if record.get("settle"):
        lines += [f"Every episode goes on for a settle window of {record['settle']:g} s after its motion, the "
                  f"reference holding the goal, and is scored over the whole episode ({score}: J_exec's weights on "
                  f"every period of motion and window); it succeeds only if every joint is within {SETTLE_BAND:g} of "
                  f"the move of the goal and slower than {SETTLE_SPEED:g} rad/s when the window ends (a row that is "
                  "not fails as not_settled)."
                  + (f" The {NOISY_FAMILY} family runs the mismatch family's scenarios with measurement noise of "
                     f"{record['noisy_sigma']:g} rad on q (sqrt(2) sigma / dt on qd), which the control laws and the "
                     "policies see alike." if record.get("noisy_sigma") else ""), ""]
    lines += [f"Held-out scenarios 0..{record['scenarios'] - 1} of each family ({families}) under seed "
              f"{record['seed']}; every method on the same scenarios, plants, saturation and score ({score}, "
              f"Bryson's weights per task). Reference: {reference}. Per family: J / {reference} is the ratio of mean "
              f"{score} "
              "(seeds pooled); IQM improvement the interquartile mean of 1 - J / J_ref over every (seed, "
              "scenario); P(improve) the probability that an episode beats the reference's (ties one half); "
              f"95 % stratified-bootstrap intervals ({record['reps']} resamples over scenarios and seeds, "
              f"rliable). Failures: {record['failure_rule']}. Methods: planner+PID (feedforward + PID), "
              f"planner+CT (computed torque on the nominal model), planner+adaptive CT (computed torque that "
              f"estimates a payload, damping and friction online), {TUNED_LABEL}, {ORACLE_LABEL} where the adaptive "
              "law runs (it knows each plant's payload, damping and friction: not deployable, a floor for the "
              "others), and each policy configuration (its seeds pooled; `seeds` counts them).", ""]
    return lines


def _floor_words(record: dict[str, Any]) -> str:
    """What the table against the floor reads."""
    score = SCORE_NAMES[record.get("protocol_base", "v1")]
    reference = record.get("reference", REFERENCE)
    reached = ("at rest at the goal when the settle window ends" if record.get("settle") else
               "reaching the goal")
    starts = ("solved from every control law's execution (floor.csv also gives, per law, the floor found "
              "without its own: floor_without_LAW)" if record.get("settle") else
              "the best found from the least of the control laws' executions")
    return (f"Against the floor (the clairvoyant floor of each scenario's cubic reference: the least {score} any "
            f"controller can score on that plant, {reached}; floor.csv) and paired with the strongest "
            f"classical method of each family (least mean {score} among planner+law and tuned gains). J / floor "
            "is the ratio of means; headroom closed (J_ref - J) / (J_ref - J_floor) with J_ref "
            f"{reference}'s (0: the reference, 1: the floor); 95 % intervals as above. On the mismatch and "
            f"noisy families (one plant, so one floor) the floor is {starts} on a plant with dry friction: an "
            "upper estimate of the true floor. Methods on other planners than cubic track another reference, "
            "whose floor differs.")


def _versus_words(record: dict[str, Any]) -> str:
    """What the pairing tables read."""
    score = SCORE_NAMES[record.get("protocol_base", "v1")]
    named = record["versus"] if isinstance(record["versus"], list) else [record["versus"]]
    each = " (a table each)" if len(named) > 1 else ""
    return (f"Paired against {', '.join(v['method'] for v in named)} on the same scenarios{each}: the ratio of "
            f"mean {score} and the probability that an episode scores below its (ties one half), 95 % "
            "intervals as above.")


def _policy_lines(labels: Sequence[str], policies: Sequence[ScoredPolicy]) -> list[str]:
    """One line per policy: its source, how it was trained, the env it acts in."""
    lines = []
    for label, p in zip(labels, policies, strict=True):
        batched = p.record is not None and p.record.get("format") in (BATCHED_RUN, ENSEMBLE_FORMAT)
        algo = ("imitation (behaviour cloning, DAgger)" if p.record is not None and "distill" in p.record else
                "batched PPO (skrl)" if batched else
                p.record["settings"]["algo"].upper() if p.record is not None else "")
        if p.record is not None and p.record.get("format") == ENSEMBLE_FORMAT:
            seeds = ", ".join(str(r["settings"]["seed"]) for r in member_records(p.record))
            what = f"the mean of {len(p.record['members'])} policies: {algo}, seeds {seeds}"
        else:
            what = (f"{algo}, {p.timesteps} steps, seed {p.record['settings']['seed']}" if p.record is not None
                    else p.kind)
        lines.append(f"- {label}: `{p.source}` ({what}; acts in {json.loads(p.columns()['policy_env'])}"
                     f"{', privileged: sees the plant' if p.sees_plant else ''})")
    return lines
