"""Ensembles (`mjtraj.rl.ensemble`): the NumPy action is the mean of the members' torch modules' actions (the oracle:
the modules themselves), members that act apart are refused by name, and rl eval holds the ensemble to every member's
training streams and scores it as a policy."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from mjtraj.exceptions import InvalidInputError
from mjtraj.rl.batched_policy import BATCHED_RUN, batched_policy_class, load_batched, save_policy
from mjtraj.rl.distill import DistillSettings
from mjtraj.rl.ensemble import is_ensemble, load_ensemble, write_ensemble
from mjtraj.rl.streams import family_entropies, training_entropies

ANCHORED = DistillSettings(families=("mismatch",), num_envs=2, hidden=(8, 8), preview=2, observe_task=True,
                           observe_control=True, observe_disturbance=True, action_mode="torque", controller="pid",
                           output="cubic", anchor="disturbance", features="error_over_move")
PLAIN = DistillSettings(families=("nominal",), num_envs=2, hidden=(8,), preview=2, controller="pid")
GAIN = dataclasses.replace(ANCHORED, output="linear", features="none", preview_frame="reference", structure="gain")
GAIN_FULL = dataclasses.replace(ANCHORED, structure="gain_full")
GAIN_BEYOND = dataclasses.replace(GAIN, structure="gain_beyond")


def _member(tmp_path, settings, seed, *, gym_seeds=(), distilled=False, unknown=(), name=""):
    """A member saved as rl distill saves one: random weights and standardisation, a record with its streams (with
    `distilled`, also the distillation's format and settings, but those named in `unknown`, as a record written
    before they existed), saved as tmp_path / `name` (default member_SEED.pt)."""
    from mjtraj.envs import resolve

    torch.manual_seed(seed)
    module = batched_policy_class()(resolve(**settings.env_kwargs(settings.families[0])).obs_size, 3,
                                    settings.policy_settings())
    gen = np.random.default_rng(seed)
    with torch.no_grad():
        for p in module.net.parameters():
            p.copy_(torch.as_tensor(gen.normal(scale=0.7, size=p.shape)))
        module.mean.copy_(torch.as_tensor(gen.normal(size=module.mean.shape)))
        module.std.copy_(torch.as_tensor(gen.uniform(0.5, 2.0, size=module.std.shape)))
        module.epsilon.fill_(1e-8)
        module.clip.fill_(5.0)
    record = {"settings": {**dataclasses.asdict(settings.policy_settings()), "seed": seed},
              "streams": {"train": {"gym_seeds": list(gym_seeds) or training_entropies(seed, 2)},
                          "validation": {"count": 2}}}
    if distilled:
        record.update(format=BATCHED_RUN, distill={k: v for k, v in dataclasses.asdict(settings).items()
                                                   if k not in unknown})
    path = tmp_path / (name or f"member_{seed}.pt")
    path.parent.mkdir(parents=True, exist_ok=True)
    save_policy(module, path, record)
    return path


@pytest.mark.parametrize("settings", [ANCHORED, PLAIN, GAIN, GAIN_BEYOND, GAIN_FULL],
                         ids=["anchored-cubic-features", "linear", "gain", "gain_beyond",
                              "gain_full-anchored-cubic-features"])
def test_an_ensembles_action_is_the_mean_of_its_members_modules_actions(tmp_path, settings):
    """The oracle: each member's torch module, as rl eval feeds it (float32), averaged; within float32 rounding.
    Observations spread wide enough that clipping, the cube and the anchor each act; 1e-5 is float32 rounding
    through the layers (summed in another order) and the cube; 2e-5 with the gain structure, whose products K [e; ed]
    of terms up to about 10 add their own rounding (measured: 1.01e-5 at worst)."""
    paths = [_member(tmp_path, settings, seed) for seed in (0, 1, 2)]
    out = write_ensemble(paths, tmp_path / "ensemble.pt")
    ensemble = load_ensemble(out)
    modules = [load_batched(p) for p in paths]
    obs = np.random.default_rng(5).normal(scale=3.0, size=(256, modules[0].mean.numel()
                                                          - (3 if settings.features != "none" else 0)))
    if settings.features != "none":
        one = obs.shape[1]
        obs[:, one - 2] = np.abs(obs[:, one - 2]) + 0.1  # the move is positive
    with torch.no_grad():
        actions = [m(torch.as_tensor(obs, dtype=torch.float32)).numpy() for m in modules]
    got = ensemble(obs)
    assert got.shape == (256, 3) and got.dtype == np.float32
    np.testing.assert_allclose(got, np.mean(actions, axis=0), atol=2e-5 if settings.structure != "none" else 1e-5,
                               rtol=0)
    assert np.ptp([a[:, 0] for a in actions], axis=0).max() > 0.1  # the members disagree: the mean is tested
    assert (np.abs(actions[0]) == 1).any() and (np.abs(actions[0]) < 0.5).any()  # clipped and unclipped rows
    assert is_ensemble(out) and not is_ensemble(paths[0])
    assert ensemble.env == modules[0].env and [m["record"] for m in ensemble.record["members"]] == [
        m.record for m in modules]


def test_members_that_act_apart_the_same_file_twice_and_an_ensemble_as_one_policy_are_refused(tmp_path):
    a = _member(tmp_path, PLAIN, 0)
    b = _member(tmp_path, dataclasses.replace(PLAIN, preview=3), 1)
    with pytest.raises(InvalidInputError, match=r"^members: .*member_1\.pt acts with preview=3 where .*member_0\.pt "
                                                r"acts with preview=2; expected members that act in one env$"):
        write_ensemble([a, b], tmp_path / "e.pt")
    wide = _member(tmp_path, dataclasses.replace(PLAIN, hidden=(16,)), 2)
    with pytest.raises(InvalidInputError, match=r"^members: .*member_2\.pt has hidden=\(16,\) where .*member_0\.pt "
                                                r"has hidden=\(8,\); expected members of one architecture$"):
        write_ensemble([a, wide], tmp_path / "e.pt")
    with pytest.raises(InvalidInputError, match=r"^members: .*member_0\.pt is .*member_0\.pt again; expected "
                                                r"distinct policies$"):
        write_ensemble([a, a], tmp_path / "e.pt")
    with pytest.raises(InvalidInputError, match=r"^members: expected at least one policy file, got none$"):
        write_ensemble([], tmp_path / "e.pt")
    with pytest.raises(InvalidInputError, match=r"^members: expected policy files, got .*nowhere\.pt, which is not a "
                                                r"file$"):
        write_ensemble([a, tmp_path / "nowhere.pt"], tmp_path / "e.pt")
    cubic = _member(tmp_path, dataclasses.replace(PLAIN, action_mode="torque", output="cubic"), 3)
    linear = _member(tmp_path, dataclasses.replace(PLAIN, action_mode="torque"), 4)
    with pytest.raises(InvalidInputError, match=r"^members: .*member_4\.pt has output='linear' where .*member_3\.pt "
                                                r"has output='cubic'; expected members of one architecture$"):
        write_ensemble([cubic, linear], tmp_path / "e.pt")
    before = a.read_bytes()
    with pytest.raises(InvalidInputError, match=r"^out: expected a file other than the members', got .*member_0\.pt, "
                                                r"which is one of them$"):
        write_ensemble([a, cubic], a)
    assert a.read_bytes() == before
    with pytest.raises(InvalidInputError, match=r"^out: expected a file name ending in \.pt .*, got .*e\.zip$"):
        write_ensemble([a], tmp_path / "e.zip")
    assert not (tmp_path / "e.pt").exists()
    one = write_ensemble([a], tmp_path / "one.pt")
    with pytest.raises(InvalidInputError, match=r"^policy: .*one\.pt is an ensemble \(mjtraj rl ensemble\); "
                                                r"expected one policy saved by"):
        load_batched(one)
    with pytest.raises(InvalidInputError, match=r"^policy: expected an ensemble written by mjtraj rl ensemble \(format "
                                                r"mjtraj-ensemble-policy/1\), got .*member_0\.pt of format "
                                                r"'mjtraj-batched-policy/1'$"):
        load_ensemble(a)


def test_rl_eval_holds_an_ensemble_to_every_members_training_streams(tmp_path):
    """The second member trained on the stream of nominal scenario 3 under seed 9: scoring the ensemble there is
    refused, as it is for that member alone; seed 10 is clear. The label names the ensemble."""
    from mjtraj.rl.adapters import load_any
    from mjtraj.rl.evaluate import check_held_out

    clear = _member(tmp_path, PLAIN, 0)
    shared = _member(tmp_path, PLAIN, 1, gym_seeds=[family_entropies("nominal", 9, [3])[0]])
    policy = load_any(str(write_ensemble([clear, shared], tmp_path / "e.pt")))
    assert policy.label.endswith(", ensemble of 2") and policy.kind == "callable" and len(policy.sha256) == 64
    with pytest.raises(InvalidInputError, match=r"^seed: 1 of the nominal scenarios under seed 9 share a seed "
                                                r"stream with .*e\.pt's training"):
        check_held_out(policy, "nominal", 9, 5)
    check_held_out(policy, "nominal", 10, 5)


@pytest.mark.slow
def test_the_command_line_writes_an_ensemble_that_rl_eval_scores_and_times(tmp_path, capsys):
    """`mjtraj rl ensemble A B --out E` then `rl eval --policy E`: its rows carry the ensemble's label, and the
    compute table times its inference."""
    import csv

    from mjtraj.cli import main

    members = [str(_member(tmp_path, PLAIN, seed)) for seed in (0, 1)]
    target = tmp_path / "e.pt"
    assert main(["rl", "ensemble", *members, "--out", str(target)]) == 0
    assert capsys.readouterr().out == f"wrote {target} (the mean of 2 policies)\n"
    out = tmp_path / "eval"
    assert main(["rl", "eval", "--policy", str(target), "--family", "nominal", "--scenarios", "2", "--controllers",
                 "pid", "--out", str(out), "--no-progress"]) == 0
    rows = [r for r in csv.DictReader((out / "eval.csv").open()) if r["policy"] == str(target)]
    assert len(rows) == 2 and all(r["method"].endswith(", ensemble of 2") for r in rows)
    summary = (out / "SUMMARY.md").read_text()
    assert "the mean of 2 policies: batched PPO (skrl), seeds 0, 1" in summary
    assert any(line.startswith("| cubic+") and "ensemble of 2 | inference, batch 1 |" in line
               for line in summary.splitlines())


def test_distilled_students_pool_as_seeds_only_where_their_distillations_differ_in_the_seed_alone(tmp_path):
    """Students whose distillations differ in a setting the policy's own settings do not hold (DAgger's mixing) are
    two configurations; a record written before the collection's noise settings existed pools with one that writes
    their defaults."""
    from mjtraj.rl.adapters import load_any
    from mjtraj.rl.evaluate import _labels, configurations

    recipe = dataclasses.replace(PLAIN, mixing=0.5)
    files = [_member(tmp_path, dataclasses.replace(recipe, seed=0), 0, distilled=True, name="a/best.pt"),
             _member(tmp_path, dataclasses.replace(recipe, seed=1), 1, distilled=True, name="b/best.pt",
                     unknown=("action_noise", "noise_on")),
             _member(tmp_path, dataclasses.replace(recipe, seed=2, mixing=0.8), 2, distilled=True, name="c/best.pt")]
    policies = [load_any(str(f)) for f in files]
    labels = _labels(policies)
    groups = configurations(policies, labels)
    assert sorted(map(sorted, groups.values()), key=len) == [[labels[2]], sorted(labels[:2])]
    assert any(name.endswith("[mixing=0.8]") for name in groups)


def test_ensembles_of_one_recipe_pool_as_seeds_and_other_recipes_do_not(tmp_path):
    """Two ensembles of the same recipe's members under other seeds (whatever their file names and member order) are
    one configuration of two seeds; an ensemble that mixes in a member of another recipe (more sub-envs) is another."""
    from mjtraj.rl.adapters import load_any
    from mjtraj.rl.evaluate import _labels, configurations

    same = [_member(tmp_path, PLAIN, seed) for seed in (0, 1, 2, 3)]
    other = _member(tmp_path, dataclasses.replace(PLAIN, num_envs=3), 4)
    files = [write_ensemble([same[0], same[1]], tmp_path / "first.pt"),
             write_ensemble([same[3], same[2]], tmp_path / "second.pt"),
             write_ensemble([same[0], other], tmp_path / "mixed.pt")]
    policies = [load_any(str(f)) for f in files]
    labels = _labels(policies)
    groups = sorted(configurations(policies, labels).values(), key=len)
    assert [len(g) for g in groups] == [1, 2]
    assert groups[0] == [labels[2]] and sorted(groups[1]) == sorted(labels[:2])
