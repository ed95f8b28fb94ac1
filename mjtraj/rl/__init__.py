"""Reinforcement-learning tracking policies on the UR5Track envs (the benchmark: UR5Track-v1 and its variants),
trained and scored like the planners.

Training, SB3 zips and the shipped baselines need the `rl` extra (Stable-Baselines3 on CPU PyTorch), imported only
when a function needs it; scoring a plain callable needs none of it:
- `train`: `train(TrainSettings, out)`, an SB3 agent on the natively vectorised env (`sb3_env`), with its
  learning curve (`curve`);
- `evaluate`: `evaluate(policies, family=...)`, policies and planners on the same held-out sweep scenarios;
- `policy`: a saved policy (the SB3 zip and its mjtraj record) and its deterministic actions;
- `episodes`: whole episodes of a policy on given references, through the env's own engine;
- `streams`: the seed streams that keep training, validation and evaluation scenarios apart.
"""

from __future__ import annotations

ALGORITHMS = ("sac", "ppo", "td3", "recurrent_ppo")
"""SB3's SAC, PPO and TD3, and sb3-contrib's RecurrentPPO (an LSTM policy: memory across an episode)."""
RECURRENT = ("recurrent_ppo",)
ALGORITHM_NAMES = {"sac": "SAC", "ppo": "PPO", "td3": "TD3", "recurrent_ppo": "RecurrentPPO"}
"""How labels name each algorithm."""
ACTION_MODES = ("residual", "torque")
"""The env's action modes a policy can learn in ('pid' has nothing to learn)."""
LAW_LABELS = {"pid": "PID", "computed_torque": "CT", "adaptive_computed_torque": "adaptive CT", "mpc": "MPC",
              "adaptive_mpc": "adaptive MPC"}
"""How tables name a control law (planner+LAW, planner+LAW+residual ...); a plug-in law by its own name."""


def law_label(law: str) -> str:
    """LAW_LABELS' name of the control law `law`."""
    return LAW_LABELS.get(law, law)
