"""Imitation (`mjtraj.rl.distill`): the labels make the loop apply the teacher's command (the oracle: the teacher's
own answer); a student distilled on one move closes most of the gap from its law to its teacher there; a
distillation interrupted and resumed is the uninterrupted one, bit for bit."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
import torch

import mjtraj.rl.distill as distill_module
from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.distill import DistillSettings, distill, labels, resume_distill

SMALL = DistillSettings(teacher="computed_torque", controller="pid", families=("nominal", "mismatch"), num_envs=4,
                        rounds=2, steps=30, epochs=3, hidden=(16, 16), preview=2, validation=2)


@pytest.mark.parametrize("mode", ["residual", "torque"])
def test_acting_on_the_labels_makes_the_loop_apply_the_teachers_command(mode):
    """A PID env with a computed-torque teacher, stepped with the labels as its actions (a residual on PID, or the
    whole torque): every period the loop applies what the teacher answered (to rounding: the label divides and the
    loop multiplies by the scale)."""
    import dataclasses

    from mjtraj.envs import UR5TrackVectorEnv

    env = UR5TrackVectorEnv(3, **dataclasses.replace(SMALL, action_mode=mode).env_kwargs("mismatch"))
    env.reset(seed=[11, 12, 13])
    for _ in range(60):
        k = env.loop.periods.copy()
        wanted = env.loop.teach("computed_torque").dtau.copy()
        env.step(labels(env, "computed_torque", "pid", SMALL.residual_scale))
        applied = env.loop.rollout().dtau[np.arange(3), k]
        np.testing.assert_allclose(applied, wanted, rtol=0, atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("recipe", [{}, {"mixing": 0.5, "decay": True, "rounds": 3, "balance": "family-hold",
                                        "families": ("aggressive", "nominal"), "steps": 80, "output": "cubic",
                                        "action_noise": 0.5, "change_weight": 2.0}],
                         ids=["plain", "mixed"])
def test_a_resumed_distillation_is_the_uninterrupted_one_bit_for_bit(tmp_path, monkeypatch, recipe):
    """Interrupted in its second round's training and resumed: the same policy and losses, bit for bit (with DAgger's
    mixing and the action noise, whose draws come from the saved generator, the annealed learning rate, the change
    term and the weights by family and phase, whose phases are saved with the data, too)."""
    import dataclasses

    settings = dataclasses.replace(SMALL, **recipe)
    whole = distill(settings, tmp_path / "whole", progress=False)
    train = distill_module._train
    calls = {"n": 0}

    def interrupted(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return train(*args, **kwargs)

    monkeypatch.setattr(distill_module, "_train", interrupted)
    with pytest.raises(KeyboardInterrupt):
        distill(settings, tmp_path / "cut", progress=False)
    monkeypatch.setattr(distill_module, "_train", train)
    saved = torch.load(tmp_path / "cut" / "resume.pt", weights_only=False)
    if settings.balance == "family-hold":  # the aggressive motions reached their windows: both phases weighed
        assert set(np.concatenate(saved["hold"]).tolist()) == {False, True}
    else:  # a resume point from before the phases were kept resumes too
        del saved["hold"]
        torch.save(saved, tmp_path / "cut" / "resume.pt")
    resumed = resume_distill(tmp_path / "cut", progress=False)
    for name in ("policy.pt", "best.pt"):
        a = torch.load(whole.out / name, weights_only=True)["state"]
        b = torch.load(resumed.out / name, weights_only=True)["state"]
        assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    drop = ("collect_s", "train_s")  # wall-clock
    assert [{k: v for k, v in r.items() if k not in drop} for r in whole.rounds] == [
        {k: v for k, v in r.items() if k not in drop} for r in resumed.rounds]
    assert whole.best_point["round"] == resumed.best_point["round"]
    with pytest.raises(InvalidInputError, match=r"holds a run already"):
        distill(settings, tmp_path / "whole", progress=False)


@pytest.mark.parametrize(("round_", "noise_on", "sigma"), [(0, "all", 2.0), (1, "all", 2.0), (1, "teacher", 2.0),
                                                            (0, "all", 150.0)])
def test_the_action_noise_is_a_gaussian_torque_over_the_action_scale(round_, noise_on, sigma):
    """Collected with action_noise: every applied action is the one collected without it (the label in round 0; after,
    the label where mixing lets the teacher act, else the student's) plus a draw of the run's generator, N m over the
    envs' scale (only on the teacher's actions with noise_on teacher), clipped, drawn in the order the oracle redraws
    them (150 N m: some actions clipped); the labels are the teacher's at the states the noisy actions lead to. The
    residual's scale is not the saturation, so a noise over the wrong scale shows."""
    import torch

    from mjtraj.rl.batched_policy import batched_policy_class

    settings = dataclasses.replace(SMALL, action_mode="torque", action_noise=sigma, steps=12, mixing=0.5,
                                   noise_on=noise_on, residual_scale=6.0)
    env = distill_module._Families(settings)
    torch.manual_seed(0)
    module = batched_policy_class()(env.reset(0).shape[1], env.actions, settings.policy_settings())
    module.clip.fill_(10.0)
    module.std.fill_(1.0)
    applied, seen = [], []
    step = env.step

    def spy(action):
        applied.append(action.copy())
        with torch.no_grad():
            seen.append((env.labels(), module(torch.as_tensor(obs_now[0], dtype=torch.float32)).numpy()))
        obs_now[0] = step(action)
        return obs_now[0]

    obs_now = [env.reset(round_)]
    env.reset = lambda r: obs_now[0]  # type: ignore[method-assign]
    env.step = spy  # type: ignore[method-assign]
    x, y, _ = distill_module._collect(env, module, settings, np.random.default_rng(5), round_)
    oracle = np.random.default_rng(5)
    scale = np.full(3, 60.0)  # the UR5's saturation: torque mode's N m per unit
    np.testing.assert_array_equal(env.action_scale, scale)
    noisy, beyond = [], []
    for k, (action, (label, student)) in enumerate(zip(applied, seen, strict=True)):
        teacher = np.full(len(label), True) if round_ == 0 else oracle.random(len(label)) < 0.5
        clean = np.where(teacher[:, None], label, student.astype(np.float64))
        noise = oracle.normal(0.0, sigma, clean.shape) / scale
        unclipped = clean + (noise * teacher[:, None] if noise_on == "teacher" else noise)
        beyond.append(np.abs(unclipped) > 1.0)
        np.testing.assert_array_equal(action, np.clip(unclipped, -1.0, 1.0))
        np.testing.assert_array_equal(y[k * settings.num_envs:(k + 1) * settings.num_envs], label)
        noisy.append(np.any(action != clean, axis=1))
        if noise_on == "teacher":
            np.testing.assert_array_equal(action[~teacher], clean[~teacher])
    assert np.concatenate(noisy).any()
    assert np.concatenate(beyond).any() or sigma < 60  # at 150 N m the clip is exercised


def test_a_resume_point_from_before_the_noise_settings_resumes_with_their_defaults_alone(tmp_path):
    """A resume point whose record predates action_noise and noise_on meant no noise: resuming it without noise is
    accepted, with noise refused (the settings it lacks are their defaults, not the resuming command's)."""
    settings = dataclasses.replace(SMALL, rounds=1, validation=0)
    distill(settings, tmp_path, progress=False)
    saved = torch.load(tmp_path / "resume.pt", weights_only=False)
    for name in ("action_noise", "noise_on"):
        del saved["record"]["distill"][name]
    torch.save(saved, tmp_path / "resume.pt")
    for noisy in (dataclasses.replace(settings, action_noise=1.0),
                  dataclasses.replace(settings, action_noise=1.0, noise_on="teacher")):
        with pytest.raises(InvalidInputError, match=r"^out: .* holds a distillation with other settings; give another "
                                                    r"folder$"):
            distill(noisy, tmp_path, progress=False, resume=True)
    assert distill(settings, tmp_path, progress=False, resume=True).rounds[0]["round"] == 0


def test_balanced_weights_make_each_family_count_at_its_own_scale():
    """Two rounds of three steps on four sub-envs (two per family), one family's labels a hundred times the other's:
    with balance "family" each family's weighted mean squared label is the same and the weights average 1 (the
    oracle: the definition, computed by hand per family); without balance every weight is 1."""
    settings = DistillSettings(teacher="computed_torque", controller="pid", families=("nominal", "aggressive"),
                               num_envs=4, balance="family")
    rng = np.random.default_rng(2)
    envs = np.array([0, 0, 1, 1])
    y = rng.normal(size=(2 * 3 * 4, 3)) * np.where(np.tile(envs, 6) == 0, 0.01, 1.0)[:, None]
    w = distill_module.sample_weights(y, settings)
    family = np.tile(envs, 6)
    weighted = [np.mean(w[family == g, None] * y[family == g] ** 2) for g in (0, 1)]
    assert weighted[0] == pytest.approx(weighted[1], rel=1e-12) and w.mean() == pytest.approx(1.0, rel=1e-12)
    assert w[family == 0][0] / w[family == 1][0] == pytest.approx(np.mean(y[family == 1] ** 2)
                                                                  / np.mean(y[family == 0] ** 2), rel=1e-12)
    assert np.all(distill_module.sample_weights(y, SMALL) == 1.0)


def test_weights_by_family_and_phase_make_each_group_count_at_its_own_scale():
    """balance "family-hold": the motion's and the settle window's states of each family are weighed apart, each
    group's weighted mean squared label the same, the weights averaging 1 (the oracle: the definition by hand); a
    group with no states takes no part; without the phases it is refused by name."""
    settings = DistillSettings(teacher="computed_torque", controller="pid", families=("nominal", "aggressive"),
                               num_envs=4, balance="family-hold")
    rng = np.random.default_rng(3)
    family = np.tile(np.array([0, 0, 1, 1]), 6)
    holding = np.repeat(np.arange(6) >= 3, 4)  # the last three steps of the rounds' sub-envs hold
    holding[family == 0] = False  # the nominal sub-envs never reach their window: an empty group amid the others
    size = np.where(family == 1, np.where(holding, 1e-2, 0.1), 1.0)
    y = rng.normal(size=(24, 3)) * size[:, None]
    w = distill_module.sample_weights(y, settings, holding)
    groups = [(family == f) & (holding == h) for f, h in ((0, False), (1, False), (1, True))]
    weighted = [np.mean(w[g, None] * y[g] ** 2) for g in groups]
    assert weighted == pytest.approx([weighted[0]] * 3, rel=1e-12) and w.mean() == pytest.approx(1.0, rel=1e-12)
    for g in groups:
        assert np.ptp(w[g]) == 0.0
    with pytest.raises(InvalidInputError, match=r"^holding: family-hold needs each labelled state's phase, expected "
                                                r"24, got None$"):
        distill_module.sample_weights(y, settings)


def test_holding_marks_the_settle_window():
    """The vector env's `holding`, read before each step as the distillation reads it: each episode steps exactly
    the window's periods (0.5 s: 25) while holding, its last ones, and no other; False everywhere without a
    window."""
    from mjtraj.envs import UR5TrackVectorEnv

    env = UR5TrackVectorEnv(2, task="random", family="aggressive", settle=0.5)
    env.reset(seed=[5, 6])
    phases: list[list[bool]] = [[], []]
    ended = np.zeros(2, dtype=bool)
    while not ended.all():
        holding = env.holding.copy()
        _, _, terminated, truncated, _ = env.step(np.zeros((2, 3)))
        for i in np.flatnonzero(~ended):
            phases[i].append(bool(holding[i]))
        ended |= terminated | truncated
    for phase in phases:
        assert len(phase) > 25 and phase[-25:] == [True] * 25 and not any(phase[:-25])
    plain = UR5TrackVectorEnv(2, task="random", family="aggressive")
    plain.reset(seed=[5, 6])
    for _ in range(120):
        assert not plain.holding.any()
        plain.step(np.zeros((2, 3)))


def test_a_states_successor_is_its_sub_envs_next_period_in_the_same_episode():
    """`successors` over two rounds as the distillation gathers them: row t B + i is followed by (t + 1) B + i
    exactly where sub-env i's step t did not end its episode and was not its round's last (the oracle: the vector
    env's own terminated and truncated flags); every other row by none."""
    settings = dataclasses.replace(SMALL, num_envs=4, steps=130, teacher="pid")
    env = distill_module._Families(settings)
    rows, wanted = [], []
    for round_ in range(2):
        obs = env.reset(round_)
        for t in range(settings.steps):
            rows.append(obs.copy())
            obs, _, terminated, truncated = env.mixed.step(env.labels())
            ended = terminated | truncated
            base = (round_ * settings.steps + t) * settings.num_envs
            wanted += [-1 if ended[i] or t == settings.steps - 1 else base + settings.num_envs + i
                       for i in range(settings.num_envs)]
    following = distill_module.successors(np.concatenate(rows), settings, 6 * 3)
    np.testing.assert_array_equal(following, wanted)
    assert 4 <= np.sum(following < 0) - 2 * settings.num_envs  # episodes did end within the rounds


def test_the_change_term_is_the_error_of_the_networks_change_against_the_labels():
    """With change_weight c, a batch B's loss is mean over B of w (f - y)^2 plus c times the sum over B's rows with a
    successor of w (f(next) - f - (y(next) - y))^2, over |B| n; the epoch's loss is the batches' mean (the oracle:
    the formula in float64 over the module's own outputs, the batches drawn as `_train` draws them, the steps made
    negligible); without the term, or with c = 0, the first alone. The first step's gradient is the formula's
    through both outputs (autograd over a copy of the network, in float64)."""
    import copy

    from mjtraj.rl.batched_policy import batched_policy_class

    rng = np.random.default_rng(3)
    x, y, w = rng.normal(size=(12, 5)), rng.uniform(-0.5, 0.5, size=(12, 3)), rng.uniform(0.5, 2.0, size=12)
    following = np.array([1, 2, -1, 4, 5, -1, 7, 8, 9, -1, 11, -1])
    normal = (x - x.mean(axis=0)) / (x.std(axis=0) + 1e-8)
    for weight in (0.0, 2.5):
        settings = dataclasses.replace(SMALL, epochs=1, batch=5, change_weight=weight, learning_rate=1e-12)
        module = batched_policy_class()(5, 3, settings.policy_settings())
        module.clip.fill_(10.0)  # as `distill` sets them
        module.epsilon.fill_(1e-8)
        net = copy.deepcopy(module.net).double()
        optimiser = torch.optim.Adam(module.net.parameters(), lr=settings.learning_rate)
        gradients: list[list[torch.Tensor]] = []
        real_step = optimiser.step

        def step(*args, _real=real_step, _net=module.net, _seen=gradients, **kwargs):
            if not _seen:
                _seen.append([p.grad.detach().clone() for p in _net.parameters()])
            return _real(*args, **kwargs)

        optimiser.step = step  # type: ignore[method-assign]
        loss = distill_module._train(module, optimiser, x, y, w, settings, np.random.default_rng(0), following)
        order = np.random.default_rng(0).permutation(12)  # `_train`'s first draw: epoch 0's order
        f = net(torch.as_tensor(normal))
        yt, wt = torch.as_tensor(y), torch.as_tensor(w)[:, None]
        losses = []
        for k in range(0, 12, 5):
            pick = order[k:k + 5]
            first = pick[following[pick] >= 0]
            second = torch.as_tensor(following[first])
            change = (f[second] - f[first]) - (yt[second] - yt[first])
            losses.append(torch.mean(wt[pick] * (f[pick] - yt[pick]) ** 2)
                          + weight * torch.sum(wt[first] * change**2) / (len(pick) * 3))
        assert loss == pytest.approx(float(torch.stack(losses).mean().detach()), rel=1e-5)
        wanted = torch.autograd.grad(losses[0], list(net.parameters()))
        for got, expected in zip(gradients[0], wanted, strict=True):
            np.testing.assert_allclose(got.numpy(), expected.numpy(), rtol=1e-4, atol=1e-7)
        if weight:  # the term counts
            plain = [torch.mean(wt[order[k:k + 5]] * (f[order[k:k + 5]] - yt[order[k:k + 5]]) ** 2)
                     for k in range(0, 12, 5)]
            assert loss > float(torch.stack(plain).mean().detach()) * (1 + 1e-3)


def test_a_distillation_with_a_change_weight_trains_on_each_rounds_successors(tmp_path, monkeypatch):
    """`distill` hands `_train` the rows' successors (`successors` of the round's states, the phase column 6n) with
    a change_weight, and none without."""
    seen: list[object] = []
    train = distill_module._train

    def spy(module, optimiser, x, y, w, settings, rng, following=None, bound=None):
        seen.append(following)
        return train(module, optimiser, x, y, w, settings, rng, following, bound)

    monkeypatch.setattr(distill_module, "_train", spy)
    states: list[np.ndarray] = []
    real = distill_module.successors
    monkeypatch.setattr(distill_module, "successors",
                        lambda x, settings, phase: (states.append((x.copy(), phase)), real(x, settings, phase))[1])
    for weight in (0.0, 1.0):
        seen.clear()
        settings = dataclasses.replace(SMALL, rounds=1, validation=0, change_weight=weight)
        distill(settings, tmp_path / f"weight_{weight:g}", progress=False)
        if not weight:
            assert seen == [None]
            continue
        (x, phase), = states
        assert phase == 18
        np.testing.assert_array_equal(seen[0], real(x, settings, 18))
        assert np.sum(seen[0] >= 0) > len(x) // 2


def test_the_families_of_the_sub_envs_are_the_ones_the_weights_assume():
    """`families_of_envs` (what `sample_weights` groups by) is the family of each sub-env in the order the
    distillation collects them (`_Families`), also where a previewing teacher splits the aggressive family into
    sub-envs of their own."""
    for teacher, families in (("computed_torque", ("nominal", "mismatch")),
                              ("mpc", ("nominal", "aggressive", "mismatch"))):
        settings = DistillSettings(teacher=teacher, families=families, num_envs=5, hidden=(8,), preview=2)
        collected = distill_module._Families(settings).mixed.envs
        order = [env.settings.family for env in collected for _ in range(env.num_envs)]
        assert order == [families[g] for g in settings.families_of_envs()]


def test_a_student_declares_what_it_observes_and_the_env_gives_it():
    """A student that observes the task, the relative preview, the PID integral and the adaptive law's estimate: its
    deployable module declares them (what `rl eval` builds its env from), and that env's observation is the size
    the student was trained on."""
    from mjtraj.envs import resolve

    from mjtraj.rl.batched_policy import batched_policy_class

    settings = DistillSettings(teacher="computed_torque", families=("nominal",), num_envs=2, hidden=(8,), preview=3,
                               preview_frame="relative", observe_task=True, observe_control=True,
                               observe_plant="estimate", history=1)
    trained = resolve(**settings.env_kwargs("nominal")).obs_size
    module = batched_policy_class()(trained, 3, settings.policy_settings())
    declared = ("observe_task", "observe_control", "observe_plant", "history", "preview", "preview_frame")
    assert {k: module.env[k] for k in declared} == {"observe_task": True, "observe_control": True,
                                                    "observe_plant": "estimate", "history": 1, "preview": 3,
                                                    "preview_frame": "relative"}
    assert resolve(**module.env).obs_size == trained == (6 * 3 + 1 + 6 * 3 + 6 + 7 + 2) * 2


def test_settings_are_refused_by_name():
    with pytest.raises(InvalidInputError, match=r"^teacher: "):
        DistillSettings(teacher="oracle")
    with pytest.raises(InvalidInputError, match=r"^num_envs: expected at least one sub-env per family \(3\), got 2$"):
        DistillSettings(num_envs=2)
    with pytest.raises(InvalidInputError, match=r"^balance: "):
        DistillSettings(balance="equal")
    with pytest.raises(InvalidInputError, match=r"^balance: family-hold weighs the settle window apart and needs one "
                                                r"\(settle > 0\), got settle=0\.0$"):
        DistillSettings(balance="family-hold", settle=0.0)
    with pytest.raises(InvalidInputError, match=r"^mixing: expected a probability in \[0, 1\), got 1.0$"):
        DistillSettings(mixing=1.0)
    for bad in (-0.5, float("nan"), float("inf"), "1", True):
        with pytest.raises(InvalidInputError, match=r"^action_noise: expected a finite standard deviation >= 0, N m, "
                                                    rf"got {re.escape(repr(bad))}$"):
            DistillSettings(action_noise=bad)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match=r"^noise_on: unknown value 'student'; valid: all, teacher$"):
        DistillSettings(noise_on="student", action_noise=1.0)
    with pytest.raises(InvalidInputError, match=r"^noise_on: teacher chooses where action_noise goes and needs some; "
                                                r"expected action_noise > 0, got 0.0$"):
        DistillSettings(noise_on="teacher")
    for bad in (-1.0, float("nan"), float("inf"), "1", True):
        with pytest.raises(InvalidInputError, match=rf"^change_weight: expected a finite weight >= 0, got "
                                                    rf"{re.escape(repr(bad))}$"):
            DistillSettings(change_weight=bad)  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match=r"^observe_plant: "):
        DistillSettings(observe_plant="true")
    with pytest.raises(InvalidInputError, match=r"^observe_plant: a torque policy cannot observe"):
        DistillSettings(action_mode="torque", observe_plant="estimate")
    with pytest.raises(InvalidInputError, match=r"^preview_frame: unknown value 'ahead'; valid: absolute, relative, "
                                                r"reference$"):
        DistillSettings(preview_frame="ahead")
    with pytest.raises(InvalidInputError, match=r"^validation: expected a number of tasks >= 0, got -1$"):
        DistillSettings(validation=-1)
    with pytest.raises(InvalidInputError, match=r"^output: unknown value 'square'; valid: linear, cubic$"):
        DistillSettings(output="square")
    with pytest.raises(InvalidInputError, match=r"^hidden: expected layer widths >= 1 \(none: a linear network\), "
                                                r"got \(8, 0\)$"):
        DistillSettings(hidden=(8, 0))
    with pytest.raises(InvalidInputError, match=r"^structure: unknown value 'bilinear'; valid: none, gain, "
                                                r"gain_beyond, gain_full$"):
        DistillSettings(structure="bilinear")
    with pytest.raises(InvalidInputError, match=r"^structure: gain reads the measured state through e and ed alone; "
                                                r"expected output linear, features none, history 0 and a preview "
                                                r"frame absolute or reference, got output 'cubic', history 1, "
                                                r"preview_frame 'relative'$"):
        DistillSettings(structure="gain", output="cubic", history=1, preview_frame="relative")
    with pytest.raises(InvalidInputError, match=r"^structure: gain_beyond reads the measured state through e and ed "
                                                r"alone; .*, got features 'error_over_move'$"):
        DistillSettings(structure="gain_beyond", features="error_over_move", observe_task=True,
                        preview_frame="reference")


@pytest.mark.slow
def test_a_student_distilled_from_mpc_on_one_move_closes_most_of_the_gap_to_it(tmp_path):
    """Where the student is scored on the motion it was trained on (the paper's move, every episode), it must
    reproduce its teacher: a residual on PID distilled from `mpc` (behaviour cloning, one DAgger round) closes at
    least 70 % of the J_settle that `mpc` gains over PID (measured: 88 %; 83 % before the teacher counted the
    applied command), and the arm comes to rest. The oracles are the two laws' own executions of the same move."""
    from mjtraj.envs import UR5TrackEnv

    from mjtraj.rl.batched_policy import load_batched

    settings = DistillSettings(teacher="mpc", controller="pid", families=("nominal",), num_envs=2, rounds=2,
                               steps=125, epochs=2000, hidden=(64, 64), preview=10, residual_scale=6.0, task="paper")
    module = load_batched(distill(settings, tmp_path / "run", progress=False).policy)

    def score(controller: str, student: bool) -> tuple[float, bool]:
        kwargs = {**settings.env_kwargs("nominal"), "controller": controller, "teacher": "none"}
        env = UR5TrackEnv(**kwargs)
        obs, _ = env.reset(seed=0)
        total, done = 0.0, False
        while not done:
            action = (module(torch.as_tensor(obs[None], dtype=torch.float32)).detach().numpy()[0] if student
                      else np.zeros(3))
            obs, reward, terminated, truncated, info = env.step(action)
            total, done = total + reward, terminated or truncated
        return -total, bool(info["settled"])

    (pid, _), (mpc, _), (mine, settled) = score("pid", False), score("mpc", False), score("pid", True)
    assert settled and (pid - mine) / (pid - mpc) >= 0.7, (pid, mpc, mine)


@pytest.mark.slow
def test_a_linear_student_distilled_from_pid_recovers_the_law(tmp_path):
    """PID's whole command (the feedforward, then Kp e + Kd ed + Ki times the integral) is a linear function of an
    observation that holds e, ed, the loop's integral and the period's feedforward: a student with no hidden layer,
    cloned from it and trained on one DAgger round of its own states, must command what PID commands. The oracle is
    PID's own answer (`labels`) at every state of held-out sub-envs driven by the student: within 1 % of the
    labels' size (measured: 0.4 %; without the annealed learning rate Adam's noise floor left 160 %)."""
    from mjtraj.envs import UR5TrackVectorEnv

    from mjtraj.rl.batched_policy import load_batched

    settings = DistillSettings(teacher="pid", controller="pid", action_mode="torque", observe_control=True,
                               families=("nominal",), num_envs=4, rounds=2, steps=200, epochs=500, batch=256,
                               learning_rate=1e-2, decay=True, hidden=(), preview=0)
    module = load_batched(distill(settings, tmp_path / "run", progress=False).policy)
    assert [type(layer).__name__ for layer in module.net] == ["Linear"]
    env = UR5TrackVectorEnv(3, **settings.env_kwargs("nominal"))
    obs, _ = env.reset(seed=[101, 102, 103])
    errors, wanted = [], []
    for _ in range(150):
        label = labels(env, "pid", "pid", settings.residual_scale)
        action = module(torch.as_tensor(obs, dtype=torch.float32)).detach().numpy().astype(np.float64)
        errors.append(action - label)
        wanted.append(label)
        obs = env.step(action)[0]
    rms = [float(np.sqrt(np.mean(np.concatenate(v) ** 2))) for v in (errors, wanted)]
    assert rms[0] < 0.01 * rms[1], rms


def test_each_round_is_validated_and_best_pt_is_the_best_round(tmp_path):
    """With validation, every round's row holds the batched runs' validation columns; best.pt is the round that
    ranks first by `selection_key`, and scoring it again on the validation sets gives its row back (the oracle: an
    independent `Validation` of the saved policy). A pruner that says stop ends the run after that round."""
    import csv
    import dataclasses

    from mjtraj.rl.batched import Validation, selection_key, selection_value
    from mjtraj.rl.batched_policy import load_batched

    settings = dataclasses.replace(SMALL, rounds=3, validation=2)
    report = distill(settings, tmp_path / "run", progress=False)
    rows = list(csv.DictReader((tmp_path / "run" / "learning_curve.csv").open()))
    assert [int(r["round"]) for r in rows] == [0, 1, 2] and "missed" in rows[0] and "nominal_ratio" in rows[0]
    best = min(report.rounds, key=selection_key)
    assert report.best_point["round"] == best["round"]
    again = Validation(settings.policy_settings()).row(load_batched(report.best))
    assert again == {k: v for k, v in best.items() if k in again}
    seen = []
    pruned = distill(settings, tmp_path / "pruned", progress=False,
                     on_validation=lambda samples, value: seen.append((samples, value)) is None)
    assert pruned.stopped == "pruned by the search" and len(pruned.rounds) == 1
    assert seen == [(report.rounds[0]["samples"], selection_value(report.rounds[0]))]


def test_validation_versus_the_teacher_pairs_the_student_with_the_teacher_alone(tmp_path):
    """validate_versus teacher: the reference outcomes are the teacher's alone on the same tasks (the oracle: the env
    built for the teacher's law from its arguments, run on the validation sets), each round's row pairs the student
    with them (an independent `Validation` versus the teacher scores best.pt to its row), and the record names it."""
    import dataclasses
    import json

    from mjtraj.envs import resolve

    from mjtraj.rl.batched import Validation
    from mjtraj.rl.batched_policy import load_batched
    from mjtraj.rl.episodes import run_episodes

    settings = dataclasses.replace(SMALL, validate_versus="teacher")
    policy_settings = settings.policy_settings()
    versus = Validation(policy_settings, SMALL.teacher)
    for family, _, refs, w, p, settle in versus.sets:
        env = resolve(**{**policy_settings.env_kwargs(family), "controller": SMALL.teacher})
        assert [o.metrics["cost"] for o in versus.alone[family]] == \
            [o.metrics["cost"] for o in run_episodes(None, env, refs, w, p, settle)]
    law = Validation(policy_settings)
    assert any(versus.alone[f][0].metrics["cost"] != law.alone[f][0].metrics["cost"] for f in SMALL.families)
    report = distill(settings, tmp_path / "run", progress=False)
    again = versus.row(load_batched(report.best))
    assert again == {k: v for k, v in report.best_point.items() if k in again}
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["versus"] == SMALL.teacher and record["distill"]["validate_versus"] == "teacher"
    assert record["versus_validation_cost"] == {f: v for f, v in versus.law_alone()["versus_validation_cost"].items()}
    with pytest.raises(InvalidInputError, match="validate_versus"):
        dataclasses.replace(SMALL, validate_versus="mpc")


def test_a_cubic_student_acts_with_the_cube_of_its_clipped_output():
    """output cubic: the policy's action is the cube of its network's output clipped to [-1, 1] (the oracle: the
    same network's output, computed apart), and the network learns the labels' cube roots, so that acting on its
    targets gives back the labels."""
    import dataclasses

    from mjtraj.rl.batched_policy import batched_policy_class

    torch.manual_seed(0)
    linear = batched_policy_class()(5, 3, SMALL.policy_settings())
    cubic = batched_policy_class()(5, 3, dataclasses.replace(SMALL, output="cubic").policy_settings())
    cubic.load_state_dict(linear.state_dict())
    for module in (linear, cubic):
        module.std.fill_(1.0)
        module.clip.fill_(10.0)
    with torch.no_grad():
        for layer in (linear.net[-1], cubic.net[-1]):
            layer.weight.mul_(50.0)  # outputs beyond [-1, 1]: the clip comes before the cube
        obs = torch.randn(64, 5)
        raw = linear.net(obs)
        assert bool((raw.abs() > 1).any()) and bool((raw.abs() < 1).any())
        assert torch.equal(linear(obs), torch.clamp(raw, -1, 1))
        assert torch.equal(cubic(obs), torch.clamp(raw, -1, 1) ** 3)
    y = np.random.default_rng(1).uniform(-1, 1, size=(50, 3))
    np.testing.assert_allclose(distill_module.targets(y, "cubic") ** 3, y, rtol=1e-12, atol=0)
    assert distill_module.targets(y, "linear") is y


def test_the_annealed_learning_rate_is_a_cosine_over_each_rounds_epochs():
    """`decay`: the epochs of a round train at learning_rate (1e-3 + (1 - 1e-3) (1 + cos(pi e / E)) / 2), e = 0..E-1
    (the oracle: the formula, read off the optimiser at each epoch); without it at learning_rate throughout."""
    import dataclasses

    from mjtraj.rl.batched_policy import batched_policy_class

    for decay in (True, False):
        settings = dataclasses.replace(SMALL, epochs=4, batch=8, decay=decay)
        module = batched_policy_class()(5, 3, settings.policy_settings())
        optimiser = torch.optim.Adam(module.net.parameters(), lr=settings.learning_rate)
        seen = []
        real_step = optimiser.step

        def step(*args, _real=real_step, _seen=seen, _opt=optimiser, **kwargs):
            _seen.append(_opt.param_groups[0]["lr"])
            return _real(*args, **kwargs)

        optimiser.step = step  # type: ignore[method-assign]
        rng = np.random.default_rng(0)
        distill_module._train(module, optimiser, rng.normal(size=(8, 5)), rng.normal(size=(8, 3)) * 0.1, np.ones(8),
                              settings, rng)
        wanted = [settings.learning_rate * ((1e-3 + (1 - 1e-3) * 0.5 * (1 + np.cos(np.pi * e / 4))) if decay else 1.0)
                  for e in range(4)]
        assert seen == pytest.approx(wanted, rel=1e-12)


def test_a_student_reads_its_position_error_over_the_move_where_asked(tmp_path):
    """features error_over_move: the network reads the observation, then e over the task's move, both taken from
    the observation the env gives (the oracle: the env's own e and move entries, divided apart); a saved student
    loads with the same inputs; and the feature is refused without the move observed and by PPO."""
    import gymnasium as gym

    from mjtraj.rl.batched import train_batched
    from mjtraj.rl.batched_policy import BatchedSettings, batched_policy_class, load_batched, save_policy

    settings = DistillSettings(families=("nominal",), num_envs=2, hidden=(8,), preview=2, observe_task=True,
                               observe_control=True, history=1, features="error_over_move")
    env = gym.make_vec("UR5Track-v2", num_envs=2, vectorization_mode="vector_entry_point",
                       **{k: v for k, v in settings.env_kwargs("nominal").items() if k != "teacher"})
    obs, _ = env.reset(seed=2)
    obs, *_ = env.step(np.full((2, 3), 0.3))
    env.close()
    module = batched_policy_class()(obs.shape[1], 3, settings.policy_settings())
    one = obs.shape[1] // 2
    x = module.inputs(torch.as_tensor(obs))
    assert x.shape == (2, obs.shape[1] + 3) and module.mean.shape == (obs.shape[1] + 3,)
    np.testing.assert_array_equal(x[:, :obs.shape[1]].numpy(), obs)
    np.testing.assert_allclose(x[:, obs.shape[1]:].numpy(), obs[:, 12:15] / obs[:, one - 2:one - 1], rtol=1e-15)
    assert np.abs(obs[:, 12:15]).max() > 0
    save_policy(module, tmp_path / "p.pt", {"settings": dataclasses.asdict(settings.policy_settings())})
    loaded = load_batched(tmp_path / "p.pt")
    assert loaded.scaled == module.scaled
    with pytest.raises(InvalidInputError, match=r"^features: error_over_move reads the task's move, which the policy "
                                                r"observes with observe_task; expected observe_task true, got false$"):
        DistillSettings(features="error_over_move")
    with pytest.raises(InvalidInputError, match=r"^features: batched PPO's networks act on the observation alone"):
        train_batched(BatchedSettings(observe_task=True, features="error_over_move"), tmp_path / "ppo")


def test_an_anchored_student_adds_the_torque_that_cancels_the_observed_disturbance():
    """anchor disturbance: the action is the network's (cubed) plus -d over the saturation, d the filter's estimate
    the env observes (the oracle: the env's loop's `mpc_filter`, read apart); the network learns the labels less
    that anchor, so that acting on its targets gives back the labels (within [-1, 1])."""
    import gymnasium as gym

    from mjtraj.core.mpc import disturbance_of
    from mjtraj.rl.batched_policy import batched_policy_class

    settings = DistillSettings(families=("mismatch",), num_envs=2, hidden=(8,), preview=2, observe_task=True,
                               observe_control=True, observe_disturbance=True, history=1, action_mode="torque",
                               controller="pid", output="cubic", anchor="disturbance")
    env = gym.make_vec("UR5Track-v2", num_envs=2, vectorization_mode="vector_entry_point",
                       **{k: v for k, v in settings.env_kwargs("mismatch").items() if k != "teacher"})
    obs, _ = env.reset(seed=7)
    for _ in range(30):
        obs, *_ = env.step(np.full((2, 3), 0.02))
    d = disturbance_of(env.unwrapped.loop.teach("mpc_filter").state, 3) / 60.0
    env.close()
    assert np.abs(d).max() > 0.01
    module = batched_policy_class()(obs.shape[1], 3, settings.policy_settings())
    module.std.fill_(1.0)
    module.clip.fill_(10.0)
    x = torch.as_tensor(obs, dtype=torch.float32)
    np.testing.assert_allclose(module.anchor(x).numpy(), -d, rtol=1e-6)
    with torch.no_grad():
        net = torch.clamp(module.net(module.inputs(x) - module.mean), -1, 1) ** 3
        np.testing.assert_allclose(module(x).numpy(), torch.clamp(net - x[:, module.anchored[0]:module.anchored[1]],
                                                                  -1, 1).numpy(), rtol=1e-6)
    y = np.random.default_rng(1).uniform(-0.5, 0.5, size=(2, 3))
    fitted = distill_module._less_anchor(module, obs, y)
    np.testing.assert_allclose(np.clip(fitted - obs[:, module.anchored[0]:module.anchored[1]], -1, 1), y, atol=1e-15)
    with pytest.raises(InvalidInputError, match=r"^anchor: disturbance cancels the observed disturbance with the "
                                                r"whole torque; expected observe_disturbance true and action_mode "
                                                r"torque, got False and 'torque'$"):
        DistillSettings(action_mode="torque", anchor="disturbance")


GAIN = DistillSettings(families=("nominal",), num_envs=2, hidden=(16, 16), preview=2, preview_frame="reference",
                       controller="pid", structure="gain")


def _gain_student(inputs: int = 40, **changes):
    """A student (3 joints) of `inputs` observed values with GAIN's settings and `changes` (a gain structure by
    default), standardisation the identity."""
    from mjtraj.rl.batched_policy import batched_policy_class

    module = batched_policy_class()(inputs, 3, dataclasses.replace(GAIN, **changes).policy_settings())
    module.std.fill_(1.0)
    module.clip.fill_(1e6)
    return module


def test_a_gain_student_is_affine_in_e_and_ed_and_reads_q_and_qd_through_them_alone():
    """structure gain: the output is k + K [e; ed] with (k, K) the network's output at the observation without q,
    qd, e and ed, e and ed clipped to GAIN_RANGE (the oracle: the network applied to those entries by hand);
    changing q or qd leaves it; within the range it is affine in e and ed (second differences vanish), beyond it
    held."""
    from mjtraj.rl.batched_policy import GAIN_RANGE

    torch.manual_seed(0)
    module = _gain_student()
    gen = np.random.default_rng(0)
    obs = torch.as_tensor(gen.normal(size=(32, 40)), dtype=torch.float32)
    obs[:, 12:18] = torch.as_tensor(gen.uniform(-1.5, 1.5, size=(32, 6)), dtype=torch.float32)
    keep = [j for j in range(40) if not (j < 6 or 12 <= j < 18)]
    with torch.no_grad():
        out = module.net(obs[:, keep])
        gain = out[:, 3:].reshape(-1, 3, 6)
        by_hand = out[:, :3] + torch.einsum("bij,bj->bi", gain, obs[:, 12:18])
        np.testing.assert_allclose(module.raw(obs).numpy(), by_hand.numpy(), rtol=1e-6, atol=1e-6)
        moved = obs.clone()
        moved[:, :6] += 3.0
        assert torch.equal(module.raw(moved), module.raw(obs))
        step = torch.zeros(40)
        step[12:18] = torch.as_tensor(gen.uniform(-1, 1, size=6), dtype=torch.float32)
        second = module.raw(obs + step) + module.raw(obs - step) - 2 * module.raw(obs)
        assert float(second.abs().max()) < 1e-4
        assert float((module.raw(obs + step) - module.raw(obs)).abs().max()) > 1e-2  # e and ed do act
        far = obs.clone()
        far[:, 12:18] = GAIN_RANGE
        farther = obs.clone()
        farther[:, 12:18] = 10 * GAIN_RANGE
        assert torch.equal(module.raw(far), module.raw(farther))


def test_a_gain_beyond_student_is_affine_within_the_range_and_reads_the_excess_beyond_it():
    """structure gain_beyond: (k, K) are the network's output at the context and the excess of e and ed beyond
    GAIN_RANGE (the oracle: by hand, the excess 0 within the range), the output k + K [e; ed] with e and ed clipped;
    within the range it is affine in e and ed, and beyond it the network sees how far they lie."""
    from mjtraj.rl.batched_policy import GAIN_RANGE

    torch.manual_seed(0)
    module = _gain_student(structure="gain_beyond")
    gen = np.random.default_rng(0)
    obs = torch.as_tensor(gen.normal(size=(32, 40)), dtype=torch.float32)
    obs[:, 12:18] = torch.as_tensor(gen.uniform(-6, 6, size=(32, 6)), dtype=torch.float32)
    keep = [j for j in range(40) if not (j < 6 or 12 <= j < 18)]
    with torch.no_grad():
        errors = torch.clamp(obs[:, 12:18], -GAIN_RANGE, GAIN_RANGE)
        out = module.net(torch.cat([obs[:, keep], obs[:, 12:18] - errors], dim=1))
        by_hand = out[:, :3] + torch.einsum("bij,bj->bi", out[:, 3:].reshape(-1, 3, 6), errors)
        np.testing.assert_allclose(module.raw(obs).numpy(), by_hand.numpy(), rtol=1e-6, atol=1e-6)
        inside = obs.clone()
        inside[:, 12:18] = torch.as_tensor(gen.uniform(-1.5, 1.5, size=(32, 6)), dtype=torch.float32)
        step = torch.zeros(40)
        step[12:18] = torch.as_tensor(gen.uniform(-1, 1, size=6), dtype=torch.float32)
        second = module.raw(inside + step) + module.raw(inside - step) - 2 * module.raw(inside)
        assert float(second.abs().max()) < 1e-4
        far = inside.clone()
        far[:, 12] = GAIN_RANGE
        farther = inside.clone()
        farther[:, 12] = 2 * GAIN_RANGE
        assert float((module.raw(farther) - module.raw(far)).abs().max()) > 1e-3  # the excess is read


def test_a_full_gain_student_adds_a_gain_path_to_a_network_of_the_whole_observation():
    """structure gain_full: (k, K) are the network's output at the whole observation (the oracle: by hand), the
    output k + K [e; ed], e and ed within GAIN_RANGE; it takes a cubic output and the relative frame."""
    from mjtraj.rl.batched_policy import GAIN_RANGE

    torch.manual_seed(0)
    module = _gain_student(structure="gain_full", output="cubic", preview_frame="relative")
    obs = torch.as_tensor(np.random.default_rng(0).normal(scale=2.0, size=(32, 40)), dtype=torch.float32)
    with torch.no_grad():
        out = module.net(obs)
        errors = torch.clamp(obs[:, 12:18], -GAIN_RANGE, GAIN_RANGE)
        by_hand = out[:, :3] + torch.einsum("bij,bj->bi", out[:, 3:].reshape(-1, 3, 6), errors)
        np.testing.assert_allclose(module.raw(obs).numpy(), by_hand.numpy(), rtol=1e-6, atol=1e-6)
        assert torch.equal(module(obs), torch.clamp(module.raw(obs), -1, 1) ** 3)


def test_a_gain_student_trained_on_a_law_whose_gain_varies_recovers_its_gains():
    """The oracle: labels of a known law whose gain varies with the context, y = (G + r H) [e; ed] + C s (G, H fixed
    3 x 6 gains, r one entry of the rest, s two others), fitted by the distillation's training step with a linear
    network (k and K then linear in the rest: the law inside the form exactly, which no linear function of the
    observation is; e and ed uniform, within GAIN_RANGE standard deviations): the student's output at held-out
    observations is the law's, and its finite-difference gain in e and ed is G + r H, both within 1e-4 of their size
    (measured: below 1e-6, float32)."""
    torch.manual_seed(0)
    gen = np.random.default_rng(1)

    def draw(m):
        x = gen.normal(size=(m, 40))
        x[:, 12:18] = gen.uniform(-1.5, 1.5, size=(m, 6))
        return x

    x = draw(4000)
    G = gen.uniform(-0.1, 0.1, size=(3, 6))
    H = gen.uniform(-0.05, 0.05, size=(3, 6))
    C = gen.uniform(-0.2, 0.2, size=(3, 2))

    def gains(obs):
        return G[None] + obs[:, 25, None, None] * H[None]  # (M, 3, 6)

    def law(obs):
        return np.einsum("mij,mj->mi", gains(obs), obs[:, 12:18]) + obs[:, 20:22] @ C.T

    module = _gain_student(hidden=())
    optimiser = torch.optim.Adam(module.net.parameters())
    settings = dataclasses.replace(GAIN, hidden=(), epochs=30, batch=128, learning_rate=1e-2, decay=True)
    distill_module._train(module, optimiser, x, law(x), np.ones(len(x)), settings, np.random.default_rng(2))
    held = draw(200)
    with torch.no_grad():
        got = module(torch.as_tensor(held, dtype=torch.float32)).numpy()
        np.testing.assert_allclose(got, law(held), atol=1e-4 * np.abs(law(held)).max(), rtol=0)
        h = 1e-1
        for j in range(6):
            step = np.zeros(40)
            step[12 + j] = h
            fd = (module(torch.as_tensor(held + step, dtype=torch.float32))
                  - module(torch.as_tensor(held - step, dtype=torch.float32))).numpy() / (2 * h)
            np.testing.assert_allclose(fd, gains(held)[:, :, j], atol=1e-4 * np.abs(gains(held)).max(), rtol=0)


def test_the_training_step_leaves_an_output_past_its_saturated_labels_alone():
    """With the labels' limits, a network whose outputs all lie past labels at the limit (+1 labels, outputs 2; -1
    labels, outputs -2) has no error and the training step leaves it unchanged, bit for bit; without them, the same
    step pulls it to the labels (the oracle: the parameters before and after)."""
    for bound in (True, False):
        module = _gain_student(hidden=())
        with torch.no_grad():
            for parameter in module.net.parameters():
                parameter.zero_()
            module.net[-1].bias[:3] = torch.tensor([2.0, -2.0, 2.0])  # k; K = 0
        before = [q.detach().clone() for q in module.net.parameters()]
        x = np.random.default_rng(0).normal(size=(256, 40))
        y = np.tile([1.0, -1.0, 1.0], (256, 1))
        optimiser = torch.optim.Adam(module.net.parameters())
        distill_module._train(module, optimiser, x, y, np.ones(256), dataclasses.replace(GAIN, epochs=2),
                              np.random.default_rng(1), None, distill_module.saturated(y) if bound else None)
        same = all(torch.equal(a, b) for a, b in zip(before, module.net.parameters(), strict=True))
        assert same == bound


def test_a_label_at_the_limit_is_met_by_any_output_beyond_it():
    """one_sided: where the teacher's command is at the saturation (a label of +-1), an output past it has no error
    and one short of it keeps its error; elsewhere the error is untouched. saturated marks the limits."""
    y = np.array([[1.0, -1.0, 0.5], [1.0, -1.0, -0.999]])
    bound = distill_module.saturated(y)
    np.testing.assert_array_equal(bound, [[1, -1, 0], [1, -1, 0]])
    error = torch.tensor([[0.3, -0.3, 0.2], [-0.3, 0.3, -0.2]])
    got = distill_module.one_sided(error, torch.as_tensor(bound))
    np.testing.assert_array_equal(got.numpy(), np.array([[0.0, 0.0, 0.2], [-0.3, 0.3, -0.2]], dtype=np.float32))


def test_a_gain_distillation_trains_one_sided_at_the_saturated_labels(tmp_path, monkeypatch):
    """`distill` hands `_train` the labels' limits (`saturated` of every round's labels) with a gain structure, and
    none without."""
    seen: list[object] = []
    labelled: list[np.ndarray] = []
    train = distill_module._train

    def spy(module, optimiser, x, y, w, settings, rng, following=None, bound=None):
        seen.append(bound)
        return train(module, optimiser, x, y, w, settings, rng, following, bound)

    monkeypatch.setattr(distill_module, "_train", spy)
    real = distill_module.saturated
    monkeypatch.setattr(distill_module, "saturated", lambda y: (labelled.append(y.copy()), real(y))[1])
    for structure in ("none", "gain"):
        seen.clear()
        settings = dataclasses.replace(GAIN, rounds=1, steps=10, epochs=1, validation=0, structure=structure)
        distill(settings, tmp_path / structure, progress=False)
        if structure == "none":
            assert seen == [None] and not labelled
            continue
        (y,) = labelled
        assert y.shape == (10 * settings.num_envs, 3)
        np.testing.assert_array_equal(seen[0], real(y))


def test_a_gain_student_saves_and_loads_and_ppo_refuses_it(tmp_path):
    """A gain student round-trips through a policy file: the module loaded acts as the one saved, bit for bit (the
    oracle: the module in memory), its joints recovered from the network's n + 2 n^2 outputs; a distilled one's file
    loads so too; batched PPO refuses the structure by name."""
    from mjtraj.rl.batched import BatchedSettings, train_batched
    from mjtraj.rl.batched_policy import load_batched, save_policy

    torch.manual_seed(3)
    for structure in ("gain", "gain_beyond", "gain_full"):
        module = _gain_student(structure=structure)
        record = {"settings": dataclasses.asdict(dataclasses.replace(GAIN, structure=structure).policy_settings())}
        save_policy(module, tmp_path / f"{structure}.pt", record)
        loaded = load_batched(tmp_path / f"{structure}.pt")
        assert loaded.n == 3 and loaded.net[-1].out_features == 3 + 2 * 9
        obs = torch.randn(64, 40) * 3
        with torch.no_grad():
            assert torch.equal(loaded(obs), module(obs))
        assert "context" not in torch.load(tmp_path / f"{structure}.pt", weights_only=True)["state"]
    report = distill(dataclasses.replace(GAIN, rounds=1, steps=10, epochs=1, validation=0), tmp_path / "run",
                     progress=False)
    assert load_batched(report.policy).n == 3
    with pytest.raises(InvalidInputError, match=r"^structure: batched PPO's networks act on the observation alone, "
                                                r"expected none, got 'gain'"):
        train_batched(BatchedSettings(preview_frame="reference", structure="gain"), tmp_path / "ppo")
