"""How a policy's observations are scaled: SB3's running statistics, or fixed physical scales.

`running` (the default) is VecNormalize's: each entry minus its running mean over the training data, over its
running standard deviation. The statistics follow the training distribution, so under plant randomisation the
errors PID leaves on a near-nominal plant (about 1e-3 rad) become noise next to those of a heavy payload.

`fixed` divides each entry by a scale stated once, from the env's settings alone (no data), then clips to
+-clip like VecNormalize:

| entries                                 | divided by            | so that 1 means                               |
|-----------------------------------------|-----------------------|-----------------------------------------------|
| positions q, q_ref, previewed q_ref     | pi rad                | half a turn                                   |
| velocities qd, qd_ref, previewed qd_ref | pi rad/s              | the reward's velocity scale (Bryson, 1/pi^2)  |
| position error e                        | s / kp rad            | PID's proportional torque equals s            |
| velocity error ed                       | s / kd rad/s          | PID's derivative torque equals s              |
| phase k/N                               | 1                     | the end of the motion                         |
| PID integral of e (observe_control)     | s / ki rad s          | PID's integral torque equals s                |
| feedforward torque (observe_control)    | the torque limit, N m | saturation                                    |
| plant parameters (observe_plant)        | 1 (already theta/theta_max) | the parameter's bound                   |

With history, each previous observation is scaled as the current one.

s is the torque of one unit of action (the residual scale, or the saturation in torque mode), per joint. The
errors are thus observed as the torques PID makes of them, in units of the authority the policy has: what the
policy's action competes with, at the same scale on every plant.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mjtraj.envs import TrackSettings
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.policy import Normalization

OBSERVATION_SCALINGS = ("running", "fixed")


def fixed_scales(settings: TrackSettings) -> NDArray[np.float64]:
    """The fixed scale of each observation entry (table above), shape (obs_size,), in the entry's unit.

    Raises:
      InvalidInputError: the controller is not pid, or a PID gain is zero (its error would have no scale).
    """
    loop = settings.loop
    if loop.controller != "pid":
        raise InvalidInputError(f"observation_scaling: fixed scales the errors by the PID gains; expected the pid "
                                f"controller, got {loop.controller!r}")
    gains = {"kp": loop.gains.kp, "kd": loop.gains.kd, "ki": loop.gains.ki}
    for name, gain in gains.items():
        if np.any(gain <= 0):
            raise InvalidInputError(f"observation_scaling: fixed needs positive PID gains; {name} is "
                                    f"{gain.tolist()}")
    n = settings.n
    s = settings.action_scale
    angle, rate = np.full(n, np.pi), np.full(n, np.pi)
    parts = [angle, rate, angle, rate, s / gains["kp"], s / gains["kd"], np.ones(1)]
    parts += [angle, rate] * settings.preview
    if settings.observe_control:
        parts += [s / gains["ki"], settings.torque_limit]
    if settings.observe_plant != "none":  # already over their bounds
        parts += [np.ones(1 + 2 * n)]
    if settings.observe_disturbance:  # already over the saturation
        parts += [np.ones(n)]
    scales = np.tile(np.concatenate(parts).astype(np.float64), 1 + settings.history)
    assert scales.size == settings.obs_size
    return scales


def fixed_normalization(settings: TrackSettings, clip: float) -> Normalization:
    """`fixed_scales` as a Normalization (mean 0, var = scale^2, epsilon 0): clip(obs / scale, -clip, clip)."""
    scales = fixed_scales(settings)
    return Normalization(np.zeros_like(scales), np.square(scales), 0.0, float(clip))
