"""The stability check of the linearised closed loop: batched equals one-by-one, sampling is bounded."""

from __future__ import annotations

import numpy as np
import pytest

from mjtraj.core.controller import PIDGains
from mjtraj.core.feedforward import feedforward
from mjtraj.core.gains import mass_matrix
from mjtraj.core.linearize import discretize_zoh, linearize
from mjtraj.core.model import JointInfo
from mjtraj.core.planners import default_names, make
from mjtraj.core.stability import closed_loop_map, sample_indices, spectral_radii
from mjtraj.core.task import Task


def one_by_one(model, gains, references, *, moving):
    """The oracle: every sample linearised on its own (linearize, one expm, one eigvals per sample)."""
    limit = JointInfo.of(model).torque_limit
    worst = 0.0
    for ref in references:
        ff = feedforward(model, ref)
        for k in range(ref.steps):
            A, B = (linearize(model, ref.q[k], ref.qd[k], np.clip(ff[k], -limit, limit)) if moving
                    else linearize(model, ref.q[k]))
            Ad, Bd = discretize_zoh(A, B, ref.dt)
            worst = max(worst, float(np.max(np.abs(np.linalg.eigvals(closed_loop_map(Ad, Bd, gains, ref.dt))))))
    return worst


@pytest.mark.slow
def test_batched_check_equals_the_one_by_one_oracle(model, scenario):
    refs = [scenario.planner(name).plan(scenario.task, model) for name in default_names()]
    radii = spectral_radii(model, scenario.loop.gains, refs)  # on every core's thread
    assert radii["at_rest"] == one_by_one(model, scenario.loop.gains, refs, moving=False)
    assert radii["moving"] == one_by_one(model, scenario.loop.gains, refs, moving=True)
    assert spectral_radii(model, scenario.loop.gains, refs, nthread=1) == radii


def test_default_gains_are_stable_along_every_reference(model, scenario):
    refs = [scenario.planner(name).plan(scenario.task, model) for name in default_names()]
    radii = spectral_radii(model, scenario.loop.gains, refs)
    assert radii["at_rest"] < 1.0
    assert radii["moving"] < 1.0


def test_naive_diagonal_gains_are_unstable(model, scenario):
    """ur5_params.md's pitfall, reproduced: kp = D_ii(q_bar) w^2 at the same bandwidth is unstable at 0.02 s."""
    w = 2 * np.pi / (20 * 0.02)
    inertia = np.diag(mass_matrix(model, (scenario.task.q0 + scenario.task.qg) / 2))
    naive = PIDGains.create(inertia * w**2, inertia * w**3 / 10, 2 * inertia * w, 3)
    refs = [make("cubic").plan(scenario.task, model)]
    assert spectral_radii(model, naive, refs)["at_rest"] > 1.5


def test_scenario_gains_are_stable_over_the_workspace(model, scenario, rng):
    """Random tasks keep the paper scenario's gains: the linearised closed loop at rest is stable at random poses."""
    joints = JointInfo.of(model)
    for q in rng.uniform(joints.lower, joints.upper, size=(100, 3)):
        Ad, Bd = discretize_zoh(*linearize(model, q), scenario.task.dt)
        assert np.max(np.abs(np.linalg.eigvals(closed_loop_map(Ad, Bd, scenario.loop.gains, scenario.task.dt)))) < 1


@pytest.mark.parametrize(("steps", "bound", "expected"), [(5, 200, [0, 1, 2, 3, 4]), (10, 4, [0, 3, 6, 9]),
                                                          (30000, 200, None)])
def test_samples_are_bounded_and_keep_both_ends(steps, bound, expected):
    k = sample_indices(steps, bound)
    assert k.size == min(steps, bound) and k[0] == 0 and k[-1] == steps - 1 and np.all(np.diff(k) > 0)
    if expected is not None:
        assert k.tolist() == expected


def test_a_long_plan_costs_no_more_linearisations(model, scenario):
    """T = 60 s at dt = 0.002 (30,000 periods) is checked at 200 samples per reference, as N = 200 is."""
    fine = Task.create(scenario.task.q0, scenario.task.qg, 60.0, 0.002)
    coarse = Task.create(scenario.task.q0, scenario.task.qg, 0.4, 0.002)
    from mjtraj.core.model import load_model

    fast = load_model(dt=0.002)
    long_ref, short_ref = make("cubic").plan(fine, fast), make("cubic").plan(coarse, fast)
    assert long_ref.steps == 30000 and short_ref.steps == 200
    radii = spectral_radii(fast, scenario.loop.gains, [long_ref])
    assert set(radii) == {"at_rest", "moving"} and all(np.isfinite(v) for v in radii.values())
