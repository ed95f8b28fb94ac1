"""The regression oracles (mjtraj.golden, docs/testing.md "Golden values"): the golden files against this code, bit
for bit on the recording machine and at the stated tolerances elsewhere; and the comparison's own rules on synthetic
oracles with known answers."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from mjtraj import golden
from mjtraj.cli import main
from mjtraj.golden import COMMAND, SETS, Check, Entry, GoldenSet, compare_entries

GOLDEN = Path(__file__).parent / "golden"


def _failure(check: Check, group: str) -> str:
    return Check(check.path, check.same_machine, [d for d in check.differences if d.entry.split("/")[0] == group],
                 check.unpinned).message()


@pytest.fixture(scope="module")
def fast() -> Check:
    return golden.check(SETS["fast"], GOLDEN)


@pytest.mark.parametrize("group", list(golden.GROUPS))
def test_the_fast_golden_values_hold(fast, group):
    """Each group of the fast set as recorded. On a failure: regenerate with `mjtraj golden --write` if the change
    is intended, and say why in CHANGELOG.md."""
    moved = [d for d in fast.differences if d.entry.split("/")[0] == group]
    assert moved == [], _failure(fast, group)


def test_the_fast_file_pins_every_entry_the_code_computes(fast):
    """A new entry (a planner registered, a law added) is pinned by regenerating; new keys of an entry are not
    required (a metric added moves no published number)."""
    new = [name for name in fast.unpinned if " " not in name]
    assert new == [], (f"{len(new)} entries computed that {fast.path} does not pin: {', '.join(new[:10])}; "
                       f"regenerate with `{COMMAND}` and say why in CHANGELOG.md")
    groups = {name.split("/")[0] for name in json.loads(fast.path.read_text())["entries"]}
    assert groups == set(golden.GROUPS)


@pytest.mark.slow
def test_the_full_golden_values_hold():
    """The full set (tens of scenarios per family, every law on every family)."""
    check = golden.check(SETS["full"], GOLDEN)
    assert check.differences == [], check.message()
    assert [name for name in check.unpinned if " " not in name] == []


# The comparison's rules, on synthetic oracles


def _one(entry: Entry) -> dict[str, Entry]:
    return {"sweep/pid/nominal/0/cubic": entry}


def test_a_value_beyond_the_tolerance_fails_on_another_machine():
    differences, _ = compare_entries(_one(Entry(values={"cost": 1.0})), _one(Entry(values={"cost": 1.0 + 3e-9})),
                                     exact=False)
    assert [(d.entry, d.key, d.old, d.new) for d in differences] == [("sweep/pid/nominal/0/cubic", "cost", 1.0,
                                                                      1.0 + 3e-9)]
    assert differences[0].rule == "relative 3e-09 > 1e-09"


def test_a_value_within_the_tolerance_passes_on_another_machine():
    old = Entry(values={"cost": 1.0, "zero": 0.0, "nan": math.nan, "inf": math.inf})
    new = Entry(values={"cost": 1.0 + 9e-10, "zero": 0.0, "nan": math.nan, "inf": math.inf})
    assert compare_entries(_one(old), _one(new), exact=False) == ([], [])


def test_any_change_fails_on_the_recording_machine():
    last_bit = math.nextafter(1.0, 2.0)
    differences, _ = compare_entries(_one(Entry(values={"cost": 1.0})), _one(Entry(values={"cost": last_bit})),
                                     exact=True)
    assert [(d.key, d.rule) for d in differences] == [("cost", "exact")]
    assert compare_entries(_one(Entry(values={"z": 0.0})), _one(Entry(values={"z": -0.0})), exact=True)[0] != []
    assert compare_entries(_one(Entry(values={"n": math.nan})), _one(Entry(values={"n": math.nan})),
                           exact=True) == ([], [])


@pytest.mark.parametrize("exact", [True, False])
@pytest.mark.parametrize("kind", list(golden.TOLERANCES))
def test_a_status_change_always_fails(exact, kind):
    old = Entry(kind, {"status": "ok", "solver": "sqp"}, {"cost": 1.0})
    new = Entry(kind, {"status": "missed_goal", "solver": "sqp"}, {"cost": 1.0})
    differences, _ = compare_entries(_one(old), _one(new), exact=exact)
    assert [(d.key, d.old, d.new, d.rule) for d in differences] == [("status", "ok", "missed_goal", "status, exact")]


def test_the_float32_tolerance_is_looser():
    old = _one(Entry("float32", values={"cost": 1.0}))
    assert compare_entries(old, _one(Entry("float32", values={"cost": 1.0 + 9e-6})), exact=False) == ([], [])
    assert compare_entries(old, _one(Entry("float32", values={"cost": 1.0 + 2e-5})), exact=False)[0] != []
    assert compare_entries(old, _one(Entry("float32", values={"cost": 1.0 + 1e-15})), exact=True)[0] != []


def test_sensitive_values_hashes_and_exact_ones_count_on_the_recording_machine_only():
    old = Entry("sensitive", {"status": "ok"}, {"cost": 1.0}, {"residual": 1e-12}, {"u_plan": "a" * 64})
    new = Entry("sensitive", {"status": "ok"}, {"cost": 1.5}, {"residual": 2e-12}, {"u_plan": "b" * 64})
    assert compare_entries(_one(old), _one(new), exact=False) == ([], [])
    differences, _ = compare_entries(_one(old), _one(new), exact=True)
    assert [(d.key, d.rule) for d in differences] == [("cost", "exact"), ("residual", "exact"),
                                                      ("u_plan", "sha256 of the array, exact")]
    abroad = Entry("float64", {}, {"cost": 1.0}, {"residual": 1e-12}, {"u_plan": "a" * 64})
    moved = Entry("float64", {}, {"cost": 1.0}, {"residual": 5e-12}, {"u_plan": "b" * 64})
    assert compare_entries(_one(abroad), _one(moved), exact=False) == ([], [])


def test_what_is_missing_fails_and_what_is_new_is_reported():
    old = {"a/1": Entry(statuses={"status": "ok"}, values={"cost": 1.0}), "a/2": Entry(values={"cost": 2.0})}
    now = {"a/1": Entry(statuses={}, values={"cost": 1.0, "rms_err": 0.1}), "a/3": Entry()}
    differences, unpinned = compare_entries(old, now, exact=False)
    assert [(d.entry, d.key, d.new) for d in differences] == [("a/1", "status", "missing"),
                                                              ("a/2", "(entry)", "missing")]
    assert unpinned == ["a/3", "a/1 rms_err"]


def test_the_failure_message_names_the_value_and_the_cure():
    check = Check(Path("tests/golden/fast.json"), True,
                  compare_entries(_one(Entry(values={"cost": 0.5})), _one(Entry(values={"cost": 0.25})),
                                  exact=True)[0], [])
    message = check.message()
    assert "sweep/pid/nominal/0/cubic cost: golden 0.5, now 0.25 (exact)" in message
    assert "bit for bit" in message
    assert f"regenerate the golden files with `{COMMAND}`" in message and "CHANGELOG.md" in message


SYNTHETIC = GoldenSet("synthetic", {}, {}, (), 0, (0,), (0, 0))


def _entries() -> dict[str, Entry]:
    return {"sweep/pid/nominal/0/cubic": Entry("float64", {"status": "ok"}, {"cost": 0.1, "nan": math.nan,
                                                                          "inf": -math.inf}),
            "policy/nominal/0": Entry("float32", {"status": "ok"}, {"cost": 1 / 3}),
            "nonlinear/nonlinear_optimal/paper": Entry("float64", {"solver": "sqp"}, {"objective": 28.690861282715712},
                                                       {"terminal_residual": 1.7e-12}, {"u_plan": "f" * 64})}


def test_files_round_trip_bit_for_bit(tmp_path):
    path = golden.write(SYNTHETIC, _entries(), tmp_path)
    recorded, entries = golden.read(SYNTHETIC, tmp_path)
    assert recorded == golden.fingerprint()
    assert entries.keys() == _entries().keys()
    for name, entry in entries.items():
        assert entry.record() == _entries()[name].record()
    assert golden.check(SYNTHETIC, tmp_path, _entries()).differences == []
    assert path.read_text() == json.dumps(golden.file_record(SYNTHETIC, _entries()), indent=1) + "\n"


def test_the_fingerprint_decides_how_values_are_compared(tmp_path):
    golden.write(SYNTHETIC, _entries(), tmp_path)
    last_bit = _entries()
    last_bit["sweep/pid/nominal/0/cubic"] = Entry("float64", {"status": "ok"},
                                                  {"cost": math.nextafter(0.1, 1.0), "nan": math.nan,
                                                   "inf": -math.inf})
    same = golden.check(SYNTHETIC, tmp_path, last_bit)
    assert same.same_machine and [d.key for d in same.differences] == ["cost"]
    record = json.loads((tmp_path / "synthetic.json").read_text())
    record["fingerprint"]["cpu"] = "another CPU"
    (tmp_path / "synthetic.json").write_text(json.dumps(record))
    other = golden.check(SYNTHETIC, tmp_path, last_bit)
    assert not other.same_machine and other.differences == []
    assert "not the recording machine's" in Check(other.path, False, same.differences, []).message()


def test_the_fingerprint_names_the_machine_and_the_numerical_libraries_not_mjtraj():
    facts = golden.fingerprint()
    assert {"cpu", "python", "numpy", "scipy", "mujoco", "numba", "daqp", "osqp", "torch", "blas"} <= facts.keys()
    assert "mjtraj" not in facts
    assert facts["numpy"] and facts["mujoco"] and facts["blas"]


def test_the_committed_files_state_their_command_and_tolerances():
    for spec in SETS.values():
        record = json.loads(golden.golden_path(spec, GOLDEN).read_text())
        assert COMMAND in record["about"] and "CHANGELOG.md" in record["about"]
        assert record["tolerances"] == golden.TOLERANCES
        assert record["set"] == spec.name and record["seed"] == golden.SEED


@pytest.mark.parametrize(("protocol", "table"), [("v1", "best"), ("v2", "v2")])
def test_each_protocols_golden_policy_is_the_one_its_published_table_scores(protocol, table):
    """The oracle is the published table (docs/results/TABLE/summary.json, written by rl eval): the policy it scores,
    its sha256 and its kind; the golden entries must pin that policy, with the tolerance kind of the kind it
    published."""
    published = json.loads((Path(__file__).parents[1] / "docs" / "results" / table / "summary.json").read_text())
    (policy,) = published["policies"]
    assert policy["policy"] == golden.POLICIES[protocol]
    group = "policy" if protocol == "v1" else f"policy_{protocol}"
    for spec in SETS.values():
        entries = json.loads(golden.golden_path(spec, GOLDEN).read_text())["entries"]
        pinned = [e for k, e in entries.items() if k.split("/")[0] == group]
        assert pinned, f"{spec.name}: no {group} entries"
        for entry in pinned:
            assert entry["statuses"]["policy_sha256"] == policy["policy_sha256"]
            assert entry["kind"] == golden.policy_entry_kind(policy["policy_kind"])


def test_the_command_writes_and_checks(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(golden.SETS, "fast", SYNTHETIC)
    monkeypatch.setattr(golden, "compute", lambda spec, **_: _entries())
    assert main(["golden", "--set", "fast", "--dir", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"mjtraj: error: dir: no golden file {tmp_path / 'synthetic.json'}; write it with `{COMMAND}`")
    assert main(["golden", "--set", "fast", "--write", "--dir", str(tmp_path)]) == 0
    assert f"wrote {tmp_path / 'synthetic.json'} (3 entries)" in capsys.readouterr().out
    assert main(["golden", "--set", "fast", "--dir", str(tmp_path)]) == 0
    assert "3 entries as recorded" in capsys.readouterr().out
    moved = _entries()
    moved["policy/nominal/0"] = Entry("float32", {"status": "diverged"}, {"cost": 1 / 3})
    monkeypatch.setattr(golden, "compute", lambda spec, **_: moved)
    assert main(["golden", "--set", "fast", "--dir", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "policy/nominal/0 status: golden 'ok', now 'diverged' (status, exact)" in out
    assert f"`{COMMAND}`" in out
    assert main(["golden", "--set", "fast", "--write", "--dir", str(tmp_path)]) == 0
    assert "1 value(s) moved" in capsys.readouterr().out


def test_a_round_off_value_passes_on_another_machine_within_the_absolute_floor():
    """An at-rest speed of 2.3e-10 that another machine moves by 2.8e-17 passes (ROUND_OFF); a move of 1e-14 fails."""
    old = Entry(values={"end_speed": 2.3198275480617465e-10})
    moved_off, _ = compare_entries(_one(old), _one(Entry(values={"end_speed": 2.3198278300590025e-10})), exact=False)
    assert moved_off == []
    moved, _ = compare_entries(_one(old), _one(Entry(values={"end_speed": 2.3198275480617465e-10 + 1e-14})),
                               exact=False)
    assert [d.key for d in moved] == ["end_speed"]
