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
    """The provenance of a policy's numbers (`mjtraj.versions.provenance`: the versions of mjtraj and of its numeric
    libraries, torch among them, the BLAS, the CPU model and the commit), then Stable-Baselines3's and Python's
    versions; '' for a package that is not installed (scoring a plain callable needs neither torch nor SB3)."""
    import platform

    from mjtraj.versions import library_version, provenance

    return {**provenance(), "stable_baselines3": library_version("stable_baselines3"),
            "python": platform.python_version()}
