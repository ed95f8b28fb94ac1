"""The control laws by name: the built-in ones (PID, computed torque, adaptive computed torque, model-predictive and
adaptive model-predictive) and plug-ins' (entry points `mjtraj.controllers`), and the factory the closed loop calls."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mjtraj.core.adaptive import AdaptiveComputedTorque
from mjtraj.core.controller import PID, ComputedTorque, Controller

CONTROLLERS = ("pid", "computed_torque", "adaptive_computed_torque", "mpc", "adaptive_mpc")
"""The built-in control laws (`LoopConfig.controller`); plug-ins add others (`controller_names`)."""


def _pid(config: Any, dt: float, n: int, nsim: int, model: Any) -> Controller:
    return PID(config.gains.tiled(nsim), config.anti_windup)


def _computed_torque(config: Any, dt: float, n: int, nsim: int, model: Any) -> Controller:
    return ComputedTorque.for_period(dt, n)


def _adaptive(config: Any, dt: float, n: int, nsim: int, model: Any) -> Controller:
    return AdaptiveComputedTorque(model, dt, nsim, config.adaptation_rate)


def _mpc(config: Any, dt: float, n: int, nsim: int, model: Any) -> Controller:
    from mjtraj.core.mpc import ModelPredictive

    return ModelPredictive(model, dt, nsim)


def _adaptive_mpc(config: Any, dt: float, n: int, nsim: int, model: Any) -> Controller:
    from mjtraj.core.mpc import AdaptiveModelPredictive

    return AdaptiveModelPredictive(model, dt, nsim, rate=config.adaptation_rate)


def _mpc_filter(config: Any, dt: float, n: int, nsim: int, model: Any) -> Controller:
    from mjtraj.core.mpc import PredictiveFilter

    return PredictiveFilter(model, dt, nsim)


_BUILT_IN: dict[str, Callable[..., Controller]] = {"pid": _pid, "computed_torque": _computed_torque,
                                                   "adaptive_computed_torque": _adaptive, "mpc": _mpc,
                                                   "adaptive_mpc": _adaptive_mpc}

ESTIMATORS: dict[str, Callable[..., Controller]] = {"mpc_filter": _mpc_filter}
"""Laws that only estimate (`mjtraj.core.mpc.PredictiveFilter`: `mpc`'s filter without its plan): a loop runs them
in its shadow (`ClosedLoop(teachers=...)`) for a policy to observe; they are not control laws of the study
(`controller_names` leaves them out)."""


def _factories() -> dict[str, Callable[..., Controller]]:
    """Built-in laws and those of installed plug-ins (entry points `mjtraj.controllers`, see `mjtraj.plugins`).

    Raises:
      PluginError: a plug-in cannot be loaded, is not callable, or takes a built-in law's name.
    """
    from mjtraj.exceptions import PluginError
    from mjtraj.plugins import CONTROLLERS as GROUP
    from mjtraj.plugins import plugins

    out = dict(_BUILT_IN)
    for name, factory in plugins(GROUP).items():
        if name in out or name in ESTIMATORS:
            raise PluginError(f"plug-in controller {name!r}: the name of a built-in control law or estimator")
        if not callable(factory):
            raise PluginError(f"plug-in controller {name!r}: expected a factory(config, dt, n, nsim), got "
                              f"{factory!r}")
        out[name] = factory
    return out


def controller_names() -> tuple[str, ...]:
    """The control laws a loop accepts: the built-in ones, then plug-ins'."""
    return tuple(_factories())


def make_controller(config: Any, dt: float, n: int, nsim: int, model: Any = None) -> Controller:
    """The control law `config.controller` (a LoopConfig) for `nsim` simulations of n joints at period dt (s) of
    the nominal `model` (a built-in law may read it; plug-ins' factories get the first four arguments).

    Raises:
      PluginError: a plug-in's factory failed (its message) or did not return a Controller.
    """
    factory = _factories()[config.controller]
    if config.controller in _BUILT_IN:
        return factory(config, dt, n, nsim, model)
    from mjtraj.exceptions import PluginError

    try:
        law = factory(config, dt, n, nsim)
    except Exception as e:  # noqa: BLE001 - foreign code: one line, named
        raise PluginError(f"plug-in controller {config.controller!r}: {type(e).__name__}: {e}") from e
    if not callable(law) or not hasattr(law, "needs_dynamics"):
        raise PluginError(f"plug-in controller {config.controller!r}: its factory returned {law!r}, not a "
                          f"Controller (callable, with needs_dynamics)")
    return law
