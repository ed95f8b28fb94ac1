"""What a training run needs to continue after an interruption, saved at a clean point between two updates.

`mjtraj rl train` writes RUN/resume/ at every checkpoint: the algorithm with its optimisers (SB3's save), its replay
buffer (off-policy algorithms), the observation and reward normaliser (VecNormalize, with its running discounted
returns), the vector env itself mid-episode (its simulations, plants, references, controller states and random
generators: it pickles whole), the episode monitor's running sums, the random generators of NumPy, PyTorch and
Python, and the progress of the run's own bookkeeping (next validation and checkpoint, learning-curve rows). The
point is the start of a rollout, after the previous update: continuing from it runs exactly what the uninterrupted
run would have run next, so on the same machine and thread count the resumed run ends with the same policy bits.
"""

from __future__ import annotations

import pickle
import random
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

RESUME_DIR = "resume"
MONITOR_FIELDS = ("episode_returns", "episode_lengths", "episode_count")


@dataclass
class ResumeState:
    """A loaded resume point: the vector env and monitor sums to rebuild the env chain, the random generators'
    states, and the run's bookkeeping (`tracker`: JSON-ready)."""

    env: Any
    monitor: dict[str, Any]
    returns: Any
    """VecNormalize's running discounted return per env."""
    rng: dict[str, Any]
    tracker: dict[str, Any]
    folder: Path


def save_state(folder: Path, model: Any, agent_env: Any, monitor: Any, normalizer: Any,
               tracker: dict[str, Any]) -> None:
    """Write `folder`/resume/ whole, or leave the previous one (written to resume.tmp, then swapped in)."""
    import torch

    tmp, final, old = folder / f"{RESUME_DIR}.tmp", folder / RESUME_DIR, folder / f"{RESUME_DIR}.old"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    model.save(tmp / "model.zip")
    if getattr(model, "replay_buffer", None) is not None:
        model.save_replay_buffer(tmp / "replay_buffer.pkl")
    normalizer.save(str(tmp / "normalizer.pkl"))
    state = {"env": agent_env, "monitor": {k: getattr(monitor, k) for k in MONITOR_FIELDS},
             "returns": normalizer.returns,  # VecNormalize's pickle leaves its running discounted returns out
             "rng": {"numpy": np.random.get_state(),  # noqa: NPY002 - SB3 samples its buffer from it
                     "torch": torch.get_rng_state(), "python": random.getstate()},
             "tracker": tracker}
    with open(tmp / "state.pkl", "wb") as f:
        pickle.dump(state, f)
    shutil.rmtree(old, ignore_errors=True)
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    shutil.rmtree(old, ignore_errors=True)


def load_state(folder: Path) -> ResumeState:
    """The resume point in `folder`/resume/ (the model and normaliser load later, on the rebuilt env chain)."""
    where = folder / RESUME_DIR
    with open(where / "state.pkl", "rb") as f:
        state = pickle.load(f)  # noqa: S301 - the run's own file, written by save_state
    return ResumeState(state["env"], state["monitor"], state["returns"], state["rng"], state["tracker"], where)


def restore_rngs(rng: dict[str, Any]) -> None:
    """Put NumPy's, PyTorch's and Python's global generators back where the resume point left them."""
    import torch

    np.random.set_state(rng["numpy"])  # noqa: NPY002 - the global generator SB3 samples its buffer from
    torch.set_rng_state(rng["torch"])
    random.setstate(rng["python"])
