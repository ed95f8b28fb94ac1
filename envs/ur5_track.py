"""UR5Track-v0: the paper's closed loop (plant, feedforward + PID, saturation) behind the Gymnasium API."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium import spaces
from mjtraj.envs.core import TrackCore
from mjtraj.envs.settings import RENDER_MODES, ArgumentsSignature, TrackSettings, resolve
from numpy.typing import NDArray

from mjtraj.core import ClosedLoop, JointInfo, Task
from mjtraj.exceptions import InvalidInputError
from mjtraj.media import ArmRenderer

RESET_OPTIONS = ("q0", "qg", "duration", "scenario")
"""Keys `reset(options=...)` accepts: one episode of that task (the others keep the env's), or "scenario": one
held-out sweep scenario {"family": F, "seed": S, "index": i} (task, duration and plant; not with the others)."""


def check_reset_options(options: dict[str, Any] | None) -> None:
    """InvalidInputError unless `options` holds only RESET_OPTIONS, and "scenario" alone."""
    if not options:
        return
    unknown = sorted(set(options) - set(RESET_OPTIONS))
    if unknown:
        raise InvalidInputError(f"options: unknown key {unknown[0]!r}; valid: {', '.join(RESET_OPTIONS)}")
    if "scenario" in options and len(options) > 1:
        raise InvalidInputError("options: 'scenario' sets the task, duration and plant; give it alone")
VELOCITY_BOUND = 200.0
"""rad/s, the velocity bounds of the observation space: 60 N m on the lightest joint inertia (0.09 kg m^2) cannot
reach it before the tracking error exceeds pi, which ends the episode."""


def observation_space(settings: TrackSettings) -> spaces.Box:
    """Positions within the joint ranges +- pi, errors within the range widths + pi, velocities within
    +-VELOCITY_BOUND on the UR5 (unbounded on a user's arm), the phase in [0, 1]; float64. Layout in UR5TrackEnv's
    docstring."""
    joints = JointInfo.of(settings.model)
    q_low, q_high = joints.lower - np.pi, joints.upper + np.pi
    e_max = joints.upper - joints.lower + np.pi
    # VELOCITY_BOUND's argument is the UR5's; a user's arm may have light joints that reach any speed: there the
    # velocities have no a-priori bound (half the largest float, so that the velocity errors' 2 v stays finite)
    v = np.full(settings.n, VELOCITY_BOUND if settings.model_path is None else np.finfo(np.float64).max / 2)
    zero, one = np.zeros(1), np.ones(1)
    ahead = ([q_low, -v], [q_high, v]) if settings.preview_frame == "absolute" else ([-e_max, -2 * v], [e_max, 2 * v])
    low = [q_low, -v, q_low, -v, -e_max, -2 * v, zero] + ahead[0] * settings.preview
    high = [q_high, v, q_high, v, e_max, 2 * v, one] + ahead[1] * settings.preview
    if settings.observe_control:  # no a-priori bound: the largest finite float (Gymnasium warns on inf)
        unbounded = np.full(2 * settings.n, np.finfo(np.float64).max)
        low, high = [*low, -unbounded], [*high, unbounded]
    if settings.observe_plant != "none":  # theta / theta_max: >= 0; a user's plant may exceed its bound
        low, high = [*low, np.zeros(1 + 2 * settings.n)], [*high, np.full(1 + 2 * settings.n, np.finfo(np.float64).max)]
    if settings.observe_disturbance:  # the filter's torque over the saturation: no a-priori bound
        unbounded = np.full(settings.n, np.finfo(np.float64).max)
        low, high = [*low, -unbounded], [*high, unbounded]
    if settings.observe_task:  # the move (rad, within the range widths) and the time to the motion's end (s; a
        # reset may ask for any duration)
        low = [*low, np.array([0.0, -settings.settle_steps * settings.dt])]  # as the observation computes it
        high = [*high, np.array([float(np.max(joints.upper - joints.lower)), np.finfo(np.float64).max])]
    one_low, one_high = np.concatenate(low), np.concatenate(high)
    reps = 1 + settings.history
    return spaces.Box(np.tile(one_low, reps), np.tile(one_high, reps), dtype=np.float64)  # type: ignore[arg-type]


def action_space(settings: TrackSettings) -> spaces.Box:
    """[-1, 1]^n, float32."""
    return spaces.Box(-1.0, 1.0, shape=(settings.n,), dtype=np.float32)


class UR5TrackEnv(gym.Env[NDArray[np.float64], NDArray[np.float32]]):
    """Track a planned joint-space reference with a 3-DoF UR5 under the paper's controller.

    ## Description
    Registered as UR5Track-v0 (the defaults below), as the benchmark UR5Track-v2 with its variants
    UR5TrackAggressive-v2, UR5TrackMismatch-v2 and UR5TrackNoisy-v2 (protocol v2: a settle window after each motion,
    success at rest at the goal), and as v1's UR5Track-v1, UR5TrackAggressive-v1 and UR5TrackMismatch-v1, kept for
    earlier results (see Version History). The plant is MuJoCo's model of a UR5
    reduced to shoulder_pan, shoulder_lift and elbow (`assets/ur5_3dof.xml`, RK4, gravity compensated). Each episode
    a planner (cubic, quintic, trapezoidal, optimal or your own) plans a point-to-point move q0 -> qg of `duration`
    seconds; every step is one control period dt, in which the corrective torque dtau = clip(tau_ff + tau_fb [+
    residual], -60, 60) N m is applied on top of G(q): tau_ff from inverse dynamics of the reference, tau_fb from a
    PID on the tracking error. This is `mjtraj compare`'s closed loop (`mjtraj.ClosedLoop`), not a copy of it: in
    `pid` mode with the `paper` task the episode's metrics equal `mjtraj compare`'s for the same planner.

    ## Action Space
    `Box(-1, 1, (3,), float32)`, scaled to N m (`residual_scale` s in residual mode, default 6 N m; the 60 N m
    saturation in torque mode). Values outside [-1, 1] are clipped; a non-finite value raises InvalidInputError.

    | action_mode | the action                                                              |
    |-------------|-------------------------------------------------------------------------|
    | pid         | ignored: the paper's controller alone (feedforward + PID)               |
    | residual    | s a N m added to feedforward + PID before the saturation                |
    | torque      | 60 a N m is the whole corrective torque (gravity compensation stays)    |

    ## Observation Space
    `Box(float64)` of size 19 + 6 preview (+ 6 with observe_control, + 7 with observe_plant, + 3 with
    observe_disturbance, + 2 with observe_task).
    After step k the loop is at period k+1 and the reference sample is that period's. Bounds: `range` is a joint's
    position range (pan and lift +-2 pi, elbow +-pi), `width` its length; velocities are bounded by 200 rad/s, which
    60 N m cannot reach before |e| > pi ends the episode.

    | index          | observation                                        | min           | max          | unit  |
    |----------------|----------------------------------------------------|---------------|--------------|-------|
    | 0-2            | joint positions q                                  | range - pi    | range + pi   | rad   |
    | 3-5            | joint velocities qd                                | -200          | 200          | rad/s |
    | 6-8            | reference positions q_ref,k                        | range - pi    | range + pi   | rad   |
    | 9-11           | reference velocities qd_ref,k                      | -200          | 200          | rad/s |
    | 12-14          | position error e = q_ref,k - q                     | -(width + pi) | width + pi   | rad   |
    | 15-17          | velocity error ed = qd_ref,k - qd                  | -400          | 400          | rad/s |
    | 18             | phase k / N                                        | 0             | 1            | -     |
    | 19+6j .. 21+6j | preview j = 0..preview-1: q_ref,k+1+j (held at N)  | range - pi    | range + pi   | rad   |
    | 22+6j .. 24+6j | preview j: qd_ref,k+1+j (held at N)                | -200          | 200          | rad/s |
    | m .. m+2       | observe_control: the PID integral of e             | -max float    | max float    | rad s |
    | m+3 .. m+5     | observe_control: tau_ff of period k+1 (then N)     | -max float    | max float    | N m   |
    | p .. p+6      | observe_plant: payload, damping_j, friction_j over their bounds theta_max | 0 | max float | - |
    | u .. u+2       | observe_disturbance: mpc's filtered torque d over the saturation | -max float | max float | - |
    | t              | observe_task: the move, max_i abs(qg_i - q0_i)     | 0             | largest range width | rad |
    | t+1            | observe_task: time to the motion's end (N - k) dt  | -settle       | max float    | s     |

    (m = 19 + 6 preview; max float = the largest finite float64: these have no a-priori bound. p = m (+ 6 with
    observe_control); u = p (+ 7 with observe_plant); t = u (+ 3 with observe_disturbance); N the motion's periods
    (without the settle window). observe_disturbance runs `mpc`'s Kalman filter without its plan beside the loop
    (`mpc_filter`, counting the torque the loop applied): d is the estimate `mpc` would plan from at these states,
    corrected by this period's measurement; it needs a settle window (the filter runs in protocol v2's episodes) and,
    as a predictive teacher does, episodes of one length per vector env (the aggressive family's vary: one sub-env per
    vector env, as `mjtraj.rl.batched.MixedFamilies` runs them). With
    preview_frame='relative' each preview sample is given minus the observed q and qd, with 'reference' minus q_ref
    and qd_ref now (bounds as e and ed). With
    observe_measured, q, qd, e and ed are what the control law measures, noisy under measurement_noise (else the
    true state, which a policy then sees and the law does not); theta_max: `mjtraj.core.adaptive.BOUND_RULE`; 'true'
    gives the episode's plant (privileged), 'estimate' the adaptive law's online estimate. observe_control's integral
    is the PID integral the loop keeps: `pid` integrates e into it (its I term, in torque mode too, where it does not
    command); under computed torque, the adaptive law and the predictive laws it stays 0; those laws'
    own states (the adaptive estimate, the predictive laws' filter) are read through `env.unwrapped.loop.law_state()`
    (`observe_plant='estimate'` for the adaptive law's). With `history` h the
    whole observation above, of size d, is followed by the h previous ones (latest first, each of size d; an
    episode's first observation fills them): size d (1 + h).)

    ## Rewards
    r_k = reward_tracking + reward_effort = -(x_k^T Q_exec x_k) - (dtau_k^T R_exec dtau_k), x_k = [e_k; ed_k] the
    error before control in period k. The return of an episode is therefore -J_exec, the executed cost the
    planners are scored on (Q_exec, R_exec diagonal); with a settle window (v2's envs) it is -J_settle, the same
    sum over the motion and the window. By default both follow Bryson's rule for the episode's task,
    as sweeps score every scenario: 1/move^2 on positions (move = the largest joint displacement), 1/pi^2 on
    velocities, 1/60^2 on torques; for the paper task these are the paper scenario's weights.

    With `reward_baseline="controller"` (earlier named "pid", still accepted) the env also runs each episode under
    the configured control law alone (same task, plant and noise, no action) in a shadow loop and subtracts its step
    cost: r_k = -(cost_k - cost_k^law), the advantage over the controller alone. The subtracted term does not depend
    on the actions, so the optimal policy is unchanged; a whole episode returns J_exec^law - J_exec, and
    `info["metrics"]` still holds J_exec.

    ## Starting State
    The arm rests on the reference's first sample (q0, zero velocity), with the integral of the PID at zero.
    `task="paper"`: the paper scenario's move (q0 = (0, -pi/2, 0), qg = q0 + 1 rad). `task="random"`: q0 uniform
    in the joint ranges, qg uniform in the ranges within +-max_displacement of q0, from `reset(seed=...)`'s
    generator. `task="explicit"`: your q0 and qg. `reset(options={"q0": ..., "qg": ..., "duration": ...})` runs one
    episode of that task instead (each key defaults to the env's).

    ## Episode End
    Terminated after N = duration/dt steps (the motion's horizon is part of the state through the phase), or
    earlier when the closed loop diverges (|e| above pi on a joint, or a non-finite state); the episode length
    follows duration and dt (no TimeLimit is registered). At the end `info["metrics"]` holds the episode's Metrics
    (`mjtraj.Metrics` fields; NaN if diverged), `info["diverged"]` says whether it diverged and
    `info["missed_goal"]` whether it ended farther from the goal than the benchmark's goal rule allows (terminal
    error above `mjtraj.core.GOAL_TOLERANCE` of the task's largest joint displacement: a failure in every family,
    whatever the return). Under a time
    limit of your own (`gym.make(..., max_episode_steps=k)`, k < N), which the env itself cannot see, read them at
    the truncation with `env.unwrapped.episode_metrics()`: over the k periods run, J_exec summed over them (minus
    the return), terminal_err at the pose reached. The vector env's own `max_episode_steps` puts them in the
    truncating step's info.
    With `floor=True` the ending step's `info["metrics"]` also holds `floor`, the episode's clairvoyant floor (the
    least score any controller can reach on that task and plant, reaching the goal, or in a v2 env at rest at it),
    and `cost_over_floor`, NaN where the floor fails; its solve time: docs/floor.md.

    ## Plant randomisation
    With `plant_randomization="mismatch"` each episode runs on its own plant, drawn from the reset's generator
    after the task by the rules of the sweeps' mismatch family (`mjtraj.domain.families`): a payload of U(0, 5) kg
    at the flange, each link's mass and inertia scaled by U(0.8, 1.2), joint damping U(0, 1) N m s/rad and
    friction U(0, 3) N m. The planner and the feedforward keep the nominal model, as in the sweeps. On a user's
    arm (`xml_file`) the links are the bodies its joints move and the flange its `attachment_site`, else the last
    link's centre of mass.
    `measurement_noise=sigma` adds noise of std sigma (rad) to the measured q and sqrt(2) sigma / dt to qd, drawn
    per episode after the plant; the controller sees it, the reward and metrics score the true state. Held-out
    evaluation runs the sweep family's own seeded scenarios (`mjtraj rl eval --family mismatch`).

    ## Info
    Every step: tau_ff, tau_fb, dtau (N m, shape (3,)), saturated (bool (3,)), e (rad, (3,)), reward_tracking,
    reward_effort, reward_baseline (the law alone's step cost with a reward baseline, else 0; the reward is
    reward_tracking + reward_effort - reward_baseline). With plant randomisation, reset's info["plant"] describes
    the episode's plant: payload_kg, mass_scale_j, inertia_scale_j, damping_j (N m s/rad), friction_j (N m) for
    joints j = 0..2.

    ## Arguments
    The defaults are UR5Track-v0's (kept as it was for earlier numbers). The benchmark envs differ in these ("-":
    the default):

    | id | action_mode | task | family | settle | observe_measured | observe_task | measurement_noise |
    |---|---|---|---|---|---|---|---|
    | UR5Track-v1 | "residual" | "random" | "nominal" | - | - | - | - |
    | UR5TrackAggressive-v1 | "residual" | "random" | "aggressive" | - | - | - | - |
    | UR5TrackMismatch-v1 | "residual" | "random" | "mismatch" | - | - | - | - |
    | UR5Track-v2 | "residual" | "random" | "nominal" | 0.5 | True | True | - |
    | UR5TrackAggressive-v2 | "residual" | "random" | "aggressive" | 0.5 | True | True | - |
    | UR5TrackMismatch-v2 | "residual" | "random" | "mismatch" | 0.5 | True | True | - |
    | UR5TrackNoisy-v2 | "residual" | "random" | "mismatch" | 0.5 | True | True | 0.001 |

    | argument         | default    | meaning                                                                 |
    |------------------|------------|-------------------------------------------------------------------------|
    | planner          | "cubic"    | registered planner name or an object with plan(task, model)             |
    | xml_file         | None       | an MJCF arm instead of the UR5 (ArmTrack-v0; docs/arms.md)                |
    | torque_limit     | None       | with xml_file: every joint's corrective saturation, N m (None: the model's) |
    | action_mode      | "pid"      | pid, residual or torque                                                 |
    | residual_scale   | 6.0        | s, N m per unit of action in residual mode (> 0)                        |
    | task             | "paper"    | paper, random or explicit                                               |
    | q0               | None       | start, rad (task="explicit")                                            |
    | qg               | None       | goal, rad (task="explicit")                                             |
    | family           | "none"     | none, or nominal, aggressive, mismatch: each episode by its rules  |
    | max_displacement | 1.5        | largest abs(qg - q0) per joint of task="random", rad                    |
    | duration         | 2.0        | T, s (a whole number of dt)                                             |
    | dt               | 0.02       | control period, s                                                       |
    | controller       | "pid"      | pid (feedforward + PID), computed_torque or adaptive_computed_torque    |
    | feedforward      | "inverse"  | inverse, planned or none                                                |
    | ff_accel         | "sample"   | sample or step_average                                                  |
    | gravity_comp     | "native"   | native or zoh                                                           |
    | anti_windup      | "none"     | none or clamp                                                           |
    | adaptation_rate  | 0.0155     | adaptive_computed_torque's adaptation rate, 1/(N m rad)                 |
    | substeps         | 1          | integrator steps per control period                                     |
    | divergence_bound | 3.141592653589793 | abs(e) above this on a joint ends the episode as diverged, rad   |
    | delay            | 0          | actuation delay in control periods (0 or 1)                             |
    | plant_randomization | "none"  | none, or mismatch: each episode's plant drawn by the mismatch rules     |
    | measurement_noise | 0.0       | std of the noise on measured q, rad (sqrt(2) x / dt on qd); per episode |
    | reward_baseline  | "none"     | none, or controller: reward = advantage over the law alone (pid: old name) |
    | floor            | False      | at the episode's end also its clairvoyant floor in info["metrics"] (below) |
    | preview          | 0          | future reference samples in the observation                             |
    | preview_frame    | "absolute" | absolute, relative (minus the observed q, qd), reference (minus q_ref, qd_ref) |
    | observe_control  | False      | append the PID integral and the next feedforward torque (6 values)      |
    | observe_plant    | "none"     | none, true (the plant's parameters: privileged) or estimate (adaptive law's) |
    | observe_disturbance | False   | append mpc's filtered torque disturbance over the saturation (3 values) |
    | observe_task     | False      | append the move (rad) and the time to the motion's end (s)              |
    | observe_measured | False      | observe the measured (noisy) state the law gets, not the true one       |
    | settle           | 0.0        | settle window after the motion, s (protocol v2; info["settled"] at the end) |
    | history          | 0          | previous observations appended, latest first                             |
    | teacher          | "none"     | a control law shadowing the env's own: loop.teach(teacher), for imitation |
    | Q_exec           | None       | diag of Q_exec, 6 weights (None: Bryson's rule for each task)           |
    | R_exec           | None       | diag of R_exec, 3 weights (None: Bryson's rule)                         |
    | render_mode      | None       | None, "rgb_array", "depth_array" or "human" (a window; needs a display) |
    | width            | 640        | image width, px                                                         |
    | height           | 480        | image height, px                                                        |
    | camera           | "front"    | the model's (UR5: front, side, top) or free; front falls back to free  |
    | render_quality   | "fast"     | fast (no shadows or reflection, fewer facets) or high (publication)     |

    The PID gains are the paper scenario's, identical for every planner and task (their rule: `mjtraj gains`).

    ## Version History
    | id | defaults beyond the arguments table | since |
    |----|-------------------------------------|-------|
    | UR5Track-v0 | none: action_mode="pid" (the action is ignored), task="paper" | 0.1.0 |
    | UR5Track-v1 | action_mode="residual" (6 N m), task="random", family="nominal" (docs/benchmark.md) | 0.2.0 |
    | UR5TrackAggressive-v1 | as v1 with family="aggressive" (T uniform in [0.5, 1] s) | 0.2.0 |
    | UR5TrackMismatch-v1 | as v1 with family="mismatch" (a perturbed plant each episode) | 0.2.0 |
    | UR5Track-v2 | as v1 with settle=0.5, observe_measured=True, observe_task=True (protocol v2) | 0.4.0 |
    | UR5TrackAggressive-v2, UR5TrackMismatch-v2 | as v2 with family="aggressive", "mismatch" | 0.4.0 |
    | UR5TrackNoisy-v2 | as UR5TrackMismatch-v2 with measurement_noise=0.001 (protocol v2's noisy family) | 0.4.0 |

    v0 and v1 are kept unchanged for reproducibility (v0's dynamics and residual default changed within 0.1.0 before
    the benchmark was versioned); new work should use v2. In v2 an episode of N motion periods runs N + 25 steps:
    after the motion the reference holds the goal at rest for the 0.5 s settle window, every period scored with the
    same weights (the return is minus J_settle), and the last step's info says whether the arm is at rest at the
    goal (`info["settled"]`: every joint within 2 % of the move and slower than 0.05 rad/s; why not in
    `info["settle_reason"]`); its metrics add cost_position, cost_velocity, cost_torque, cost_motion (J_exec of the
    motion alone), end_err, end_speed and settle_time (`mjtraj.core.settle`). `reset(options={"scenario": {"family":
    F, "seed": S, "index": i}})` replays held-out sweep scenario i of family F under seed S (task, duration, plant),
    bit for bit the episode `mjtraj sweep` and `mjtraj rl eval` score; reset's info carries the task (q0, qg,
    duration) and, on perturbed plants, the plant.
    """

    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 50}
    __signature__ = ArgumentsSignature()
    """What `help()` and `inspect.signature` show: every argument with its default (the Arguments table)."""

    def __init__(self, **kwargs: Any) -> None:
        """Every argument is keyword-only, with the default of the Arguments table (`inspect.signature(UR5TrackEnv)`
        lists them); an unknown one is an InvalidInputError naming the valid ones."""
        self.settings = resolve(**kwargs)
        render_mode = self.settings.render_mode
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.settings.dt)}
        self.observation_space = observation_space(self.settings)  # type: ignore[assignment]
        self.action_space = action_space(self.settings)  # type: ignore[assignment]
        self._core = TrackCore(self.settings, 1)
        self._running = False
        self._renderer: ArmRenderer | None = None
        self._window: Any = None
        """render_mode='human': the window (mjtraj.media.window.HumanViewer), opened at the first frame."""

    @property
    def loop(self) -> ClosedLoop:
        """The ClosedLoop this env runs (read its public queries; do not step it)."""
        return self._core.loop

    @property
    def reference(self) -> Any:
        """The current episode's Reference (None before the first reset)."""
        return self._core.references[0]

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float64], dict[str, Any]]:
        super().reset(seed=seed)
        check_reset_options(options)
        if options and "scenario" in options:
            episode = self._core.replay(self.settings.scenario(options["scenario"]))
        else:
            episode = self._core.plan(self.np_random, self._task_of(options) if options else None)
        obs = self._core.begin([episode])
        self._running = True
        info = self._core.start_info(np.zeros(1, np.intp))
        task = info["task"]
        out: dict[str, Any] = {"task": {"q0": task["q0"][0], "qg": task["qg"][0],
                                        "duration": float(task["duration"][0])}}
        if "plant" in info:
            out["plant"] = {name: float(v[0]) for name, v in info["plant"].items()}
        if self.render_mode == "human":  # a window follows the episode by itself (Gymnasium's convention)
            self.render()
        return obs[0], out

    def _task_of(self, options: dict[str, Any]) -> Task:
        """The task `reset(options=...)` asks for: q0, qg (rad) and duration (s), each defaulting to this env's."""
        s = self.settings
        base = s.fixed_task
        q0 = options.get("q0", None if base is None else base.q0)
        qg = options.get("qg", None if base is None else base.qg)
        if q0 is None or qg is None:
            raise InvalidInputError("options: a random-task env needs both q0 and qg (rad)")
        return Task.create(q0, qg, options.get("duration", s.duration), s.dt, model=s.model)

    @property
    def dt(self) -> float:
        """The control period, s: one step."""
        return self.settings.dt

    def step(self, action: npt.ArrayLike) -> tuple[NDArray[np.float64], float, bool, bool, dict[str, Any]]:
        if not self._running:
            raise InvalidInputError("step: call reset() first (before the first step and after an episode ends)")
        shape = np.shape(action) if isinstance(action, (np.ndarray, list, tuple)) else None
        if shape is not None and len(shape) > 1:  # one env takes one action (n,): a batch of one is the vector env's
            raise InvalidInputError(f"action: expected shape ({self.settings.n},), got {shape}")
        obs, reward, terminated, info = self._core.step(action)
        out = {key: value[0] for key, value in info.items()}
        done = bool(terminated[0])
        if done:
            self._running = False
            out["metrics"] = self.episode_metrics()
            out["diverged"] = bool(self._core.loop.diverged[0])
            out["missed_goal"] = bool(self._core.goal_missed(np.zeros(1, np.intp),
                                                             np.array([out["metrics"]["terminal_err"]]))[0])
            if self._core.settings.settle:
                why = self._core.settled(np.zeros(1, np.intp), {k: np.array([v]) for k, v in out["metrics"].items()})
                out["settled"], out["settle_reason"] = not why[0], why[0]
            if self._core.settings.floor:
                floors = self._core.floors(np.zeros(1, np.intp), np.array([out["metrics"]["cost"]]))
                out["metrics"].update({name: float(value[0]) for name, value in floors.items()})
        if self.render_mode == "human":
            self.render()
        return obs[0], float(reward[0]), done, False, out

    def episode_metrics(self) -> dict[str, float]:
        """The Metrics of the current (or last) episode over the periods run so far: at the end the episode's, and
        after a truncation by a wrapper's time limit (which this env cannot see) those of the k periods run, J_exec
        summed over them (minus the return), terminal_err at the pose reached; NaN if it diverged."""
        if not self._core.loop.started:
            raise InvalidInputError("episode_metrics: call reset() first")
        return {name: float(v[0]) for name, v in self._core.metrics(np.zeros(1, np.intp)).items()}

    def render(self) -> NDArray[np.uint8] | NDArray[np.float32] | None:
        """rgb_array: the executed arm and, translucent, the reference pose it tracks, (height, width, 3) uint8;
        depth_array: the executed arm's depth image, (height, width) float32, m; human: the same scene in a window
        (drawn at every reset and step by itself; returns None; needs a display, see mjtraj.media.window)."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' to gym.make")
            return None
        if not self._core.loop.started:
            raise InvalidInputError("render: call reset() first")
        if self.render_mode == "human":
            if self._window is None:
                from mjtraj.media import HumanViewer

                self._window = HumanViewer(self.settings.model, width=self.settings.width,
                                           height=self.settings.height)
            self._window.show(self._core.loop.positions[0], self._core.reference_pose(0))
            return None
        if self._renderer is None:
            s = self.settings
            self._renderer = ArmRenderer(s.model, width=s.width, height=s.height, camera=s.camera,
                                         quality=s.render_quality)
        if self.render_mode == "depth_array":
            return self._renderer.depth(self._core.loop.positions[0])
        return self._renderer.frame(self._core.loop.positions[0], self._core.reference_pose(0))

    def __getstate__(self) -> dict[str, Any]:
        """Everything but the renderer (an OpenGL context): a copy makes its own at its first render()."""
        state = self.__dict__.copy()
        state["_renderer"] = state["_window"] = None
        return state

    def close(self) -> None:
        renderer = getattr(self, "_renderer", None)  # absent if __init__ refused its arguments
        if renderer is not None:
            renderer.close()
            self._renderer = None
        window = getattr(self, "_window", None)
        if window is not None:
            window.close()
            self._window = None
