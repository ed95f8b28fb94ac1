"""The trained policies the benchmark's summary reports, shipped so that anyone can score them again.

Each baseline is a folder NAME/ with the SB3 zip and its record (policy.zip, policy.json), a batched run's
policy (policy.pt: the torch module with its record; mjtraj.rl.batched) or a plan run's (policy.npz: the network
with its record; mjtraj.rl.plan_policy), and the training run's run.json;
`baseline:NAME` loads it wherever a policy is accepted, `mjtraj rl baselines` lists them, and
TRAINING.md beside this file gives the command that trained each.
"""

from __future__ import annotations

import hashlib
import io
import json
import shutil
import zipfile
from importlib import resources
from pathlib import Path
from typing import Any

from mjtraj.exceptions import InvalidInputError
from mjtraj.files import atomic_path, write_text_atomic

OPTIMIZER_MEMBERS = ("actor.optimizer.pth", "critic.optimizer.pth", "ent_coef_optimizer.pth", "policy.optimizer.pth")
"""Members of an SB3 zip that hold optimiser states: needed to continue training, never to act."""


def baselines_folder() -> Path:
    """Where the shipped baselines live."""
    return Path(str(resources.files("mjtraj.rl.baselines")))


POLICY_FILES = ("policy.zip", "policy.pt", "policy.npz")
"""A baseline's policy: an SB3 zip, a batched run's module, or a plan run's policy."""


def baseline_names() -> list[str]:
    """The shipped baselines, sorted."""
    return sorted({p.parent.name for name in POLICY_FILES for p in baselines_folder().glob(f"*/{name}")})


BEST_FILE = "BEST.json"
"""The record of `baseline:best`'s choice (mjtraj.rl.best), beside the baselines."""


def best_name(folder: Path | None = None) -> str:
    """The baseline `baseline:best` names (BEST.json's choice).

    Raises:
      InvalidInputError: no choice has been made (mjtraj rl best makes it).
    """
    path = (folder or baselines_folder()) / BEST_FILE
    if not path.is_file():
        raise InvalidInputError("policy: baseline:best has not been chosen yet; run mjtraj rl best")
    return str(json.loads(path.read_text())["best"])


def baseline_path(name: str) -> Path:
    """The policy file of baseline `name` (one of POLICY_FILES; best: the one BEST.json names, see
    mjtraj.rl.best).

    Raises:
      InvalidInputError: no such baseline (the message lists them).
    """
    if name == "best":
        name = best_name()
    if name and "/" not in name:
        for file in POLICY_FILES:
            path = baselines_folder() / name / file
            if path.is_file():
                return path
    raise InvalidInputError(f"policy: no baseline {name!r}; shipped: {', '.join(baseline_names()) or 'none'}")


def describe(name: str) -> dict[str, Any]:
    """A baseline's facts from its record: algorithm, seed, the checkpoint's steps (None for a plan), the env it
    acts in, the run's settings; a plan's also its name (`label`)."""
    path = baseline_path(name)
    if path.suffix == ".npz":
        from mjtraj.rl.plan_policy import load_plan

        plan = load_plan(path)
        settings = plan.record["settings"]
        return {"name": name, "algo": "plan", "seed": settings["seed"], "timesteps": None, "env": plan.env,
                "settings": settings, "label": plan.name}
    if path.suffix == ".pt":
        from mjtraj.rl.batched_policy import load_batched

        record = load_batched(path).record
        settings = record["settings"]
        return {"name": name, "algo": "ppo (batched)", "seed": settings["seed"], "timesteps": record["timesteps"],
                "env": {"controller": settings["controller"],
                        "plant_randomization": "+".join(settings["families"])}, "settings": settings}
    record = json.loads((path.parent / "policy.json").read_text())
    run = record["run"]
    return {"name": name, "algo": run["settings"]["algo"], "seed": run["settings"]["seed"],
            "timesteps": record["timesteps"], "env": run["env"], "settings": run["settings"]}


def strip_optimizers(source: Path, target: Path) -> None:
    """Copy the SB3 zip `source` to `target` with every optimiser's state emptied (its parameter groups kept, so
    that SB3 still loads it): about half the size, the same actions bit for bit (acting reads only the policy)."""
    import torch

    with zipfile.ZipFile(source) as zin, atomic_path(target) as tmp, \
            zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename in OPTIMIZER_MEMBERS:
                state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=False)
                buffer = io.BytesIO()
                torch.save({"state": {}, "param_groups": state["param_groups"]}, buffer)
                data = buffer.getvalue()
            zout.writestr(info.filename, data)


STUDENT_RULE = ("a student ships a privileged teacher's weights (trained observing each plant's true payload, "
                "damping and friction) observing instead the adaptive law's online estimate of them: RMA's recipe "
                "(Kumar et al., 2021) with Slotine and Li's estimator, which needs only the measured motion, as the "
                "adaptation module; deployable, as nothing privileged reaches it")


def ship(run: str | Path, name: str, *, which: str = "best", into: str | Path | None = None,
         student: bool = False) -> Path:
    """Ship policy `which` (best: selected on validation; policy: the final one) of the training run folder `run`
    as baseline `name`: its zip without optimiser states, its record (zip_sha256 updated, the original's kept as
    source_zip_sha256), run.json and learning_curve.csv, into `into` (default: this package's folder). With
    `student`, a teacher run (observe_plant=true on the adaptive law) ships as its deployable student
    (STUDENT_RULE): the same weights, its record's env observing the estimate.

    Raises:
      InvalidInputError: no such run or policy, a name that is not a plain folder name, or `student` on a run
        that is not a teacher on the adaptive law.
    """
    from mjtraj.rl.policy import load_policy, record_path

    run = Path(run)
    if (run / f"{which}.pt").is_file() and not (run / f"{which}.zip").is_file():
        return _ship_batched(run, name, which, into)
    if (run / "policy.npz").is_file() and not (run / f"{which}.zip").is_file():
        if student:
            raise InvalidInputError(f"student: {run} is a plan run (rl plan); only a teacher on the adaptive law "
                                    "ships as a student")
        return _ship_plan(run, name, into)
    source = run / f"{which}.zip"
    if not source.is_file() or not (run / "run.json").is_file():
        raise InvalidInputError(f"run: {source} or {run / 'run.json'} not found; expected a folder of rl train")
    _check_name(name)
    body = json.loads(record_path(source).read_text())
    if student:
        env = body["run"]["env"]
        if env.get("observe_plant") != "true" or env.get("controller") != "adaptive_computed_torque":
            raise InvalidInputError(f"student: {run} is not a teacher on the adaptive law (observe_plant "
                                    f"{env.get('observe_plant', 'none')!r}, controller {env.get('controller')!r}); "
                                    "train one with --observe-plant true --controller adaptive_computed_torque")
        env["observe_plant"] = "estimate"
        body["run"]["student"] = {"rule": STUDENT_RULE, "teacher": f"{run.name}/{which}.zip"}
    folder = Path(into) if into is not None else baselines_folder()
    target = folder / name
    target.mkdir(parents=True, exist_ok=True)
    strip_optimizers(source, target / "policy.zip")
    sha = hashlib.sha256((target / "policy.zip").read_bytes()).hexdigest()
    body.update(source_zip_sha256=body["zip_sha256"], zip_sha256=sha, shipped_from=f"{run.name}/{which}.zip")
    write_text_atomic(target / "policy.json", json.dumps(body, indent=1) + "\n")
    shutil.copyfile(run / "run.json", target / "run.json")
    original, shipped = load_policy(source), load_policy(target / "policy.zip")
    import numpy as np

    probe = np.random.default_rng(0).normal(size=(64, original.normalization.mean.size)) * 2.0
    if not np.array_equal(original.act(probe), shipped.act(probe)):
        raise InvalidInputError(f"ship: the stripped zip of {source} acts differently; not shipped")
    return target / "policy.zip"


def _check_name(name: str) -> None:
    """Refuse a baseline name that is not a plain folder name."""
    if not name or not all(c.isalnum() or c in "_-" for c in name):
        raise InvalidInputError(f"name: expected letters, digits, _ and -, got {name!r}")


def _ship_plan(run: Path, name: str, into: str | Path | None) -> Path:
    """`ship` of a plan run (mjtraj.rl.plan_train; `which` does not apply: it has one policy): its policy.npz and
    run.json, checked to plan as the original, bit for bit, on a probe task; nothing is left behind if not."""
    import numpy as np

    from mjtraj.core import Task
    from mjtraj.rl.plan_policy import load_plan

    if not (run / "run.json").is_file():
        raise InvalidInputError(f"run: {run / 'run.json'} not found; expected a folder of rl plan")
    _check_name(name)
    original = load_plan(run / "policy.npz")  # refuses a file that is not a plan policy before anything is written
    target = (Path(into) if into is not None else baselines_folder()) / name
    others = [f for f in POLICY_FILES if f != "policy.npz" and (target / f).is_file()]
    if others:
        raise InvalidInputError(f"name: baseline {name!r} already holds {', '.join(others)}, which baseline:{name} "
                                "would load instead; expected a new name or an empty folder")
    target.mkdir(parents=True, exist_ok=True)
    for file in ("policy.npz", "run.json"):
        with atomic_path(target / file) as tmp:
            shutil.copyfile(run / file, tmp)
    shipped = load_plan(target / "policy.npz")
    q0 = np.array([0.3, -1.2, 1.4])[:original.n]
    probe = Task(q0, q0 + 0.4, 0.8, original.dt)
    if original.record != shipped.record or not np.array_equal(original.plan(probe), shipped.plan(probe)):
        for file in ("policy.npz", "run.json"):
            (target / file).unlink(missing_ok=True)
        raise InvalidInputError(f"ship: the copy of {run / 'policy.npz'} plans differently; not shipped")
    return target / "policy.npz"


def _ship_batched(run: Path, name: str, which: str, into: str | Path | None) -> Path:
    """`ship` of a batched run (mjtraj.rl.batched): its module as policy.pt, with run.json and the learning curve;
    the copy is checked to act as the original, bit for bit."""
    import numpy as np
    import torch

    from mjtraj.rl.batched_policy import load_batched

    if not (run / "run.json").is_file():
        raise InvalidInputError(f"run: {run / 'run.json'} not found; expected a folder of rl train --batched")
    _check_name(name)
    target = (Path(into) if into is not None else baselines_folder()) / name
    target.mkdir(parents=True, exist_ok=True)
    for source, copy in ((f"{which}.pt", "policy.pt"), ("run.json", "run.json"),
                         ("learning_curve.csv", "learning_curve.csv"), ("learning_curve.png", "learning_curve.png")):
        if (run / source).is_file():
            with atomic_path(target / copy) as tmp:
                shutil.copyfile(run / source, tmp)
    original, shipped = load_batched(run / f"{which}.pt"), load_batched(target / "policy.pt")
    probe = torch.as_tensor(np.random.default_rng(0).normal(size=(64, original.mean.numel())) * 2.0,
                            dtype=torch.float32)
    if not torch.equal(original(probe), shipped(probe)):
        raise InvalidInputError(f"ship: the copy of {run / f'{which}.pt'} acts differently; not shipped")
    return target / "policy.pt"
