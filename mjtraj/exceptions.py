"""The one exception tree of mjtraj: every error the library raises on purpose derives from MjtrajError."""

from __future__ import annotations


class MjtrajError(Exception):
    """Root of every error mjtraj raises on purpose."""


class InvalidInputError(MjtrajError, ValueError):
    """An argument, option or file entry is malformed or out of range."""


class ProvenanceError(InvalidInputError):
    """Rows of another provenance (mjtraj, a library's version, the BLAS, the CPU model, the commit) would join a
    results store: `--resume` of a store written elsewhere, or a worker that runs other code or libraries."""


class UnnamedPolicyEnvError(InvalidInputError):
    """A policy that records no env (a zip saved by stable-baselines3 itself) was given none: `reason` says so,
    `flags` are the `--policy-env KEY=VALUE` arguments that would score it (a command line's words) and the message
    ends with `example`, a command that does."""

    def __init__(self, reason: str, flags: list[str], example: str) -> None:
        super().__init__(f"{reason}, e.g. {example}")
        self.reason, self.flags = reason, flags


class ModelError(MjtrajError):
    """The MuJoCo model is missing, unreadable or lacks what mjtraj needs."""


class InfeasibleError(MjtrajError):
    """An optimisation problem has no solution within its constraints."""


class SolverError(MjtrajError):
    """A numerical solver failed or returned an unusable answer."""


class BackendError(MjtrajError):
    """A compute backend (a Ray cluster) is unavailable or unreachable."""


class MissingExtraError(MjtrajError, ImportError):
    """An optional extra (such as `rl`) that a feature needs is not installed; the message says how to get it."""


class RenderError(MjtrajError):
    """Off-screen rendering is unavailable or misconfigured."""


class PluginError(MjtrajError):
    """An installed plug-in (a planner or controller entry point) cannot be loaded or clashes with another."""


class PolicyError(MjtrajError):
    """A policy being scored raised, or returned actions of the wrong shape or non-finite ones: a bug in the policy,
    not a bad score (`mjtraj rl eval` stops on it unless told to keep going)."""


__all__ = ["BackendError", "InfeasibleError", "InvalidInputError", "MissingExtraError", "MjtrajError", "ModelError",
           "PluginError", "PolicyError", "ProvenanceError", "RenderError", "SolverError"]
