"""How tables name a distilled policy's configuration: in a module of its own, so that loading any policy
(`mjtraj.rl.adapters`) does not import the distillation and its trainers."""

from __future__ import annotations

from typing import Any


def distilled_label(record: dict[str, Any]) -> str:
    """A distillation's configuration (its seeds share it): cubic+LAW+residual distilled from TEACHER (scale,
    families, preview, rounds)."""
    from mjtraj.rl import law_label

    s, d = record["settings"], record["distill"]
    if s.get("action_mode", "residual") == "torque":
        return (f"cubic+torque distilled from {d['teacher']} ({'+'.join(s['families'])}, preview {d['preview']}, "
                f"{d['rounds']} rounds)")
    return (f"cubic+{law_label(s['controller'])}+residual distilled from {d['teacher']} ({s['residual_scale']:g} "
            f"N m, {'+'.join(s['families'])}, preview {d['preview']}, {d['rounds']} rounds)")
