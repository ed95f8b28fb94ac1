"""The evaluation pipeline: the same numbers as the closed loop run by hand, outcomes in the order of the jobs
whatever their lengths, and an actor that adds nothing changes nothing."""

from __future__ import annotations

import numpy as np
import pytest
from oracles import same_outcome

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.metrics import METRIC_NAMES, gravity_along, metrics_arrays
from mjtraj.core.planners import make
from mjtraj.core.task import Task
from mjtraj.domain.pipeline import Job, Outcome, execute, execute_batch, plan_failure
from mjtraj.exceptions import InfeasibleError, InvalidInputError, SolverError


def test_a_batch_is_the_loop_run_by_hand(model, scenario):
    refs = [make(name).plan(scenario.task, model) for name in ("cubic", "quintic")]
    weights = (scenario.Q_exec, scenario.R_exec)
    rollout, outcomes = execute_batch(model, scenario.loop, [Job(r, weights) for r in refs], total_torque=True)
    by_hand = ClosedLoop(model, scenario.loop, nsim=2).run(refs)
    np.testing.assert_array_equal(rollout.dtau, by_hand.dtau)
    arrays = metrics_arrays(by_hand, np.tile(scenario.Q_exec, (2, 1)), np.tile(scenario.R_exec, (2, 1)),
                            gravity=gravity_along(model, by_hand))
    for j, outcome in enumerate(outcomes):
        assert outcome.status == "ok" and outcome.reason == ""
        assert outcome.metrics == {m: float(arrays[m][j]) for m in METRIC_NAMES}


def test_jobs_of_several_lengths_keep_their_order(model, scenario):
    tasks = [Task.create(scenario.task.q0, scenario.task.qg, T, 0.02) for T in (2.0, 1.0, 2.0, 0.6)]
    weights = (scenario.Q_exec, scenario.R_exec)
    jobs = [Job(make("cubic").plan(t, model), weights) for t in tasks]
    together = execute(model, scenario.loop, jobs)
    alone = [execute(model, scenario.loop, [job])[0] for job in jobs]
    assert all(same_outcome(a, b) for a, b in zip(together, alone, strict=True))


class Nothing:
    """An actor that adds zero torque."""

    action_mode = "residual"

    def begin(self, loop, references, plants=()):
        self.calls = 0

    def act(self, loop):
        self.calls += 1
        return np.zeros((loop.nsim, 3))


def test_an_actor_adding_nothing_is_the_controller_alone(model, scenario):
    job = Job(make("cubic").plan(scenario.task, model), (scenario.Q_exec, scenario.R_exec))
    actor = Nothing()
    assert same_outcome(execute(model, scenario.loop, [job], actor=actor)[0], execute(model, scenario.loop, [job])[0])
    assert actor.calls == scenario.task.steps


def test_plan_failures_and_bad_jobs(model, scenario):
    assert plan_failure(InfeasibleError("too short")) == Outcome("infeasible", "InfeasibleError: too short")
    assert plan_failure(SolverError("stuck")).status == "solver_error"
    from mjtraj.domain.families import Perturbation

    job = Job(make("cubic").plan(scenario.task, model), (scenario.Q_exec, scenario.R_exec),
              Perturbation(1.0, np.ones(3), np.ones(3), np.zeros(3), np.zeros(3)))
    with pytest.raises(InvalidInputError, match=r"^jobs: perturbed jobs need the perturbed plant model"):
        execute(model, scenario.loop, [job])
