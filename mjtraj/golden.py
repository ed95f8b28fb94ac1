"""Regression oracles: golden values of the paths every published number comes from, written by `mjtraj golden
--write` into the checkout's tests/golden/ and checked by the tests (tests/test_golden.py; docs/testing.md, "Golden
values").

What a set pins (SETS; every scenario from the held-out seed SEED, as `rl eval` and `floor` draw them):
- `draw/FAMILY/I`: the families' scenarios (the task, and the plant of a mismatch scenario);
- `sweep/LAW/FAMILY/I/PLANNER`: the sweep's rows (`mjtraj.study.sweep.run_unit`, one unit) of the planners under
  each control law, on the law's base scenario as `mjtraj rl eval` chooses it (its `_law_config`), by protocol v1;
  `sweep_v2/...` the same by protocol v2 (`mjtraj.rl.protocol`: the settle window, the noisy family);
- `compare/LAW/PLANNER`: Table I (`mjtraj.study.comparison.compare`, as `mjtraj compare --controller LAW` runs it on
  the paper's move): each planner's metrics, status, plan record and reference arrays; `compare/LAW/stability`;
- `nonlinear/PLANNER/TASK`: plans of `nonlinear_optimal` and `nonlinear_min_effort` on the paper's move and nominal
  tasks: the solver's record (objective, iterations, ...) and the planned torques;
- `floor/FAMILY/I`: each starting law's J_exec on cubic's reference (pid, computed torque, the adaptive law, the
  oracle; `.../predictive` mpc's and adaptive mpc's) and `floor/FAMILY/I/solve` the clairvoyant floor
  (`mjtraj.study.floor.family_floors`, as `mjtraj floor` runs it);
- `policy/FAMILY/I`, `policy_v2/FAMILY/I`: the shipped policy each protocol's published table scores (POLICIES)
  scored as `mjtraj rl eval` scores it by protocol v1 and v2 (its planner's reference, its control law, `run_unit`
  with the policy as an actor).

How they are compared (`compare_entries`): statuses (a row's status, a plan's solver, the floor's start, a policy's
sha256) always exactly. On a machine whose fingerprint (`fingerprint`: CPU model and flags, Python, the numerical
libraries, the BLAS) is the recording machine's, every value and array bit for bit (the values' repr, the arrays'
sha256): the same code gives the same bits there, so any change, a last-bit one included, fails. On another machine
each value within its entry's relative tolerance (TOLERANCES, by the entry's kind), arrays by per-column digests; the
hashes and an entry's `exact` values are not compared there.
"""

from __future__ import annotations

import hashlib
import json
import math
import platform
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mjtraj.exceptions import InvalidInputError
from mjtraj.versions import blas

if TYPE_CHECKING:
    from numpy.typing import NDArray

COMMAND = "mjtraj golden --write"
"""The one command that writes the golden files."""
SEED = 1
"""The held-out scenarios' seed (`mjtraj rl eval`'s and `mjtraj floor`'s default)."""
FAMILIES = ("nominal", "aggressive", "mismatch")
"""Protocol v1's families (the sweeps'); protocol v2 adds the noisy family (`mjtraj.rl.protocol.NOISY_FAMILY`)."""
FAMILIES_V2 = (*FAMILIES, "noisy")
PLANNERS = ("optimal", "cubic", "quintic", "trapezoidal")
"""The sweep's default planners."""
LAWS = ("pid", "computed_torque", "adaptive_computed_torque", "mpc", "adaptive_mpc")
NONLINEAR = ("nonlinear_optimal", "nonlinear_min_effort")
POLICIES = {"v1": "baseline:ppo_batched_s1", "v2": "baseline:best"}
"""The shipped policy each protocol's published table scores: docs/results/best (v1) the baseline v1's rule chose,
docs/results/v2 (v2) `baseline:best`, chosen by v2's rule (`mjtraj.rl.best`)."""
TOLERANCES: dict[str, float | None] = {"float64": 1e-9, "float32": 1e-5, "sensitive": None}
"""An entry's relative tolerance by its kind, where the machine is not the recording one (docs/testing.md gives the
measurements).
- float64: another machine changes the last bits of operations (its SIMD paths in MuJoCo, NumPy, the BLAS and numba's
  code, its libm), which the loops and the converged solves carry to about 1e-13 of a value: the PID sum reordered
  and a second BLAS thread moved no such value of the `full` set by more than 1e-12, and every dependency at its
  declared floor (NumPy 2.2, SciPy 1.13.1, DAQP 0.5, ...) none by more than 1e-9. A change moves them by far more: a
  link's mass by 1e-6 moved nearly all of them by more than 1e-9 (the median by 1e-7).
- float32: a shipped network that computes in float32 (PyTorch), whose last bit is 1.2e-7 of a value (a plan
  policy computes in float64: NumPy and MuJoCo).
- sensitive: values that another machine or release moves by more than any tolerance that would still see a change,
  pinned on the recording machine only (their statuses everywhere): the predictive laws' executions, which solve a
  QP each period to DAQP's tolerance (DAQP 0.5 moved their rows by up to 36 %, and where the command saturates a
  second BLAS thread moved a row's J_exec by 24 %), and the mismatch floors' solves (the best local minimum found:
  0.44 % and 7 iterations)."""
PREDICTIVE = ("mpc", "adaptive_mpc")
"""The laws that solve a QP each period: what their executions decide is `sensitive`."""
WALL_CLOCK = ("seconds", "_time")
"""A plan's or a floor's record keys that end so are timings: not pinned."""
NOISE = ("terminal_residual", "bound_violation")
"""A plan's record keys that measure round-off (a residual of 1e-12): pinned on the recording machine only."""
SOLVE_EXACT = ("start", "floor_over_best", "start_spread", "iterations", "terminal_err", "converged")
"""A floor record's keys that the solve or the predictive starts decide beyond the floor's value (the start it came
from, its iterations, its terminal error along the flat directions of the minimum): pinned on the recording machine
only (`floor/FAMILY/I/solve`'s `exact`)."""
FINGERPRINT_LIBRARIES = ("numpy", "scipy", "mujoco", "numba", "llvmlite", "daqp", "osqp", "pin", "ruckig",
                         "torch", "threadpoolctl")
"""The distributions whose versions are part of the machine's fingerprint (mjtraj's own is not: a change of mjtraj is
what the oracles are for)."""


@dataclass(frozen=True)
class GoldenSet:
    """What one golden file pins (see the module docstring).

    Attributes:
      name: the file's name, tests/golden/NAME.json.
      laws: control law -> (scenarios per family, planners, families) of its sweep rows by protocol v1.
      laws_v2: the same by protocol v2.
      compare_laws: the laws Table I is computed under.
      nonlinear_tasks: nominal tasks (0..K-1) each nonlinear planner plans, besides the paper's move.
      floors: the scenarios of each family whose floor is computed.
      policy: scenarios per family (0..K-1) the shipped policy is scored on, by protocol v1 and v2.
    """

    name: str
    laws: Mapping[str, tuple[int, tuple[str, ...], tuple[str, ...]]]
    laws_v2: Mapping[str, tuple[int, tuple[str, ...], tuple[str, ...]]]
    compare_laws: tuple[str, ...]
    nonlinear_tasks: int
    floors: tuple[int, ...]
    policy: tuple[int, int]


SETS = {
    "fast": GoldenSet("fast", {"pid": (3, PLANNERS, FAMILIES), "computed_torque": (2, PLANNERS, FAMILIES),
                               "adaptive_computed_torque": (2, PLANNERS, FAMILIES),
                               "mpc": (1, ("optimal", "cubic"), ("aggressive",)),
                               "adaptive_mpc": (1, ("optimal", "cubic"), ("aggressive",))},
                      {"pid": (1, ("cubic",), FAMILIES_V2), "adaptive_computed_torque": (1, ("cubic",), FAMILIES_V2),
                       "mpc": (1, ("cubic",), ("aggressive",))},
                      ("pid", "computed_torque"), 2, (1,), (2, 1)),
    "full": GoldenSet("full", {"pid": (10, PLANNERS, FAMILIES), "computed_torque": (10, PLANNERS, FAMILIES),
                               "adaptive_computed_torque": (10, PLANNERS, FAMILIES), "mpc": (3, PLANNERS, FAMILIES),
                               "adaptive_mpc": (3, PLANNERS, FAMILIES)},
                      {"pid": (4, ("optimal", "cubic"), FAMILIES_V2),
                       "computed_torque": (4, ("optimal", "cubic"), FAMILIES_V2),
                       "adaptive_computed_torque": (4, ("optimal", "cubic"), FAMILIES_V2),
                       "mpc": (2, ("optimal", "cubic"), FAMILIES_V2),
                       "adaptive_mpc": (2, ("optimal", "cubic"), FAMILIES_V2)},
                      LAWS, 10, (0, 1, 2, 3, 4), (10, 4)),
}
"""The golden sets: `fast` (checked by the fast tier) and `full` (by the slow tier: tens of executions per family
and law). The predictive laws cost about 0.3 s an episode of 2 s: in `fast` their rows are the aggressive family's
(short moves), and the floors' starts execute them on the other families (each floor record's J_mpc and
J_adaptive_mpc). `fast` floors scenario 1 of each family: mismatch scenario 0's solve takes 60 iterations (1.7 s
more)."""


@dataclass(frozen=True)
class Entry:
    """One oracle: statuses (always compared exactly), values (exactly on the recording machine, else within the
    tolerance of `kind`), `exact` values and sha256 hashes of arrays' float64 bytes (on the recording machine only).
    """

    kind: str = "float64"
    statuses: Mapping[str, str | int | bool] = field(default_factory=dict)
    values: Mapping[str, float] = field(default_factory=dict)
    exact: Mapping[str, float | str] = field(default_factory=dict)
    hashes: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in TOLERANCES:
            raise InvalidInputError(f"kind: expected one of {', '.join(TOLERANCES)}, got {self.kind!r}")

    def record(self) -> dict[str, Any]:
        """JSON-ready: floats as their repr (they round-trip), non-finite ones as the strings 'nan', 'inf', '-inf'."""
        out: dict[str, Any] = {"kind": self.kind}
        for name in PARTS:
            part = getattr(self, name)
            if part:
                out[name] = {k: _json_float(v) if name in ("values", "exact") and not isinstance(v, str) else v
                             for k, v in part.items()}
        return out

    @classmethod
    def from_record(cls, record: Mapping[str, Any]) -> Entry:
        return cls(record.get("kind", "float64"), dict(record.get("statuses", {})),
                   {k: float(v) for k, v in record.get("values", {}).items()},
                   {k: _from_json(v) for k, v in record.get("exact", {}).items()}, dict(record.get("hashes", {})))


PARTS = ("statuses", "values", "exact", "hashes")


@dataclass(frozen=True)
class Difference:
    """One golden value that moved: where, the golden and the new value, and the rule it broke."""

    entry: str
    key: str
    old: Any
    new: Any
    rule: str

    def line(self) -> str:
        return f"{self.entry} {self.key}: golden {self.old!r}, now {self.new!r} ({self.rule})"


@dataclass(frozen=True)
class Check:
    """A golden file checked against this code on this machine."""

    path: Path
    same_machine: bool
    differences: list[Difference]
    unpinned: list[str]
    """Entries or keys computed now that the file does not hold (new outputs: not a failure; the next --write pins
    them)."""

    def message(self, *, limit: int = 40) -> str:
        """What moved, how it was compared, and what to do."""
        how = ("bit for bit: this machine's fingerprint is the recording machine's" if self.same_machine else
               "within each entry's tolerance (" + ", ".join(f"{k} {v:g} relative" for k, v in TOLERANCES.items()
                                                             if v is not None)
               + "; sensitive entries by their statuses): this machine's fingerprint is not the recording machine's")
        lines = [f"{len(self.differences)} golden value(s) of {self.path} moved, compared {how}:"]
        lines += [f"  {d.line()}" for d in self.differences[:limit]]
        if len(self.differences) > limit:
            lines.append(f"  ... and {len(self.differences) - limit} more")
        lines.append(f"If the change is intended, regenerate the golden files with `{COMMAND}` and say in "
                     "CHANGELOG.md why they moved (docs/testing.md, \"Golden values\").")
        return "\n".join(lines)


def _json_float(value: float) -> float | str:
    value = float(value)
    return value if math.isfinite(value) else repr(value)


def _from_json(value: float | str) -> float | str:
    """A value of `exact` as written: a float, its non-finite spellings, or a word."""
    return float(value) if not isinstance(value, str) or value in ("nan", "inf", "-inf") else value


def _same(a: float | str, b: float | str) -> bool:
    """Bit-for-bit equality of two floats (NaN equals NaN; 0.0 and -0.0 differ), or of two words."""
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return repr(float(a)) == repr(float(b))


ROUND_OFF = 1e-15
"""An absolute difference every entry tolerates across machines, beside its relative one: values that are zero but for
round-off (an at-rest end speed of 2.3e-10 rad/s moved by 2.8e-17, 1.2e-7 of itself, between an Intel Xeon and an
AMD EPYC) are not relatively precise."""


def _close(old: float, new: float, rtol: float) -> bool:
    """|new - old| <= rtol |old| + ROUND_OFF (NaN only equals NaN, an infinity only itself)."""
    if math.isnan(old) or math.isnan(new):
        return math.isnan(old) and math.isnan(new)
    if math.isinf(old) or math.isinf(new):
        return old == new
    return abs(new - old) <= rtol * abs(old) + ROUND_OFF


def compare_entries(golden: Mapping[str, Entry], now: Mapping[str, Entry], *, exact: bool
                    ) -> tuple[list[Difference], list[str]]:
    """The differences of `now` from `golden`, and what `now` holds that `golden` does not.

    Statuses are compared exactly. With `exact` (the recording machine) every value by its repr, and the hashes;
    else each value within TOLERANCES[kind] relative of its golden one (none for a `sensitive` entry), and neither
    the `exact` values nor the hashes. An entry or key of `golden` that `now` lacks is a difference."""
    differences: list[Difference] = []
    unpinned = [name for name in now if name not in golden]
    for name, old in golden.items():
        new = now.get(name)
        if new is None:
            differences.append(Difference(name, "(entry)", "present", "missing", "no longer computed"))
            continue
        rtol = TOLERANCES[old.kind]
        for key, value in old.statuses.items():
            if new.statuses.get(key, "missing") != value:
                differences.append(Difference(name, key, value, new.statuses.get(key, "missing"), "status, exact"))
        for part in ("values", "exact") if exact else ("values",) if rtol is not None else ():
            mine, theirs = getattr(old, part), getattr(new, part)
            for key, value in mine.items():
                if key not in theirs:
                    differences.append(Difference(name, key, value, "missing", "value"))
                elif exact and not _same(value, theirs[key]):
                    differences.append(Difference(name, key, value, theirs[key], "exact"))
                elif not exact and rtol is not None and not _close(value, theirs[key], rtol):
                    differences.append(Difference(name, key, value, theirs[key],
                                                  f"relative {_relative(value, theirs[key]):.2g} > {rtol:g}"))
        if exact:
            for key, value in old.hashes.items():
                if new.hashes.get(key) != value:
                    differences.append(Difference(name, key, value[:16], str(new.hashes.get(key, "missing"))[:16],
                                                  "sha256 of the array, exact"))
        unpinned += [f"{name} {key}" for part in PARTS for key in getattr(new, part) if key not in getattr(old, part)]
    return differences, unpinned


def _relative(old: float, new: float) -> float:
    if not (math.isfinite(old) and math.isfinite(new)):
        return math.inf
    return abs(new - old) / abs(old) if old else math.inf


# The machine


def _cpu() -> dict[str, str]:
    """The CPU's model and a digest of its feature flags (SIMD paths differ with them), from /proc/cpuinfo."""
    facts: dict[str, str] = {}
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return {"cpu": platform.processor() or platform.machine()}
    for line in text.split("\n\n")[0].splitlines():
        key, _, value = line.partition(":")
        facts[key.strip()] = value.strip()
    flags = " ".join(sorted(facts.get("flags", facts.get("Features", "")).split()))
    model = " ".join(facts.get(k, "") for k in ("vendor_id", "model name", "cpu family", "model", "stepping"))
    return {"cpu": " ".join(model.split()) or platform.machine(),
            "cpu_flags": hashlib.sha256(flags.encode()).hexdigest()[:16]}


def _version(name: str) -> str:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return ""


def fingerprint() -> dict[str, str]:
    """What decides the bits of a float64 result besides mjtraj's own code: the CPU (model, flags), the platform,
    Python, FINGERPRINT_LIBRARIES' versions and the BLAS (`mjtraj.versions.blas`). Two machines with equal
    fingerprints give the same golden values bit for bit."""
    return {**_cpu(), "platform": f"{platform.system()} {platform.machine()}", "python": platform.python_version(),
            **{name: _version(name) for name in FINGERPRINT_LIBRARIES}, "blas": blas()}


# The entries


def digest(name: str, array: NDArray[Any]) -> tuple[dict[str, float], dict[str, str]]:
    """An array's values for the tolerance check (per column: RMS and largest magnitude) and its exact hash (sha256
    of its C-ordered float64 bytes and its shape)."""
    import numpy as np

    a = np.ascontiguousarray(array, dtype=np.float64)
    columns = a.reshape(a.shape[0], -1) if a.ndim > 1 else a[:, None]
    values = {}
    for j in range(columns.shape[1]):
        values[f"{name}.rms_{j}"] = float(np.sqrt(np.mean(np.square(columns[:, j]))))
        values[f"{name}.max_{j}"] = float(np.max(np.abs(columns[:, j])))
    sha = hashlib.sha256(repr(a.shape).encode() + a.tobytes()).hexdigest()
    return values, {name: sha}


def _plan_entry(reference: Any) -> Entry:
    """A plan's record (numbers as values, words as statuses; timings and round-off left out) and its arrays."""
    statuses: dict[str, str | int | bool] = {}
    values: dict[str, float] = {}
    exact: dict[str, float] = {}
    hashes: dict[str, str] = {}
    for key, value in reference.info.items():
        if key.endswith(WALL_CLOCK):
            continue
        if isinstance(value, (str, bool)):
            statuses[key] = value
        elif isinstance(value, (int, float)):
            (exact if key in NOISE else values)[key] = float(value)
    for name in ("q", "qd", "qdd", "u_plan"):
        array = getattr(reference, name)
        if array is None:
            continue
        more, sha = digest(name, array) if name == "u_plan" else ({}, digest(name, array)[1])
        values.update(more)
        hashes.update(sha)
    return Entry("float64", statuses, values, exact, hashes)


def _row_entry(row: Mapping[str, Any], kind: str = "float64", law: str = "") -> Entry:
    """A sweep row's oracle: its status and solver, its metrics and plan effort; `sensitive` for a predictive law's
    row."""
    from mjtraj.core.metrics import METRIC_NAMES
    from mjtraj.core.settle import SETTLE_METRICS

    values = {m: float(row[m]) for m in (*METRIC_NAMES, *SETTLE_METRICS, "plan_effort") if m in row}
    if law in PREDICTIVE:
        kind = "sensitive"
    return Entry(kind, {"status": row["status"], "solver": str(row.get("solver", ""))}, values)


def _draw_entry(drawn: Any) -> Entry:
    task = drawn.task
    values = {"duration": float(task.duration), **{f"q0_{j}": float(v) for j, v in enumerate(task.q0)},
              **{f"qg_{j}": float(v) for j, v in enumerate(task.qg)}}
    if drawn.perturbation is not None:
        values.update(drawn.perturbation.as_dict())
    return Entry("float64", {}, values)


def law_config(law: str, folder: Path) -> str | None:
    """The base scenario of control law `law` as `mjtraj rl eval` chooses it (its `_law_config`: a shipped file, or
    paper.toml with the law, written into `folder`)."""
    from mjtraj.rl.evaluate import _law_config

    return _law_config(law, folder)


def draws(spec: GoldenSet) -> dict[str, Entry]:
    """`draw/FAMILY/I` for every scenario any part of the set uses."""
    from mjtraj.study import draw_scenario, load_scenario

    base = load_scenario()
    counts = [n for laws in (spec.laws, spec.laws_v2) for n, _, _ in laws.values()]
    count = max([*counts, max(spec.floors) + 1, *spec.policy])
    return {f"draw/{family}/{i}": _draw_entry(draw_scenario(family, SEED, i, base.model, base.task.dt))
            for family in FAMILIES for i in range(count)}


def sweep_settings(law: str, family: str, count: int, planners: Sequence[str], protocol: str, folder: Path
                   ) -> Any:
    """The SweepSettings `mjtraj rl eval --protocol PROTOCOL` scores `family`'s scenarios 0..count-1 with, one unit
    (`evaluate`: the law's base scenario, the protocol's settle window, the noisy family's measurement noise)."""
    from mjtraj.rl.protocol import NOISY_FAMILY, NOISY_SIGMA, SETTLE, sweep_family
    from mjtraj.study import SweepSettings

    return SweepSettings(families=(sweep_family(family),), scenarios=count, seed=SEED, planners=tuple(planners),
                         config=law_config(law, folder), batch=count, settle=SETTLE[protocol],
                         sensor_noise=NOISY_SIGMA if family == NOISY_FAMILY else 0.0)


def sweeps(spec: GoldenSet, folder: Path, protocol: str = "v1") -> dict[str, Entry]:
    """`sweep/LAW/FAMILY/I/PLANNER` (protocol v1) or `sweep_v2/...` (v2): each law's rows, one unit per family."""
    from mjtraj.study import run_unit

    group = "sweep" if protocol == "v1" else f"sweep_{protocol}"
    out = {}
    for law, (count, planners, families) in (spec.laws if protocol == "v1" else spec.laws_v2).items():
        for family in families:
            settings = sweep_settings(law, family, count, planners, protocol, folder)
            for row in run_unit(settings, (settings.families[0], 0)).rows:
                out[f"{group}/{law}/{family}/{row['scenario']}/{row['planner']}"] = _row_entry(row, law=law)
    return out


def comparisons(spec: GoldenSet) -> dict[str, Entry]:
    """`compare/LAW/PLANNER` and `compare/LAW/stability`: Table I on the paper's move under each law."""
    from mjtraj.study import load_scenario
    from mjtraj.study.comparison import compare

    out = {}
    for law in spec.compare_laws:
        scenario = load_scenario()
        if law != scenario.loop.controller:
            scenario = scenario.replace(loop={"controller": law})  # as `mjtraj compare --controller LAW`
        result = compare(scenario)
        for b, name in enumerate(result.planners):
            plan = _plan_entry(result.references[name])
            outcome = result.outcomes[name]
            statuses = {"status": outcome.status, "diverged_step": int(result.rollout.diverged_step[b]),
                        **{f"plan.{k}": v for k, v in plan.statuses.items()}}
            metrics = result.metrics[name].as_dict()
            values = {**metrics, **{f"plan.{k}": v for k, v in plan.values.items()}}
            kind = "sensitive" if law in PREDICTIVE else "float64"
            out[f"compare/{law}/{name}"] = Entry(kind, statuses, values, {f"plan.{k}": v for k, v in
                                                                          plan.exact.items()}, plan.hashes)
        for name, reason in result.failed.items():
            out[f"compare/{law}/{name}"] = Entry("float64", {"status": "not planned", "reason": reason})
        out[f"compare/{law}/stability"] = Entry("float64", {}, dict(result.stability))
    return out


def nonlinear_plans(spec: GoldenSet) -> dict[str, Entry]:
    """`nonlinear/PLANNER/paper` and `nonlinear/PLANNER/nominal/I`: the nonlinear planners' plans."""
    from mjtraj.core.planners import make
    from mjtraj.exceptions import MjtrajError
    from mjtraj.study import draw_scenario, load_scenario

    base = load_scenario()
    tasks = {"paper": base.task, **{f"nominal/{i}": draw_scenario("nominal", SEED, i, base.model, base.task.dt).task
                                    for i in range(spec.nonlinear_tasks)}}
    out = {}
    for planner in NONLINEAR:
        for label, task in tasks.items():
            try:
                entry = _plan_entry(make(planner).plan(task, base.model))
            except MjtrajError as e:
                entry = Entry("float64", {"error": type(e).__name__})
            out[f"nonlinear/{planner}/{label}"] = entry
    return out


def floors(spec: GoldenSet) -> dict[str, Entry]:
    """`floor/FAMILY/I`: each classical starting law's J_exec on cubic's reference, `floor/FAMILY/I/predictive` the
    predictive ones' (`sensitive`), and `floor/FAMILY/I/solve` the floor of that execution (`mjtraj floor`;
    `sensitive` on the mismatch family, where it is a local minimum)."""
    from mjtraj.study import family_floors, load_scenario

    base = load_scenario()
    out = {}
    predictive = tuple(f"J_{law}" for law in PREDICTIVE)
    for family in FAMILIES:
        for record in family_floors(base, family, seed=SEED, scenarios=spec.floors):
            name = f"floor/{family}/{record['scenario']}"
            record = {k: v for k, v in record.items() if k not in ("family", "scenario", "planner")
                      and not k.endswith(WALL_CLOCK)}
            starts = {k: v for k, v in record.items() if k not in (*SOLVE_EXACT, *predictive, "floor")}
            out[name] = Entry("float64", {k: v for k, v in starts.items() if isinstance(v, str)},
                              {k: float(v) for k, v in starts.items() if not isinstance(v, str)})
            if "floor" not in record:  # the floor failed: its status says why
                continue
            out[f"{name}/predictive"] = Entry("sensitive", {}, {k: float(record[k]) for k in predictive
                                                                if k in record})
            out[f"{name}/solve"] = Entry("sensitive" if family == "mismatch" else "float64", {},
                                         {"floor": float(record["floor"])},
                                         {k: v if isinstance(v, str) else float(v) for k, v in record.items()
                                          if k in SOLVE_EXACT})
    return out


def policy_entry_kind(policy_kind: str) -> str:
    """The kind (TOLERANCES) of a shipped policy's entries by its loaded kind (`ScoredPolicy.kind`): float32 for a
    PyTorch network (a torch module or an SB3 zip), float64 for one in NumPy (a plan policy, a callable)."""
    return "float32" if policy_kind in ("torch", "sb3-zip") else "float64"


def policy_rows(spec: GoldenSet, folder: Path, protocol: str = "v1") -> dict[str, Entry]:
    """`policy/FAMILY/I` (protocol v1) or `policy_v2/FAMILY/I` (v2): the protocol's shipped policy (POLICIES)
    scored as `mjtraj rl eval` scores it, on one PyTorch thread (rl eval's default): its rows of `run_unit` with the
    policy as an actor on its planner's references under its control law's base scenario; float32 entries for a
    PyTorch network, float64 for one in NumPy."""
    import torch

    from mjtraj.rl.adapters import load_any
    from mjtraj.rl.episodes import PolicyActor
    from mjtraj.study import ActorSpec, run_unit

    name = POLICIES[protocol]
    policy = load_any(name)
    kind = policy_entry_kind(policy.kind)
    group = "policy" if protocol == "v1" else f"policy_{protocol}"
    count = spec.policy[0 if protocol == "v1" else 1]
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        out = {}
        for family in FAMILIES if protocol == "v1" else FAMILIES_V2:
            settings = sweep_settings(policy.controller, family, count, (policy.planner,), protocol, folder)
            actor = ActorSpec(name, policy.planner, PolicyActor(policy, policy.settings()))
            for row in run_unit(settings, (settings.families[0], 0), actors=[actor]).rows:
                if row["planner"] == name:
                    entry = _row_entry(row, kind)
                    out[f"{group}/{family}/{row['scenario']}"] = Entry(
                        kind, {**entry.statuses, "policy_sha256": policy.sha256[:16]}, entry.values)
    finally:
        torch.set_num_threads(threads)
    return out


GROUPS: dict[str, Callable[[GoldenSet, Path], dict[str, Entry]]] = {
    "draw": lambda spec, folder: draws(spec),
    "sweep": sweeps,
    "sweep_v2": lambda spec, folder: sweeps(spec, folder, "v2"),
    "compare": lambda spec, folder: comparisons(spec),
    "nonlinear": lambda spec, folder: nonlinear_plans(spec),
    "floor": lambda spec, folder: floors(spec),
    "policy": policy_rows,
    "policy_v2": lambda spec, folder: policy_rows(spec, folder, "v2"),
}
"""The groups of entries, by the first part of their names, and what computes them."""


def compute(spec: GoldenSet, *, groups: Sequence[str] = tuple(GROUPS),
            progress: Callable[[str], None] | None = None) -> dict[str, Entry]:
    """Every entry of the set (or of `groups`), computed through the library paths the published numbers come from,
    on one BLAS thread (as every mjtraj call and the CLI run)."""
    from mjtraj.threads import one_blas_thread

    for group in groups:
        if group not in GROUPS:
            raise InvalidInputError(f"group: expected one of {', '.join(GROUPS)}, got {group!r}")
    out: dict[str, Entry] = {}
    with one_blas_thread(), tempfile.TemporaryDirectory(prefix="mjtraj-golden-") as tmp:
        for group in groups:
            if progress is not None:
                progress(group)
            out.update(GROUPS[group](spec, Path(tmp)))
    return out


# The files


def default_folder() -> Path:
    """The checkout's tests/golden/ (InvalidInputError for an installed mjtraj: give the folder)."""
    root = Path(__file__).resolve().parent.parent
    if not (root / "pyproject.toml").is_file() or not (root / "tests").is_dir():
        raise InvalidInputError(f"dir: mjtraj at {root / 'mjtraj'} is installed, not a checkout; give the folder of "
                                "the golden files (a checkout's tests/golden)")
    return root / "tests" / "golden"


def golden_path(spec: GoldenSet, folder: Path) -> Path:
    return Path(folder) / f"{spec.name}.json"


def file_record(spec: GoldenSet, entries: Mapping[str, Entry]) -> dict[str, Any]:
    """The golden file's content: how to regenerate it, the tolerances, the recording machine and the entries. No
    date: an unchanged tree writes an unchanged file."""
    from mjtraj.versions import __version__

    return {"about": f"Regression oracles of mjtraj (mjtraj.golden, docs/testing.md). Written by `{COMMAND}`; "
                     "when they move, CHANGELOG.md says why.",
            "set": spec.name, "seed": SEED, "tolerances": TOLERANCES, "mjtraj": __version__,
            "fingerprint": fingerprint(), "entries": {name: entries[name].record() for name in sorted(entries)}}


def write(spec: GoldenSet, entries: Mapping[str, Entry], folder: Path) -> Path:
    """Write the set's golden file into `folder`; its path."""
    from mjtraj.files import write_text_atomic

    path = golden_path(spec, folder)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, json.dumps(file_record(spec, entries), indent=1) + "\n")
    return path


def read(spec: GoldenSet, folder: Path) -> tuple[dict[str, str], dict[str, Entry]]:
    """The recording machine's fingerprint and the entries of the set's golden file in `folder`."""
    path = golden_path(spec, folder)
    if not path.is_file():
        raise InvalidInputError(f"dir: no golden file {path}; write it with `{COMMAND}`")
    try:
        record = json.loads(path.read_text())
        return dict(record["fingerprint"]), {k: Entry.from_record(v) for k, v in record["entries"].items()}
    except (ValueError, KeyError, TypeError) as e:
        raise InvalidInputError(f"dir: {path} is not a golden file ({e}); write it again with `{COMMAND}`") from e


def check(spec: GoldenSet, folder: Path, entries: Mapping[str, Entry] | None = None, *,
          groups: Sequence[str] | None = None) -> Check:
    """The set's golden file in `folder` against `entries` (default: computed now), bit for bit where this
    machine's fingerprint is the recording one's, else at TOLERANCES. With `groups`, only the file's entries of
    those groups are checked."""
    recorded, golden = read(spec, folder)
    if groups is not None:
        golden = {k: v for k, v in golden.items() if k.split("/")[0] in groups}
    if entries is None:
        entries = compute(spec, groups=tuple(groups) if groups is not None else tuple(GROUPS))
    same = recorded == fingerprint()
    differences, unpinned = compare_entries(golden, entries, exact=same)
    return Check(golden_path(spec, folder), same, differences, unpinned)
