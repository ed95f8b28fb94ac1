"""`mjtraj bench`: speed measured as ratios within one run (machines are noisy; no absolute targets in tests)."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from mujoco.batch import Batch

from mjtraj.core.closed_loop import ClosedLoop
from mjtraj.core.task import Task
from mjtraj.domain.scenario import Scenario

PLAN_STEPS = (100, 200, 400, 800)
LOOP_SIZES = (1, 64, 1024, 4096)


def _median_time(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def bench_plan(scenario: Scenario, steps: tuple[int, ...] = PLAN_STEPS, *, repeats: int = 51) -> list[dict[str, float]]:
    """Median wall time of the optimal plan (linearise, build, solve) per horizon N, and its ratio to the first.

    The task keeps the scenario's start, goal and dt; T = N dt.
    """
    model = scenario.model
    planner = scenario.planner("optimal")
    rows: list[dict[str, float]] = []
    for N in steps:
        task = Task.create(scenario.task.q0, scenario.task.qg, N * scenario.task.dt, scenario.task.dt, model=model)
        planner.plan(task, model)  # warm-up
        def plan(t: Task = task) -> object:
            return planner.plan(t, model)

        seconds = _median_time(plan, repeats if N <= 200 else max(3, repeats // 5))
        rows.append({"N": N, "median_ms": 1e3 * seconds, "ratio_to_first": 1e3 * seconds / rows[0]["median_ms"]
                     if rows else 1.0})
    return rows


QP_SOLVERS = ("quadprog", "proxsuite", "daqp")
"""Dense QP solvers timed beside mjtraj on the identical QP (the `bench` extra)."""


def _external_solvers(qp: Any) -> dict[str, Callable[[], np.ndarray]]:
    """name -> a call solving the condensed QP `qp` (H, f, A_eq, b_eq, lb, ub) with that solver, for the installed
    ones among QP_SOLVERS."""
    import importlib.util

    H, f, A, b, lb, ub = (np.array(a, dtype=np.float64) for a in (qp.H, qp.f, qp.A_eq, qp.b_eq, qp.lb, qp.ub))
    n = H.shape[0]
    calls: dict[str, Callable[[], np.ndarray]] = {}
    if importlib.util.find_spec("quadprog"):
        import quadprog

        C = np.hstack([A.T, np.eye(n), -np.eye(n)])
        bounds = np.concatenate([b, lb, -ub])
        calls["quadprog"] = lambda: quadprog.solve_qp(H, -f, C, bounds, A.shape[0])[0]
    if importlib.util.find_spec("proxsuite"):
        import proxsuite

        def prox() -> np.ndarray:
            solver = proxsuite.proxqp.dense.QP(n, A.shape[0], n)
            solver.settings.eps_abs = 1e-10
            solver.init(H, f, A, b, np.eye(n), lb, ub)
            solver.solve()
            return np.asarray(solver.results.x)

        calls["proxsuite"] = prox
    if importlib.util.find_spec("daqp"):
        import daqp

        upper = np.concatenate([ub, b])
        lower = np.concatenate([lb, b])
        sense = np.concatenate([np.zeros(n, dtype=np.int32), np.full(b.size, 5, dtype=np.int32)])
        calls["daqp"] = lambda: np.asarray(daqp.solve(H, f, A, upper, lower, sense)[0])
    return calls


def bench_qp(scenario: Scenario, *, repeats: int = 21) -> list[dict[str, Any]]:
    """The optimal planner's QP on the scenario's task, solved by mjtraj's banded-KKT active set (`box_lqr` on A_d,
    B_d: its whole solve) and by each installed solver of QP_SOLVERS on the condensed QP (`build_qp`'s H, f, A_eq,
    b_eq and bounds, built once outside the timing): median seconds and the largest difference of the torques from
    mjtraj's, N m."""
    from mjtraj.core.lqr import box_lqr

    model, task = scenario.model, scenario.task
    planner = scenario.planner("optimal")
    qp, facts = planner.build(task, model)  # type: ignore[attr-defined]
    Q, R = planner.weights(task, facts["bound"])  # type: ignore[attr-defined]
    x0 = np.concatenate([task.q0 - task.qg, np.zeros(task.n)])

    def banded() -> np.ndarray:
        solution = box_lqr(facts["A_d"][None], facts["B_d"][None], Q[None], R[None], x0[None], task.steps,
                           facts["bound"][None])
        return solution.U[0].ravel()

    mine = banded()
    rows = [{"solver": "mjtraj (banded KKT)", "seconds": _median_time(banded, repeats), "max_diff": 0.0}]
    for name, call in _external_solvers(qp).items():
        u = call()
        rows.append({"solver": name, "seconds": _median_time(call, repeats),
                     "max_diff": float(np.max(np.abs(u - mine)))})
    return rows


NEW_PLANNERS = ("scurve", "nonlinear_min_effort", "nonlinear_optimal")
NONLINEAR_SOLVERS = ("sqp", "slsqp")
"""The nonlinear planners' solvers that `bench_new_planners` times side by side ('auto' is the first of them that
converges)."""


def bench_new_planners(scenario: Scenario, *, scenarios: int = 12, repeats: int = 21) -> dict[str, Any]:
    """Time per plan of the fair study's planners on the scenario's task, in one process: the linear optimal plan
    (median of `repeats`), scurve (median of `repeats`) against one closed-loop execution of its plan, and each
    nonlinear planner with each of NONLINEAR_SOLVERS once, after one untimed plan per solver (seconds, iterations,
    objective; a solver that does not converge is reported by its error). Then each nonlinear planner over the
    first `scenarios` nominal scenarios with its default solver and each of NONLINEAR_SOLVERS: per solver the plans
    that failed, the median, 90th percentile and largest seconds per plan, the plans SLSQP made ('auto' turns to it
    when the SQP does not converge), the largest relative objective difference to SLSQP alone's, and the plans worse
    than it by more than 1e-4; over all those plans, the linearisations that were analytic and those differenced (see
    `Shooting.jacobians`)."""
    from mjtraj.core.planners import make
    from mjtraj.core.planners.nonlinear import NonlinearOptimal
    from mjtraj.domain.families import draw_scenario
    from mjtraj.exceptions import MjtrajError

    model, task = scenario.model, scenario.task
    scurve = scenario.planner("scurve")
    reference = scurve.plan(task, model)
    loop = ClosedLoop(model, scenario.loop, nsim=1, nthread=1)

    def execute() -> None:
        loop.start([reference])
        for _ in range(reference.steps):
            loop.step()

    execute()
    linear = make("optimal")
    out: dict[str, Any] = {"linear_s": _median_time(lambda: linear.plan(task, model), repeats),
                           "scurve_s": _median_time(lambda: scurve.plan(task, model), repeats),
                           "loop_s": _median_time(execute, repeats), "steps": task.steps,
                           "threads": Batch(model, 3 * task.n * task.steps, nthread=0).nthread}  # as Shooting's
    for solver in NONLINEAR_SOLVERS:  # untimed: a process's first plans import Pinocchio, DAQP,
        # scipy.optimize and numba, and load (or first compile) the dynamics kernel
        with contextlib.suppress(MjtrajError):  # a failure is reported below, where it is timed
            make(NEW_PLANNERS[1], solver=solver).plan(task, model)
    for name in NEW_PLANNERS[1:]:
        for solver in NONLINEAR_SOLVERS:
            try:
                info = make(name, solver=solver).plan(task, model).info
                out[f"{name} {solver}"] = {key: info[key] for key in ("plan_time", "iterations", "objective")}
            except MjtrajError as e:
                out[f"{name} {solver}"] = {"error": str(e)}
    tasks = [draw_scenario("nominal", 0, i, model, task.dt).task for i in range(scenarios)]
    out["jacobians"] = {"analytic": 0, "differenced": 0}
    for name in NEW_PLANNERS[1:]:
        planner = make(name)
        assert isinstance(planner, NonlinearOptimal)
        default = planner.solver
        runs = {solver: [_plan_or_error(make(name, solver=solver), t, model) for t in tasks]
                for solver in dict.fromkeys((default, *NONLINEAR_SOLVERS))}
        for infos in runs.values():
            for kind in ("analytic", "differenced"):
                out["jacobians"][kind] += sum(info[f"{kind}_jacobians"] for info in infos if info)
        oracle = [info["objective"] if info else np.nan for info in runs["slsqp"]]
        rows = {}
        for solver, infos in runs.items():
            done = [(info, best) for info, best in zip(infos, oracle, strict=True) if info]
            gaps = np.array([(info["objective"] - best) / best for info, best in done])
            times = [info["plan_time"] for info, _ in done]
            rows[solver] = {"failed": len(infos) - len(done), "median_s": float(np.median(times)),
                            "p90_s": float(np.percentile(times, 90)), "max_s": float(np.max(times)),
                            "max_gap": float(np.nanmax(gaps)),
                            "worse": int(np.sum(gaps > 1e-4)),
                            "by_slsqp": sum(info["solver"] == "slsqp" for info, _ in done),
                            "tracked": sum(info["start"] == "tracked" for info, _ in done)}
        out[f"{name} family"] = {"scenarios": scenarios, "default": default, "solvers": rows}
    return out


def bench_tail(scenario: Scenario, tasks: dict[str, int], *, seed: int = 1) -> dict[str, Any]:
    """Each nonlinear planner (default solver) over `tasks` random tasks per family (e.g. {"nominal": 200}) of `seed`,
    on one thread: per task the plan's seconds over the linear optimal plan's of the same task (a task whose linear
    plan is infeasible, as aggressive ones can be, is left out and counted). Returns the multiples' median, 90th
    percentile and largest per planner, the slowest task, and the failures."""
    from mjtraj.core.planners import make
    from mjtraj.domain.families import draw_scenario
    from mjtraj.exceptions import MjtrajError

    model, dt = scenario.model, scenario.task.dt
    drawn = [(family, i, draw_scenario(family, seed, i, model, dt).task)
             for family, count in tasks.items() for i in range(count)]
    linear = make("optimal")
    timed, skipped = [], 0
    for family, i, task in drawn:
        try:
            start = time.perf_counter()
            linear.plan(task, model)
            timed.append((family, i, task, time.perf_counter() - start))
        except MjtrajError:
            skipped += 1
    out: dict[str, Any] = {"tasks": len(timed), "skipped": skipped, "seed": seed}
    for name in NEW_PLANNERS[1:]:
        planner = make(name)
        planner.plan(timed[0][2], model)  # untimed: imports and compiled kernels
        multiples, failed, slowest = [], 0, (0.0, "")
        for family, i, task, base in timed:
            start = time.perf_counter()
            try:
                planner.plan(task, model)
            except MjtrajError:
                failed += 1
                continue
            seconds = time.perf_counter() - start
            multiples.append(seconds / base)
            slowest = max(slowest, (seconds, f"{family} {i}"))
        m = np.array(multiples)
        out[name] = {"median": float(np.median(m)), "p90": float(np.percentile(m, 90)), "max": float(m.max()),
                     "failed": failed, "slowest_s": slowest[0], "slowest": slowest[1]}
    return out


def _plan_or_error(planner: Any, task: Any, model: Any) -> dict[str, Any] | None:
    """The plan's info, or None where planning raised (for the nonlinear SQP alone: it did not converge)."""
    from mjtraj.exceptions import MjtrajError

    try:
        return dict(planner.plan(task, model).info)
    except MjtrajError:
        return None


def bench_loop(scenario: Scenario, sizes: tuple[int, ...] = LOOP_SIZES, *, nthread: int = 0,
               rounds: int = 3) -> list[dict[str, float]]:
    """Closed-loop env-steps/s (ClosedLoop.step over a cubic reference) against raw mujoco.batch stepping of the
    same model with the same batch size and threads. Raw and loop passes of N steps alternate for `rounds`
    rounds after a warm-up pass each; the medians are compared."""
    model = scenario.model
    reference = scenario.planner("cubic").plan(scenario.task, model)
    N = reference.steps
    rows = []
    for B in sizes:
        raw = Batch(model, B, nthread=nthread)
        loop = ClosedLoop(model, scenario.loop, nsim=B, nthread=nthread)
        loop.start([reference] * B)

        def raw_pass(raw: Batch = raw) -> None:
            for _ in range(N):
                raw.step(nstep=scenario.loop.substeps)

        def loop_pass(loop: ClosedLoop = loop, B: int = B) -> None:
            loop.start([reference] * B)
            for _ in range(N):
                loop.step()

        raw_pass()
        loop_pass()
        raw_times, loop_times = [], []
        for _ in range(rounds):
            raw_times.append(_median_time(raw_pass, 1))
            loop_times.append(_median_time(loop_pass, 1))
        raw_rate = B * N / float(np.median(raw_times))
        loop_rate = B * N / float(np.median(loop_times))
        rows.append({"scenarios": B, "raw_steps_per_s": raw_rate, "loop_steps_per_s": loop_rate,
                     "ratio": loop_rate / raw_rate})
    return rows


def bench_env(*, episodes: int = 20, rounds: int = 5) -> dict[str, float]:
    """UR5Track-v0 `env.step` rate in pid mode through gym.make (default wrappers) against two raw mj_step loops on
    the same model: the arm at rest (keyframe 0, no torque), and the same motion as the env's (its last episode's
    start state and torques, replayed: a moving arm costs MuJoCo a little more). The step loops of whole episodes
    are timed (reset excluded); raw and env passes alternate."""
    import gymnasium as gym
    import mujoco

    env = gym.make("UR5Track-v0")
    env.reset(seed=0)
    unwrapped: Any = env.unwrapped
    model = unwrapped.settings.model
    data = mujoco.MjData(model)
    steps = unwrapped.settings.steps
    action = env.action_space.sample()

    def env_pass() -> float:
        total = 0.0
        for _ in range(episodes):
            env.reset()
            start = time.perf_counter()
            for _ in range(steps):
                env.step(action)
            total += time.perf_counter() - start
        return total

    def raw_pass() -> float:
        mujoco.mj_resetDataKeyframe(model, data, 0)
        start = time.perf_counter()
        for _ in range(episodes * steps):
            mujoco.mj_step(model, data)
        return time.perf_counter() - start

    raw_pass(), env_pass()
    played = unwrapped.loop.rollout()
    q0, qd0, torques = played.q[0, 0], played.qd[0, 0], played.dtau[0]

    def replay_pass() -> float:
        total = 0.0
        ctrl = data.ctrl
        for _ in range(episodes):
            mujoco.mj_resetData(model, data)
            data.qpos[:], data.qvel[:] = q0, qd0
            start = time.perf_counter()
            for torque in torques:
                ctrl[:] = torque
                mujoco.mj_step(model, data)
            total += time.perf_counter() - start
        return total

    raw, replayed, stepped = [], [], []
    for _ in range(rounds):
        raw.append(raw_pass())
        replayed.append(replay_pass())
        stepped.append(env_pass())
    env.close()
    raw_rate = episodes * steps / float(np.median(raw))
    replay_rate = episodes * steps / float(np.median(replayed))
    env_rate = episodes * steps / float(np.median(stepped))
    return {"raw_steps_per_s": raw_rate, "replay_steps_per_s": replay_rate, "env_steps_per_s": env_rate,
            "ratio": env_rate / raw_rate, "ratio_replay": env_rate / replay_rate}


def bench_vector_env(sizes: tuple[int, ...] = (64, 1024), *, rounds: int = 3) -> list[dict[str, float]]:
    """Vector env steps/s (all sub-envs, autoresets included) against raw mujoco.batch stepping of as many
    simulations, at rest and replaying the env's own motions (its last episodes' start states and torques);
    passes of one episode alternating."""
    import gymnasium as gym

    rows = []
    for B in sizes:
        env = gym.make_vec("UR5Track-v0", num_envs=B, vectorization_mode="vector_entry_point")
        env.reset(seed=0)
        unwrapped: Any = env.unwrapped
        model = unwrapped.settings.model
        steps = unwrapped.settings.steps
        raw = Batch(model, B)
        actions = np.zeros((B, model.nu), dtype=np.float32)

        def env_pass(env: Any = env, steps: int = steps, actions: np.ndarray = actions) -> None:
            for _ in range(steps + 1):  # + the autoreset step
                env.step(actions)

        def raw_pass(raw: Batch = raw, steps: int = steps) -> None:
            for _ in range(steps + 1):
                raw.step()

        for _ in range(steps):  # one episode; its records are kept until the next step's autoreset
            env.step(actions)
        played = unwrapped.loop.rollout()
        env_pass()
        raw_pass()
        q0, qd0 = played.q[:, 0].copy(), played.qd[:, 0].copy()
        torques = np.ascontiguousarray(played.dtau.swapaxes(0, 1))  # (N, B, n)
        replay = Batch(model, B)
        qpos, qvel, ctrl = replay.bind("qpos"), replay.bind("qvel"), replay.bind("ctrl")

        def replay_pass(replay: Batch = replay, torques: np.ndarray = torques, q0: np.ndarray = q0,
                        qd0: np.ndarray = qd0, qpos: np.ndarray = qpos, qvel: np.ndarray = qvel,
                        ctrl: np.ndarray = ctrl) -> None:
            replay.reset()
            qpos[:], qvel[:] = q0, qd0
            for torque in (*torques, torques[-1]):  # as many steps as the env pass
                ctrl[:] = torque
                replay.step()

        replay_pass()
        env_times, raw_times, replay_times = [], [], []
        for _ in range(rounds):
            raw_times.append(_median_time(raw_pass, 1))
            replay_times.append(_median_time(replay_pass, 1))
            env_times.append(_median_time(env_pass, 1))
        env.close()
        raw_rate = B * (steps + 1) / float(np.median(raw_times))
        replay_rate = B * (steps + 1) / float(np.median(replay_times))
        env_rate = B * (steps + 1) / float(np.median(env_times))
        rows.append({"envs": B, "raw_steps_per_s": raw_rate, "replay_steps_per_s": replay_rate,
                     "env_steps_per_s": env_rate, "ratio": env_rate / raw_rate, "ratio_replay": env_rate / replay_rate})
    return rows


def bench_render(sizes: tuple[tuple[int, int], ...] = ((320, 240), (640, 480)), *, frames: int = 20,
                 rounds: int = 3) -> list[dict[str, object]]:
    """env.render() frames per second at each (width, height) on the GL backend in force: UR5Track-v0 at each
    render quality and Gymnasium's Reacher-v5, measured in alternating rounds of the same run (best round of
    each); `ratio` is fast UR5Track-v0 over Reacher-v5 (nan when Gymnasium's MuJoCo envs are missing)."""
    import gymnasium as gym

    from mjtraj.media.gl import active_backend
    from mjtraj.media.render import RENDER_QUALITIES

    rows: list[dict[str, object]] = []
    for width, height in sizes:
        envs = {quality: gym.make("UR5Track-v0", render_mode="rgb_array", width=width, height=height,
                                  render_quality=quality) for quality in RENDER_QUALITIES}
        try:
            envs["Reacher-v5"] = gym.make("Reacher-v5", render_mode="rgb_array", width=width, height=height)
        except Exception:  # noqa: BLE001 - gymnasium[mujoco] is optional; the row says so
            pass
        best = dict.fromkeys(envs, 0.0)
        for env in envs.values():
            env.reset(seed=0)
            env.render()  # opens the context
        for _ in range(rounds):
            for name, env in envs.items():
                start = time.perf_counter()
                for _ in range(frames):
                    env.step(env.action_space.sample())
                    env.render()
                best[name] = max(best[name], frames / (time.perf_counter() - start))
        for env in envs.values():
            env.close()
        reacher = best.get("Reacher-v5", float("nan"))
        rows.append({"size": f"{width}x{height}", "backend": active_backend(), "fast_fps": best["fast"],
                     "high_fps": best["high"], "reacher_fps": reacher, "ratio": best["fast"] / reacher,
                     "high_ratio": best["high"] / reacher})
    return rows


def bench_sweep(scenarios: int = 10_000, *, workers: int | None = None) -> dict[str, object]:
    """A nominal sweep of `scenarios` x the four paper planners into a temporary file: wall time, rows, the CPU
    seconds per stage (sample, plan, execute, metrics) summed over the workers and the driver's peak resident memory
    (this process's, MB; the workers are other processes unless `workers` is 1); then the floor, raw mujoco.batch
    stepping of as many control periods on as many threads as workers."""
    import os
    import resource
    import tempfile

    from mjtraj.study.runner import run_sweep
    from mjtraj.study.sweep import SweepSettings

    settings = SweepSettings(families=("nominal",), scenarios=scenarios)
    count = workers if workers is not None else os.cpu_count() or 1
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        report = run_sweep(settings, os.path.join(folder, "sweep.sqlite"), workers=workers, progress=False)
        wall = time.perf_counter() - start
    driver_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    periods = report.rows * settings.base.task.steps
    batch = Batch(settings.base.model, FLOOR_BATCH, nthread=count)
    start = time.perf_counter()
    for _ in range(-(-periods // FLOOR_BATCH)):
        batch.step(nstep=settings.base.loop.substeps)
    floor = time.perf_counter() - start
    return {"wall": wall, "rows": report.rows, "stages": report.seconds, "workers": count, "periods": periods,
            "floor": floor, "driver_mb": driver_mb}


FLOOR_BATCH = 4096
"""Simulations per raw mujoco.batch step when timing the sweep's floor."""


def bench_startup(*, repeats: int = 5) -> dict[str, float]:
    """Wall time of `mjtraj compare` on the paper scenario (no figures), imports included, against
    `python -c "import mujoco, gymnasium, scipy"` (the target's anchor) and against the same with `scipy.linalg`
    (which compare needs: the discretisation's matrix exponential and the banded LU), each in a fresh interpreter;
    medians of `repeats` runs."""
    import subprocess
    import sys
    import tempfile

    def wall(command: list[str]) -> float:
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            times.append(time.perf_counter() - start)
        return float(np.median(times))

    imports = wall([sys.executable, "-c", "import mujoco, gymnasium, scipy"])
    linalg = wall([sys.executable, "-c", "import mujoco, gymnasium, scipy.linalg"])
    with tempfile.TemporaryDirectory() as folder:
        compare = wall([sys.executable, "-m", "mjtraj", "compare", "--no-figures", "--out", folder])
    return {"imports_s": imports, "linalg_s": linalg, "compare_s": compare, "ratio": compare / imports,
            "ratio_linalg": compare / linalg}


STORE_BATCH = 250
"""Scenarios per unit of the synthetic store (the sweeps' default batch)."""


def synthetic_store(path: str, rows: int) -> int:
    """Write a complete nominal sweep store of about `rows` rows (4 planners x ceil(rows / 4) scenarios) at `path`
    without simulating: every scenario carries the rows of one real scenario (computed once), its own scenario
    number and unit, the real schema and settings. Returns the rows written."""
    from mjtraj.study.sweep import SweepSettings, columns, fixed_columns, run_unit
    from mjtraj.study.sweep_store import SweepStore

    scenarios = max(1, -(-rows // 4))
    settings = SweepSettings(families=("nominal",), scenarios=scenarios, batch=STORE_BATCH)
    template = run_unit(SweepSettings(families=("nominal",), scenarios=1, batch=1), ("nominal", 0)).rows
    fixed = fixed_columns(settings)
    units = settings.units()
    store = SweepStore.open(path, columns(settings), fixed, {u: settings.unit_rows(u) for u in units}, resume=False)
    written = 0
    try:
        for _, unit in units:
            first = unit * STORE_BATCH
            batch = [{**row, **fixed, "scenario": i, "unit": unit} for i in
                     range(first, min(first + STORE_BATCH, scenarios)) for row in template]
            store.append(batch)
            written += len(batch)
    finally:
        store.close()
    return written


def _peak_child(target: Callable[[], object]) -> tuple[float, float]:
    """(wall s, peak resident memory MB) of `target` run alone in a fresh process (fork). The memory is that of
    the process and every process it starts (an export's workers), summed: sampled every TREE_SAMPLE_S where
    Linux's /proc lists a process's children, never below the process's own peak."""
    import multiprocessing
    import resource
    import threading

    def run(pipe: Any) -> None:
        start = time.perf_counter()
        target()
        pipe.send((time.perf_counter() - start, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024))

    context = multiprocessing.get_context("fork")
    parent, child = context.Pipe()
    process = context.Process(target=run, args=(child,))
    process.start()
    assert process.pid is not None
    sampled = [0.0]
    done = threading.Event()

    def sample(pid: int = process.pid) -> None:
        while not done.wait(TREE_SAMPLE_S):
            sampled[0] = max(sampled[0], _tree_rss_mb(pid))

    watcher = threading.Thread(target=sample, daemon=True)
    watcher.start()
    wall, peak = parent.recv()
    done.set()
    watcher.join()
    process.join()
    return float(wall), max(float(peak), sampled[0])


TREE_SAMPLE_S = 0.05
"""How often `_peak_child` sums the resident memory of a process and its descendants."""


def _tree_rss_mb(pid: int) -> float:
    """The resident memory (MB) of process `pid` and its descendants now, from /proc (0 where it is not there)."""
    total, todo = 0.0, [pid]
    while todo:
        now = todo.pop()
        try:
            with open(f"/proc/{now}/status") as f:
                total += next((int(line.split()[1]) for line in f if line.startswith("VmRSS:")), 0) / 1024
            with open(f"/proc/{now}/task/{now}/children") as f:
                todo.extend(int(child) for child in f.read().split())
        except (OSError, ValueError):
            continue
    return total


STORE_STAGES = ("export .csv", "export .jsonl", "export .sqlite", "audit --no-tasks")
"""What `bench_store` can time on its synthetic store."""


def bench_store(rows: int = 100_000, timed: Sequence[str] = STORE_STAGES) -> dict[str, Any]:
    """A synthetic store of `rows` rows (`synthetic_store`), then those of STORE_STAGES in `timed` (`mjtraj export`
    to CSV, JSON Lines and SQLite, `mjtraj audit --no-tasks`), each in a fresh process: wall time, rows/s, peak resident
    memory and bytes per row. Returns {"rows", "write_s", "stages": name -> {"wall_s", "peak_mb"}}."""
    import os
    import tempfile

    from mjtraj.study.audit import write_audit
    from mjtraj.study.export import export

    with tempfile.TemporaryDirectory() as folder:
        store = os.path.join(folder, "synthetic.sqlite")
        start = time.perf_counter()
        written = synthetic_store(store, rows)
        write_s = time.perf_counter() - start
        stages = {}
        for name, target in (("export .csv", lambda: export(store, os.path.join(folder, "out.csv"))),
                             ("export .jsonl", lambda: export(store, os.path.join(folder, "out.jsonl"))),
                             ("export .sqlite", lambda: export(store, os.path.join(folder, "out.sqlite"))),
                             ("audit --no-tasks", lambda: write_audit([store], os.path.join(folder, "AUDIT.md"),
                                                                      figures=False, tasks=False))):
            if name not in timed:
                continue
            wall, peak = _peak_child(target)
            stages[name] = {"wall_s": wall, "peak_mb": peak}
    return {"rows": written, "write_s": write_s, "stages": stages}


def bench_floor(scenario: Scenario, *, scenarios: int = 20, mismatch: int = 20, seed: int = 1) -> list[dict[str, Any]]:
    """The floor's solve time per scenario (`mjtraj.domain.floor.floor_of`, one core) on `scenarios` nominal and
    aggressive scenarios and `mismatch` mismatch ones of `seed`: median, 90th percentile and worst, s."""
    from mjtraj.study.floor import family_floors

    rows = []
    for family, count in (("nominal", scenarios), ("aggressive", scenarios), ("mismatch", mismatch)):
        if count <= 0:
            continue
        seconds = [r["seconds"] for r in family_floors(scenario, family, seed=seed, scenarios=range(count))
                   if r["status"] == "ok"]
        rows.append({"family": family, "scenarios": count, "floored": len(seconds),
                     "median_s": float(np.median(seconds)) if seconds else float("nan"),
                     "p90_s": float(np.percentile(seconds, 90)) if seconds else float("nan"),
                     "max_s": float(np.max(seconds)) if seconds else float("nan")})
    return rows


def bench_predictive(scenario: Scenario, *, scenarios: int = 3, seed: int = 1,
                     laws: Sequence[str] = ("mpc", "adaptive_mpc"), periods: Sequence[float] = (0.02, 0.01)
                     ) -> list[dict[str, Any]]:
    """The predictive laws' time per control period on protocol v2's episodes (cubic references followed by the
    0.5 s settle window, one simulation, one core): per law, control period and family (`scenarios` of each of
    `seed`), the median, 99th percentile and worst of one `ClosedLoop.step` (the law's solve and the plant's step),
    ms, and the worst over the period; and the DAQP solve's own median and worst, ms (the rest of a period is the
    QP's condensing and the plant). The 20 ms rows run the shipped scenario; the others the UR5 prepared at that
    period (`scenario_for_model`, its gains by the workspace rule)."""
    import mjtraj.core.planners.sqp as sqp

    solves: list[float] = []
    real_qp = sqp._qp

    def timed_qp(*args: Any, **kwargs: Any) -> Any:
        clock = time.perf_counter()
        try:
            return real_qp(*args, **kwargs)
        finally:
            solves.append(time.perf_counter() - clock)

    sqp._qp = timed_qp  # type: ignore[assignment]  # the QP's share of each period (restored below)
    try:
        return _predictive_rows(scenario, scenarios, seed, laws, periods, solves)
    finally:
        sqp._qp = real_qp  # type: ignore[assignment]


def _predictive_rows(scenario: Scenario, scenarios: int, seed: int, laws: Sequence[str], periods: Sequence[float],
                     solves: list[float]) -> list[dict[str, Any]]:
    """`bench_predictive`'s rows; `solves` collects every QP's time as the laws run."""
    import dataclasses

    from mjtraj.core import SETTLE_WINDOW, default_model_path, held, window_steps
    from mjtraj.domain.families import FAMILIES, draw_scenario, perturbed_plant, plant_fields
    from mjtraj.domain.scenario import scenario_for_model

    rows = []
    for dt in periods:
        base = scenario if abs(dt - scenario.task.dt) < 1e-12 else scenario_for_model(default_model_path(), dt=dt,
                                                                                      workspace=True)
        model = base.model
        plant = perturbed_plant(model, base.model_path, base.model_torque_limit)
        for law in laws:
            config = dataclasses.replace(base.loop, controller=law)
            for family in FAMILIES:
                times = []
                solves.clear()
                for i in range(scenarios):
                    drawn = draw_scenario(family, seed, i, model, dt)
                    reference = held(base.planner("cubic").plan(drawn.task, model), window_steps(SETTLE_WINDOW, dt),
                                     drawn.task.qg)
                    perturbation = drawn.perturbation
                    loop = (ClosedLoop(model, config, plant=plant, plant_fields=plant_fields(plant, [perturbation]))
                            if perturbation is not None else ClosedLoop(model, config))
                    loop.start([reference])
                    for _ in range(loop.steps):
                        clock = time.perf_counter()
                        loop.step()
                        times.append(time.perf_counter() - clock)
                ms = 1e3 * np.array(times)
                rows.append({"law": law, "period_ms": 1e3 * dt, "family": family, "median_ms": float(np.median(ms)),
                             "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(ms.max()),
                             "worst_of_period": float(ms.max()) / (1e3 * dt),
                             "qp_median_ms": 1e3 * float(np.median(solves)), "qp_max_ms": 1e3 * float(np.max(solves))})
    return rows


def bench_labels(*, laws: Sequence[str] = ("mpc", "adaptive_mpc"), num_envs: int = 16, steps: int = 100,
                 seed: int = 0) -> list[dict[str, Any]]:
    """How fast the predictive laws label states as teachers (`ClosedLoop.teach`, what `mjtraj rl distill` asks at
    every step): a native vector env of `num_envs` mismatch sub-envs under the adaptive law with the teacher beside
    it (protocol v2's episodes, training streams), `steps` steps each after one untimed step, one core; the teacher's
    labels per second and the same env's steps per second without a teacher, in one run."""
    from mjtraj.envs import UR5TrackVectorEnv
    from mjtraj.rl.streams import TRAIN_STREAM, stream_seed
    from mjtraj.threads import one_blas_thread

    kwargs: dict[str, Any] = {"action_mode": "residual", "controller": "adaptive_computed_torque", "task": "random",
                              "family": "mismatch", "settle": 0.5, "observe_measured": True}
    seeds: list[int | None] = [stream_seed(seed, TRAIN_STREAM, i) for i in range(num_envs)]
    zero = np.zeros((num_envs, 3))

    def rate(teacher: str | None) -> float:
        env = UR5TrackVectorEnv(num_envs, autoreset_mode="SameStep", **kwargs, teacher=teacher or "none")
        env.reset(seed=seeds)
        env.step(zero)
        with one_blas_thread():
            start = time.perf_counter()
            for _ in range(steps):
                if teacher:
                    env.loop.teach(teacher)
                env.step(zero)
            return num_envs * steps / (time.perf_counter() - start)

    alone = rate(None)
    return [{"law": law, "envs": num_envs, "labels_per_s": (labels := rate(law)), "env_steps_per_s": alone,
             "minutes_1M": 1e6 / labels / 60} for law in laws]


def bench_controllers(scenario: Scenario, *, scenarios: int = 5, seed: int = 1,
                      laws: Sequence[str] = ("pid", "adaptive_computed_torque", "mpc", "adaptive_mpc")
                      ) -> list[dict[str, Any]]:
    """Each control law's time per control period on one simulation (one `ClosedLoop.step`: the law and the plant's
    step), over `scenarios` mismatch scenarios of `seed`: median and 90th percentile, ms, and the median as a fraction
    of the control period."""
    import dataclasses

    from mjtraj.domain.families import draw_scenario, perturbed_plant, plant_fields

    model = scenario.model
    plant = perturbed_plant(model, scenario.model_path, scenario.model_torque_limit)
    drawn = [draw_scenario("mismatch", seed, i, model, scenario.task.dt) for i in range(scenarios)]
    references = [scenario.planner("cubic").plan(d.task, model) for d in drawn]
    rows = []
    for law in laws:
        config = dataclasses.replace(scenario.loop, controller=law)
        times = []
        for d, reference in zip(drawn, references, strict=True):
            assert d.perturbation is not None
            loop = ClosedLoop(model, config, plant=plant, plant_fields=plant_fields(plant, [d.perturbation]))
            loop.start([reference])
            for _ in range(loop.steps):
                clock = time.perf_counter()
                loop.step()
                times.append(time.perf_counter() - clock)
        median = float(np.median(times))
        rows.append({"law": law, "median_ms": 1e3 * median, "p90_ms": 1e3 * float(np.percentile(times, 90)),
                     "of_period": median / scenario.task.dt})
    return rows


TRAIN_MIXES = (("nominal", "aggressive", "mismatch"), ("nominal", "mismatch"))
"""The family mixtures `bench_train` times: the default one, and the one without the aggressive family, whose
episodes of several lengths make the batch leave the closed loop's fast path (mjtraj.rl.batched.VARIABLE_LENGTH)."""


def bench_train(*, num_envs: int = 512, iterations: int = 2) -> list[dict[str, Any]]:
    """Env steps per second of batched training (mjtraj.rl.batched: skrl's PPO, every step's act, record and each
    rollout's update) against the same sub-envs stepped alone with zero actions, in one run, per TRAIN_MIXES; after
    one untimed iteration each. `minutes_10M` is what 10,000,000 steps take at the training rate."""
    import tempfile
    from pathlib import Path

    from mjtraj.rl.batched import MixedFamilies, interact, new_agent
    from mjtraj.rl.batched_policy import BatchedSettings

    rows = []
    for families in TRAIN_MIXES:
        settings = BatchedSettings(num_envs=num_envs, families=families)
        env = MixedFamilies(settings)
        with tempfile.TemporaryDirectory() as folder:
            agent = new_agent(settings, env, Path(folder))
            total = (iterations + 1) * settings.rollouts
            obs = env.reset()
            for t in range(settings.rollouts):  # untimed: the first rollout and update
                obs = interact(agent, env, obs, t, total)
            start = time.perf_counter()
            for t in range(settings.rollouts, total):
                obs = interact(agent, env, obs, t, total)
            train = (total - settings.rollouts) * num_envs / (time.perf_counter() - start)
        zero = np.zeros((num_envs, 3))
        env.reset()
        start = time.perf_counter()
        for _ in range(iterations * settings.rollouts):
            env.step(zero)
        alone = iterations * settings.rollouts * num_envs / (time.perf_counter() - start)
        rows.append({"families": "+".join(families), "envs": num_envs, "train_steps_per_s": train,
                     "env_steps_per_s": alone, "ratio": train / alone, "minutes_10M": 1e7 / train / 60})
    return rows
