"""Plug-ins: planners and controllers that other installed packages register through entry points.

A package declares, in its pyproject.toml,

    [project.entry-points."mjtraj.planners"]
    my_planner = "my_package.planning:MyPlanner"        # a Planner class (a dataclass whose fields are its options)

    [project.entry-points."mjtraj.controllers"]
    my_law = "my_package.control:make_my_law"           # factory(config, dt, n, nsim) -> Controller

and mjtraj's command line, scenario files, sweeps and the env then accept `my_planner` and `my_law` by name, exactly
as the built-in ones. Entry points are read once per process, when a name is first looked up.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from mjtraj.exceptions import PluginError

PLANNERS = "mjtraj.planners"
CONTROLLERS = "mjtraj.controllers"


@functools.cache
def _installed() -> Any:
    """Every installed entry point: one scan of the installed distributions per process (about 8 ms)."""
    return entry_points()


def group_entry_points(group: str) -> Sequence[EntryPoint]:
    """The installed entry points of `group`."""
    return tuple(_installed().select(group=group))


@functools.cache
def plugins(group: str) -> dict[str, Any]:
    """name -> the loaded object of every entry point in `group`, in name order.

    Raises:
      PluginError: an entry point cannot be loaded, or two packages use one name (naming both).
    """
    found: dict[str, Any] = {}
    where: dict[str, str] = {}
    for point in sorted(group_entry_points(group), key=lambda p: (p.name, p.value)):
        source = f"{point.value} ({point.dist.name if point.dist else 'unknown package'})"
        if point.name in found:
            raise PluginError(f"plug-in {point.name!r} in {group}: registered twice, by {where[point.name]} and by "
                              f"{source}")
        try:
            found[point.name] = point.load()
        except Exception as e:  # noqa: BLE001 - any failure of foreign code is reported as one line
            raise PluginError(f"plug-in {point.name!r} in {group}: cannot load {source}: "
                              f"{type(e).__name__}: {e}") from e
        where[point.name] = source
    return found
