"""The core layer: the plant, its dynamics and linearisation, the planners, the controller and the one closed
loop, rollouts, metrics and scoring. It imports nothing from the layers above it (docs/design.md, "Layers").
Every name below loads on first use."""

from __future__ import annotations

from typing import TYPE_CHECKING

from mjtraj._lazy import lazy_exports

_EXPORTS = {
    "load_model": "mjtraj.core.model",
    "default_model_path": "mjtraj.core.model",
    "JointInfo": "mjtraj.core.model",
    "Task": "mjtraj.core.task",
    "random_task": "mjtraj.core.task",
    "Reference": "mjtraj.core.reference",
    "BatchPlant": "mjtraj.core.plant",
    "GRAVITY_COMP": "mjtraj.core.plant",
    "DynamicsProbe": "mjtraj.core.dynamics",
    "linearize_many": "mjtraj.core.linearize",
    "discretize_zoh": "mjtraj.core.linearize",
    "build_qp": "mjtraj.core.qp",
    "solve_qp": "mjtraj.core.qp",
    "CondensedQP": "mjtraj.core.qp",
    "QPSolution": "mjtraj.core.qp",
    "box_lqr": "mjtraj.core.lqr",
    "BoxLQRSolution": "mjtraj.core.lqr",
    "feedforward_many": "mjtraj.core.feedforward",
    "FEEDFORWARD_MODES": "mjtraj.core.feedforward",
    "FEEDFORWARD_ACCEL": "mjtraj.core.feedforward",
    "PIDGains": "mjtraj.core.controller",
    "ControlOutput": "mjtraj.core.controller",
    "control_law": "mjtraj.core.controller",
    "controller_names": "mjtraj.core.laws",
    "FILTER": "mjtraj.core.mpc",
    "disturbance_of": "mjtraj.core.mpc",
    "AdaptiveComputedTorque": "mjtraj.core.adaptive",
    "parameter_bounds": "mjtraj.core.adaptive",
    "flange": "mjtraj.core.payload",
    "ANTI_WINDUP": "mjtraj.core.controller",
    "CONTROLLERS": "mjtraj.core.laws",
    "Controller": "mjtraj.core.controller",
    "PID": "mjtraj.core.controller",
    "ComputedTorque": "mjtraj.core.controller",
    "ClosedLoop": "mjtraj.core.closed_loop",
    "LoopConfig": "mjtraj.core.closed_loop",
    "Step": "mjtraj.core.closed_loop",
    "Rollout": "mjtraj.core.rollout",
    "RECORDED": "mjtraj.core.closed_loop",
    "Metrics": "mjtraj.core.metrics",
    "METRIC_NAMES": "mjtraj.core.metrics",
    "GOAL_TOLERANCE": "mjtraj.core.metrics",
    "missed_goal": "mjtraj.core.metrics",
    "METRIC_UNITS": "mjtraj.core.metrics",
    "metrics_arrays": "mjtraj.core.metrics",
    "gravity_along": "mjtraj.core.metrics",
    "reduction": "mjtraj.core.metrics",
    "Scoring": "mjtraj.core.scoring",
    "bryson_weights": "mjtraj.core.scoring",
    "step_cost": "mjtraj.core.scoring",
    "executed_cost": "mjtraj.core.scoring",
    "Settle": "mjtraj.core.settle",
    "SETTLE_WINDOW": "mjtraj.core.settle",
    "SETTLE_BAND": "mjtraj.core.settle",
    "SETTLE_SPEED": "mjtraj.core.settle",
    "SETTLE_METRICS": "mjtraj.core.settle",
    "SETTLE_UNITS": "mjtraj.core.settle",
    "held": "mjtraj.core.settle",
    "settle_arrays": "mjtraj.core.settle",
    "unsettled": "mjtraj.core.settle",
    "window_steps": "mjtraj.core.settle",
    "with_window": "mjtraj.core.settle",
    "JOINT_SPEED_LIMIT": "mjtraj.core.scoring",
    "gain_rule": "mjtraj.core.gains",
    "GAIN_RULE": "mjtraj.core.gains",
    "spectral_radii": "mjtraj.core.stability",
    "Planner": "mjtraj.core.planners",
    "available": "mjtraj.core.planners",
    "default_names": "mjtraj.core.planners",
    "make": "mjtraj.core.planners",
    "register": "mjtraj.core.planners",
    "check_name": "mjtraj.core.planners",
    "plan_all": "mjtraj.core.planners",
    "option": "mjtraj.core.options",
    "declared_options": "mjtraj.core.options",
    "option_names": "mjtraj.core.options",
    "from_mapping": "mjtraj.core.options",
    "check_options": "mjtraj.core.options",
}
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)

if TYPE_CHECKING:
    from mjtraj.core.adaptive import AdaptiveComputedTorque, parameter_bounds
    from mjtraj.core.closed_loop import RECORDED, ClosedLoop, LoopConfig, Step
    from mjtraj.core.controller import (
        ANTI_WINDUP,
        PID,
        ComputedTorque,
        Controller,
        ControlOutput,
        PIDGains,
        control_law,
    )
    from mjtraj.core.dynamics import DynamicsProbe
    from mjtraj.core.feedforward import FEEDFORWARD_ACCEL, FEEDFORWARD_MODES, feedforward_many
    from mjtraj.core.gains import GAIN_RULE, gain_rule
    from mjtraj.core.laws import CONTROLLERS, controller_names
    from mjtraj.core.linearize import discretize_zoh, linearize_many
    from mjtraj.core.lqr import BoxLQRSolution, box_lqr
    from mjtraj.core.metrics import (
        GOAL_TOLERANCE,
        METRIC_NAMES,
        METRIC_UNITS,
        Metrics,
        gravity_along,
        metrics_arrays,
        missed_goal,
        reduction,
    )
    from mjtraj.core.model import JointInfo, default_model_path, load_model
    from mjtraj.core.mpc import FILTER, disturbance_of
    from mjtraj.core.options import check_options, declared_options, from_mapping, option, option_names
    from mjtraj.core.payload import flange
    from mjtraj.core.planners import Planner, available, check_name, default_names, make, plan_all, register
    from mjtraj.core.plant import GRAVITY_COMP, BatchPlant
    from mjtraj.core.qp import CondensedQP, QPSolution, build_qp, solve_qp
    from mjtraj.core.reference import Reference
    from mjtraj.core.rollout import Rollout
    from mjtraj.core.scoring import JOINT_SPEED_LIMIT, Scoring, bryson_weights, executed_cost, step_cost
    from mjtraj.core.settle import (
        SETTLE_BAND,
        SETTLE_METRICS,
        SETTLE_SPEED,
        SETTLE_UNITS,
        SETTLE_WINDOW,
        Settle,
        held,
        settle_arrays,
        unsettled,
        window_steps,
        with_window,
    )
    from mjtraj.core.stability import spectral_radii
    from mjtraj.core.task import Task, random_task

__all__ = [
    "AdaptiveComputedTorque", "parameter_bounds", "RECORDED", "flange", "FILTER", "disturbance_of",
    "ANTI_WINDUP", "BatchPlant", "BoxLQRSolution", "CONTROLLERS", "ClosedLoop", "ComputedTorque", "CondensedQP",
    "ControlOutput", "Controller", "DynamicsProbe", "FEEDFORWARD_ACCEL", "FEEDFORWARD_MODES", "GAIN_RULE",
    "GOAL_TOLERANCE", "GRAVITY_COMP", "JOINT_SPEED_LIMIT", "JointInfo", "LoopConfig", "METRIC_NAMES", "METRIC_UNITS",
    "Metrics", "missed_goal", "SETTLE_BAND", "SETTLE_METRICS", "SETTLE_SPEED", "SETTLE_UNITS", "SETTLE_WINDOW",
    "Settle", "held", "settle_arrays", "unsettled", "window_steps", "with_window",
    "PID", "PIDGains", "Planner", "QPSolution", "Reference", "Rollout", "Scoring", "Step", "Task", "available",
    "box_lqr", "bryson_weights", "build_qp", "check_name", "check_options", "control_law", "controller_names",
    "declared_options",
    "default_model_path", "default_names", "discretize_zoh", "executed_cost", "feedforward_many", "from_mapping",
    "gain_rule", "gravity_along", "linearize_many", "load_model", "make", "metrics_arrays", "option",
    "option_names", "plan_all", "random_task", "reduction", "register", "solve_qp", "spectral_radii", "step_cost",
]
