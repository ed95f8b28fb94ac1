"""Trajectory planners: one module each, all registered by name (see `available` and `make`); installed plug-ins add
theirs through the `mjtraj.planners` entry points (`mjtraj.plugins`)."""

from mjtraj.core.planners.base import (
    Planner,
    available,
    check_name,
    default_names,
    make,
    plan_all,
    register,
    sampled_reference,
)
from mjtraj.core.planners.cubic import Cubic
from mjtraj.core.planners.nonlinear import NonlinearMinEffort, NonlinearOptimal, NonlinearSettings
from mjtraj.core.planners.optimal import Optimal
from mjtraj.core.planners.quintic import Quintic
from mjtraj.core.planners.scurve import SCurve
from mjtraj.core.planners.sqp import SqpSettings
from mjtraj.core.planners.trapezoidal import Trapezoidal

__all__ = [
    "Cubic", "NonlinearMinEffort", "NonlinearOptimal", "NonlinearSettings", "Optimal", "Planner", "Quintic", "SCurve",
    "SqpSettings", "Trapezoidal", "available", "check_name", "default_names", "make", "plan_all", "register",
    "sampled_reference",
]
