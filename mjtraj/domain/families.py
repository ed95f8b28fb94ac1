"""Scenario families of sweeps: seeded random tasks, and for `mismatch` a perturbed plant.

Scenario i of family F under seed s draws everything from `numpy.random.default_rng([s, FAMILY_ID[F], i])`, so a
scenario is the same whichever batch, worker or machine computes it.

Rules (stated once, used by every sweep):
- nominal: start uniform in the joint ranges, goal uniform in the ranges within +-1.5 rad of it per joint
  (`mjtraj.core.task.random_task`), T = 2 s.
- aggressive: the same tasks with T uniform in [0.5, 1.0] s, rounded to the control period.
- mismatch: nominal tasks on a plant that differs from the nominal model (planner and feedforward keep the
  nominal one): a point payload of U(0, 5) kg at the flange (a 5 cm sphere, not gravity compensated); each link's
  mass and rotational inertia scaled by independent U(0.8, 1.2) factors, its gravity compensation still that of
  the nominal mass (body_gravcomp = 1/scale); joint viscous damping U(0, 1) N m s/rad and Coulomb friction
  U(0, 3) N m (2 % of the UR5's rated 150 N m) per joint, added to what the arm's file declares (the UR5's: none).
  The links are the bodies the joints move, one per
  joint; the flange is the site `attachment_site` (the UR5's, and MuJoCo Menagerie's name for a tool flange),
  or on an arm without one the centre of mass of the last joint's body (FLANGE_RULE). On another arm the payload,
  damping and friction ranges scale with it (ARM_SCALE_RULE).
  Optional (sweep settings): measurement noise of std sigma on q and sqrt(2) sigma / dt on qd (the noise of a
  finite-difference velocity), and a one-period actuation delay.
"""

from __future__ import annotations

import functools
import weakref
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from mjtraj.core.arm import arm_spec, compile_arm
from mjtraj.core.model import default_model_path
from mjtraj.core.payload import FLANGE_RULE as FLANGE_RULE
from mjtraj.core.payload import FLANGE_SITE, PAYLOAD_RADIUS
from mjtraj.core.task import Task, random_task
from mjtraj.exceptions import ModelError

FAMILIES = ("nominal", "aggressive", "mismatch")
FAMILY_ID = {"nominal": 0, "aggressive": 1, "mismatch": 2}
MAX_DISPLACEMENT = 1.5
"""rad per joint."""
NOMINAL_DURATION = 2.0
"""s."""
AGGRESSIVE_DURATION = (0.5, 1.0)
"""s, uniform."""
PAYLOAD_MASS = (0.0, 5.0)
"""kg, uniform."""
LINK_SCALE = (0.8, 1.2)
DAMPING = (0.0, 1.0)
"""N m s/rad, uniform per joint."""
FRICTION = (0.0, 3.0)
"""N m, uniform per joint."""
PAYLOAD_BODY = "mjtraj_payload"
"""The payload body's name in the perturbed plant (an arm may not have a body of that name)."""
PERTURBATION_FIELDS = ("mass_scale", "inertia_scale", "damping", "friction")
"""The per-link or per-joint fields of a Perturbation, in column order."""


@dataclass(frozen=True)
class Perturbation:
    """How one mismatch scenario's plant differs from the nominal model. Shapes (n,) per link or joint."""

    payload: float
    """kg at the flange."""
    mass_scale: NDArray[np.float64]
    inertia_scale: NDArray[np.float64]
    damping: NDArray[np.float64]
    """N m s/rad."""
    friction: NDArray[np.float64]
    """N m."""

    def as_dict(self) -> dict[str, float]:
        """Flat columns for a results row."""
        out = {"payload_kg": self.payload}
        for name in PERTURBATION_FIELDS:
            out.update({f"{name}_{j}": float(v) for j, v in enumerate(getattr(self, name))})
        return out


@dataclass(frozen=True)
class FamilyScenario:
    """Scenario `index` of `family`: the task, the plant perturbation (None: the nominal plant), and the rng
    state that draws its measurement noise."""

    family: str
    index: int
    task: Task
    perturbation: Perturbation | None
    noise_seed: int


def draw_scenario(family: str, seed: int, index: int, model: mujoco.MjModel, dt: float, *,
                  stream: int | None = None) -> FamilyScenario:
    """Draw scenario `index` of `family` (see the module rules) from the stream [seed, stream, index]; the family's
    own stream FAMILY_ID[family] unless another is given (tuning draws its training scenarios elsewhere)."""
    rng = np.random.default_rng([seed, FAMILY_ID[family] if stream is None else stream, index])
    task, perturbation = draw_family(rng, family, model, dt)
    return FamilyScenario(family, index, task, perturbation, int(rng.integers(2**63 - 1)))


def draw_family(rng: np.random.Generator, family: str, model: mujoco.MjModel, dt: float
                ) -> tuple[Task, Perturbation | None]:
    """A task and plant (None: nominal) of `family` by the module's rules, drawn from `rng` in a fixed order: the
    duration (aggressive), the task, then the plant (mismatch). Sweeps draw from a scenario's own stream, the env
    (its `family` argument) from the episode's generator."""
    duration = NOMINAL_DURATION
    if family == "aggressive":
        duration = round(rng.uniform(*AGGRESSIVE_DURATION) / dt) * dt
    task = random_task(rng, model, max_displacement=MAX_DISPLACEMENT, duration=duration, dt=dt)
    perturbation = draw_perturbation(rng, model.nv, arm_scales(model, dt)) if family == "mismatch" else None
    return task, perturbation


UR5_TORQUE = 60.0
"""N m: the UR5's corrective saturation, the torque the damping and friction ranges are stated for."""
ARM_SCALE_RULE = ("on another arm the ranges scale with it, never beyond what its own loop overcomes as well as the "
                  "UR5's loop overcomes the UR5's: each joint's damping and friction range by the least of its "
                  "corrective saturation over the UR5's 60 N m and its proportional gain over the UR5's least, both "
                  "gains by the workspace gain rule at the control period (so a joint's friction never stalls it "
                  "further from its reference than the UR5's can stall the UR5); the payload's range by the least of "
                  "the arm's total body mass over the shipped UR5's, the payload it holds still at any workspace pose "
                  "with 80 % of each joint's saturation (HOLD_FRACTION), and its least ratio of proportional gain to "
                  "the holding torque per kg over the UR5's (so the payload's sag, in rad, is at most the UR5's). "
                  "The UR5's own factors are exactly 1 at its 20 ms period: its draws are unchanged")
HOLD_FRACTION = 0.8
"""The share of a joint's corrective saturation that the heaviest payload of the mismatch range may take to hold
still (its weight is not gravity compensated), at the workspace's worst pose (`holding_torque`)."""
UR5_DT = 0.02
"""s: the control period the UR5's reference gains (ARM_SCALE_RULE) are taken at."""


def arm_scales(model: mujoco.MjModel, dt: float = UR5_DT) -> tuple[float, NDArray[np.float64]]:
    """ARM_SCALE_RULE's factors of `model` (a prepared arm) at control period `dt` (s): the payload's, and each
    joint's damping and friction factor, shape (n,)."""
    from mjtraj.core.model import JointInfo

    shipped, mass = _shipped_mass(), float(np.sum(model.body_mass[1:]))
    limits = JointInfo.of(model).torque_limit
    holding = np.maximum(holding_torque(model), 1e-12)
    holdable = HOLD_FRACTION * float(np.min(limits / holding))
    kp = loop_stiffness(model, dt)
    reference = _ur5_reference()
    stiffness = float(np.min(kp / holding)) / reference[1]
    # exactly 1 on the UR5 itself (x / x, and it holds more than its range), so its draws are unchanged
    return (min(mass / shipped, holdable / PAYLOAD_MASS[1], stiffness),
            np.minimum(limits / UR5_TORQUE, kp / reference[0]))


_STIFFNESS: weakref.WeakKeyDictionary[mujoco.MjModel, dict[float, NDArray[np.float64]]] = weakref.WeakKeyDictionary()
"""`loop_stiffness` of each model and period already asked (every scenario draw asks it)."""


def loop_stiffness(model: mujoco.MjModel, dt: float) -> NDArray[np.float64]:
    """Each joint's proportional gain by the workspace gain rule (`mjtraj.core.gains.WORKSPACE_RULE`, around the
    model's qpos0) at control period `dt`, N m/rad, shape (n,); computed once per model and period."""
    from mjtraj.core.gains import gain_rule

    known = _STIFFNESS.setdefault(model, {})
    if dt not in known:
        known[dt] = gain_rule(model, model.qpos0, model.qpos0, dt, workspace=True).kp
    return known[dt]


@functools.cache
def _ur5_reference() -> tuple[float, float]:
    """The shipped UR5's least proportional gain (N m/rad) and least gain over holding torque per kg, at UR5_DT."""
    from mjtraj.core.model import load_model

    ur5 = load_model()
    kp = loop_stiffness(ur5, UR5_DT)
    return float(np.min(kp)), float(np.min(kp / np.maximum(holding_torque(ur5), 1e-12)))


_HOLDING: weakref.WeakKeyDictionary[mujoco.MjModel, NDArray[np.float64]] = weakref.WeakKeyDictionary()
"""`holding_torque` of each model already asked (about 19 ms each; every scenario draw asks it)."""


def holding_torque(model: mujoco.MjModel) -> NDArray[np.float64]:
    """Each joint's largest torque, N m per kg, to hold a point mass at the flange (FLANGE_RULE) still against
    gravity, over the workspace poses the gain rule sizes gains over (`mjtraj.core.gains.workspace_poses`); shape
    (n,); computed once per model."""
    known = _HOLDING.get(model)
    if known is None:
        known = _HOLDING[model] = _holding_torque(model)
    return known


def _holding_torque(model: mujoco.MjModel) -> NDArray[np.float64]:
    from mjtraj.core.gains import workspace_poses
    from mjtraj.core.payload import flange

    body, point = flange(model)
    data = mujoco.MjData(model)
    jacobian = np.zeros((3, model.nv))
    worst = np.zeros(model.nv)
    for q in workspace_poses(model, model.qpos0, model.qpos0):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        world = data.xpos[body] + data.xmat[body].reshape(3, 3) @ point
        mujoco.mj_jac(model, data, jacobian, None, world, body)
        worst = np.maximum(worst, np.abs(jacobian.T @ model.opt.gravity))
    return worst


@functools.cache
def _shipped_mass() -> float:
    """kg: the shipped UR5 model's total body mass."""
    from mjtraj.core.model import load_model

    return float(np.sum(load_model().body_mass[1:]))


def draw_perturbation(rng: np.random.Generator, n: int,
                      scales: tuple[float, NDArray[np.float64]] | None = None) -> Perturbation:
    """A mismatch plant by the module's rules, drawn from `rng` in a fixed order: the payload, then n link mass
    scales, n inertia scales, n dampings and n frictions; `scales` (`arm_scales`) stretch the payload's, the
    dampings' and the frictions' ranges (None: the UR5's)."""
    payload_scale, torque_scale = (1.0, np.ones(n)) if scales is None else scales
    return Perturbation(payload=float(rng.uniform(PAYLOAD_MASS[0], PAYLOAD_MASS[1] * payload_scale)),
                        mass_scale=rng.uniform(*LINK_SCALE, n), inertia_scale=rng.uniform(*LINK_SCALE, n),
                        damping=rng.uniform(DAMPING[0], DAMPING[1] * torque_scale, n),
                        friction=rng.uniform(FRICTION[0], FRICTION[1] * torque_scale, n))


def no_perturbation(n: int) -> Perturbation:
    """The nominal plant as a Perturbation: no payload, unit scales, no added damping or friction."""
    return Perturbation(payload=0.0, mass_scale=np.ones(n), inertia_scale=np.ones(n), damping=np.zeros(n),
                        friction=np.zeros(n))


def noise_scale(n: int, sigma: float, dt: float) -> NDArray[np.float64]:
    """Standard deviations of the measurement noise on [q; qd], shape (2n,): sigma (rad) on q, sqrt(2) sigma / dt
    (rad/s, a finite-difference velocity's) on qd."""
    return np.concatenate([np.full(n, sigma), np.full(n, np.sqrt(2.0) * sigma / dt)])


def measurement_noise(scenarios: list[FamilyScenario], steps: int, n: int, sigma: float, dt: float
                      ) -> NDArray[np.float64]:
    """Noise on [q; qd] for each scenario, shape (N, S, 2n): std sigma (rad) on q, sqrt(2) sigma / dt on qd."""
    out = np.empty((steps, len(scenarios), 2 * n))
    scale = noise_scale(n, sigma, dt)
    for b, s in enumerate(scenarios):
        out[:, b] = np.random.default_rng(s.noise_seed).standard_normal((steps, 2 * n)) * scale
    return out


def perturbed_plant(model: mujoco.MjModel, path: str | None = None,
                    torque_limit: float | tuple[float, ...] | None = None
                    ) -> mujoco.MjModel:
    """The nominal `model` with a payload body (mass set per simulation) welded at the flange (FLANGE_RULE),
    gravcomp 0.

    Args:
      model: the nominal plant (its timestep is kept).
      path, torque_limit: where `model` came from: None for the shipped UR5, else the user's MJCF file and its
        torque limit, as given to `mjtraj.core.model.load_model`.

    Raises:
      ModelError: two joints move one body (the links could not be scaled one per joint).
    """
    if path is None:
        spec = mujoco.MjSpec.from_file(str(default_model_path()))
    else:
        spec = arm_spec(path, torque_limit=torque_limit)
        spec.option.integrator = model.opt.integrator  # the nominal plant's (prepare_arm chose it)
    bodies = model.jnt_bodyid.tolist()
    if len(set(bodies)) != len(bodies):
        shared = next(b for b in bodies if bodies.count(b) > 1)
        name = model.body(shared).name or f"number {shared} (unnamed)"
        raise ModelError(f"model {path}: body {name} is moved by two joints; the mismatch family scales one link "
                         f"per joint, so it runs only on arms with one hinge per body (the other families run)")
    site = next((s for s in spec.sites if s.name == FLANGE_SITE), None)
    if site is not None:
        parent, position = site.parent, site.pos
    else:
        last = model.jnt_bodyid[model.njnt - 1]
        parent, position = spec.body(model.body(last).name), model.body_ipos[last]
    if any(b.name == PAYLOAD_BODY for b in spec.bodies):
        raise ModelError(f"model {path}: a body is named {PAYLOAD_BODY!r}, the name mjtraj gives the mismatch "
                         f"family's payload; rename it")
    body = parent.add_body(name=PAYLOAD_BODY, pos=position, gravcomp=0.0)
    body.explicitinertial = True
    body.mass = 1.0
    body.inertia = [0.4 * PAYLOAD_RADIUS**2] * 3
    body.ipos = [0.0, 0.0, 0.0]  # the centre of mass at the body's origin (MuJoCo would place it at `pos` again)
    body.iquat = [1.0, 0.0, 0.0, 0.0]
    plant = spec.compile() if path is None else compile_arm(spec, path)
    plant.opt.timestep = model.opt.timestep
    return plant


def plant_fields(plant: mujoco.MjModel, perturbations: list[Perturbation]) -> dict[str, NDArray[np.float64]]:
    """Per-simulation model fields of `plant` (from `perturbed_plant`) for `perturbations`, one per simulation: the
    links' masses and inertias scaled, the payload's mass, and the drawn damping and friction added to the joints'
    own."""
    links = plant.jnt_bodyid.tolist()
    payload = plant.body(PAYLOAD_BODY).id
    S = len(perturbations)
    mass = np.tile(plant.body_mass, (S, 1))
    inertia = np.tile(plant.body_inertia, (S, 1, 1))
    comp = np.tile(plant.body_gravcomp, (S, 1))
    damping = np.empty((S, plant.nv))
    friction = np.empty((S, plant.nv))
    for b, p in enumerate(perturbations):
        mass[b, links] *= p.mass_scale
        inertia[b, links] *= p.inertia_scale[:, None]
        comp[b, links] = plant.body_gravcomp[links] / p.mass_scale
        mass[b, payload] = p.payload
        inertia[b, payload] = 0.4 * p.payload * PAYLOAD_RADIUS**2
        comp[b, payload] = 0.0
        # added to the file's own (the UR5 has none: its plants are the draws exactly)
        damping[b], friction[b] = plant.dof_damping + p.damping, plant.dof_frictionloss + p.friction
    return {"body_mass": mass, "body_inertia": inertia, "body_gravcomp": comp, "dof_damping": damping,
            "dof_frictionloss": friction}
