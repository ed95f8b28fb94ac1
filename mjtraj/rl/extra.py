"""The `rl` extra: import Stable-Baselines3 (and PyTorch) or say how to install them."""

from __future__ import annotations

from types import ModuleType
from typing import Any

from mjtraj.exceptions import MissingExtraError

INSTALL_HINT = ("install the rl extra: pip install torch==2.13.0 && pip install 'mjtraj[rl]' (in a checkout: "
                "pip install '.[rl]'; torch first, so that "
                "pip takes the CPU build)")


def require_sb3() -> ModuleType:
    """The stable_baselines3 module; MissingExtraError naming the missing package if the extra is absent."""
    try:
        import stable_baselines3
        import torch  # noqa: F401
    except ImportError as e:
        raise MissingExtraError(f"rl: {e.name or 'stable-baselines3'} is not installed; {INSTALL_HINT}") from e
    return stable_baselines3


def algorithm(algo: str) -> Any:
    """The algorithm class of `algo` (one of mjtraj.rl.ALGORITHMS): SB3's, or sb3-contrib's RecurrentPPO."""
    if algo == "recurrent_ppo":
        try:
            from sb3_contrib import RecurrentPPO
        except ImportError as e:
            raise MissingExtraError(f"rl: {e.name or 'sb3-contrib'} is not installed; {INSTALL_HINT}") from e
        return RecurrentPPO
    return getattr(require_sb3(), algo.upper())


def policy_class(algo: str) -> str:
    """The SB3 policy name `algo` trains: an LSTM one for the recurrent algorithm, else the MLP."""
    from mjtraj.rl import RECURRENT

    return "MlpLstmPolicy" if algo in RECURRENT else "MlpPolicy"


def rl_versions() -> dict[str, str]:
    """Versions of the RL stack that shape a policy's numbers (after mjtraj's own `compare.versions`); a package of
    the rl extra that is not installed is recorded as "not installed" (scoring a plain callable needs neither)."""
    import importlib.metadata
    import platform

    from mjtraj.versions import versions

    found = {}
    for module, distribution in (("stable_baselines3", "stable_baselines3"), ("torch", "torch")):
        try:
            found[module] = importlib.metadata.version(distribution)
        except importlib.metadata.PackageNotFoundError:
            found[module] = "not installed"
    return {**versions(), **found, "python": platform.python_version()}
