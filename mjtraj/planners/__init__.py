"""Trajectory planners: one module each, all registered by name (see `available` and `make`)."""

from mjtraj.planners.base import Planner, available, make, register
from mjtraj.planners.cubic import Cubic
from mjtraj.planners.optimal import Optimal, bryson_weights
from mjtraj.planners.quintic import Quintic
from mjtraj.planners.trapezoidal import Trapezoidal

__all__ = ["Cubic", "Optimal", "Planner", "Quintic", "Trapezoidal", "available", "bryson_weights", "make",
           "register"]
