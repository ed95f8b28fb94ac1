"""The S-curve planner, held to ruckig's own guarantees on random tasks: limits held, endpoints exact, duration T;
and its errors."""

from __future__ import annotations

import numpy as np
import pytest

from mjtraj.core.planners import make
from mjtraj.core.planners.scurve import SCurve
from mjtraj.core.task import Task, random_task
from mjtraj.exceptions import InfeasibleError, InvalidInputError


def test_limits_endpoints_and_duration_on_random_tasks(model, rng):
    planner = make("scurve")
    for _ in range(200):
        T = float(rng.choice([0.6, 1.0, 2.0, 3.0]))
        task = random_task(rng, model, max_displacement=1.5, duration=T, dt=0.02)
        try:
            ref = planner.plan(task, model)
        except InfeasibleError:
            assert np.max(np.abs(task.displacement)) / T > 0.4 * np.pi  # only fast moves can be infeasible
            continue
        speed, acceleration, jerk = planner.limits(task)
        dq = task.displacement
        big = int(np.argmax(np.abs(dq)))
        s, sd, sdd = (ref.q[:, big] - task.q0[big]) / dq[big], ref.qd[:, big] / dq[big], ref.qdd[:, big] / dq[big]
        assert s[0] == 0.0 and s[-1] == 1.0 and sd[0] == sd[-1] == 0.0 and sdd[0] == sdd[-1] == 0.0
        np.testing.assert_allclose(ref.q[-1], task.qg, rtol=0, atol=1e-15)
        assert np.all(np.abs(sd) <= speed * (1 + 1e-9)) and np.all(np.abs(sdd) <= acceleration * (1 + 1e-9))
        assert np.all(np.abs(np.diff(sdd)) <= jerk * task.dt * (1 + 1e-9))  # |jerk| <= limit between samples
        assert np.all(np.abs(ref.qd) <= np.pi * (1 + 1e-9))  # the joint speed limit
        assert ref.info["duration"] == pytest.approx(T, rel=1e-9)


def test_all_joints_move_in_step(model, task):
    ref = make("scurve").plan(task, model)
    s = (ref.q - task.q0) / task.displacement
    np.testing.assert_allclose(s, s[:, :1].repeat(3, axis=1), atol=1e-15)


def test_zero_move_is_constant(model):
    task = Task.create([0.1, -1.0, 0.5], [0.1, -1.0, 0.5], 1.0, 0.02)
    ref = make("scurve").plan(task, model)
    assert np.all(ref.q == task.q0) and not ref.qd.any()


def test_errors(model):
    fast = Task.create([0.0, -1.0, 0.0], [3.0, -1.0, 0.0], 0.5, 0.02)
    with pytest.raises(InfeasibleError, match=r"^scurve: the limits need .* s for the move, more than T = 0.5 s "
                                              r"\(joint 0 moves 3 rad at most 3.142 rad/s\)"):
        make("scurve").plan(fast, model)
    with pytest.raises(InvalidInputError, match=r"^jerk_factor: expected a positive number, got 0$"):
        SCurve(jerk_factor=0)
