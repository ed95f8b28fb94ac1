"""What the README and the docs show runs, and prints what they say it prints."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

from mjtraj.rl.evaluate import evaluate

ROOT = Path(__file__).resolve().parent.parent


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block of a Markdown text."""
    return re.findall(r"```(\w*)\n(.*?)```", text, flags=re.S)


def test_the_readmes_env_example_prints_what_the_readme_shows():
    """The README's headless example (the benchmark's current env) prints its pasted output, with no warning that
    the env is out of date."""
    import warnings

    found = blocks((ROOT / "README.md").read_text())
    index = next(i for i, (lang, body) in enumerate(found) if lang == "python" and "UR5TrackMismatch-v2" in body)
    code, (_, shown) = found[index][1], found[index + 1]
    out = io.StringIO()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        with contextlib.redirect_stdout(out):
            exec(compile(code, "README.md", "exec"), {})
    assert out.getvalue() == shown


@pytest.mark.slow
def test_the_benchmark_pages_example_policy_is_scored(tmp_path):
    page = (ROOT / "docs" / "benchmark.md").read_text()
    code = next(body for lang, body in blocks(page) if lang == "python" and "class Damped" in body)
    (tmp_path / "mypolicy.py").write_text(code)
    report = evaluate([f"{tmp_path / 'mypolicy.py'}:policy"], scenarios=2, seed=1, reps=10, out=tmp_path / "out")
    (method,) = [m for m in report.summaries["nominal"] if m.endswith("mypolicy.py:policy")]
    assert report.summaries["nominal"][method].failures == 0


def test_every_relative_link_of_the_readme_and_the_docs_resolves_in_the_repository():
    """A link the Markdown files give (outside code blocks) points at a file that exists, as GitHub and a checkout
    read them; `mkdocs build --strict` checks the built site's own links (CI runs both)."""
    broken = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
        for link in re.findall(r"\]\(([^)\s]+)\)", text):
            path = link.split("#")[0]
            if path and not re.match(r"[a-z]+:", path) and not (page.parent / path).exists():
                broken.append(f"{page.relative_to(ROOT)}: {link}")
    assert broken == []


@pytest.mark.slow
def test_the_benchmark_pages_torch_module_is_scored_as_the_controller_alone(tmp_path):
    """The page's torch example starts at a zero residual: it scores exactly cubic+PID, row by row."""
    from mjtraj.study.store import read_rows

    page = (ROOT / "docs" / "benchmark.md").read_text()
    code = next(body for lang, body in blocks(page) if lang == "python" and "torch.nn.Module" in body)
    (tmp_path / "mynet.py").write_text(code)
    report = evaluate([f"{tmp_path / 'mynet.py'}:policy"], families=("nominal",), scenarios=2, reps=10,
                      out=tmp_path / "out")
    rows = read_rows(report.csv)
    mine = [(r["cost"], r["status"]) for r in rows if r["method"].endswith("mynet.py:policy")]
    assert mine == [(r["cost"], r["status"]) for r in rows if r["method"] == "cubic+PID"] and len(mine) == 2


def _table(text: str, header: str) -> dict[str, dict[str, str]]:
    """The Markdown table whose header line starts with `header`: method -> column -> cell."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header))
    columns = [c.strip() for c in lines[start].strip("|").split("|")]
    rows = {}
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows[cells[0]] = dict(zip(columns, cells, strict=True))
    return rows


@pytest.mark.parametrize("page, section, cited, headers", [
    ("docs/results.md", "## Tracking controllers under protocol v2", "docs/results/v2",
     ("| method | nominal: J / cubic+adaptive CT, P(improve) |", "| method | nominal: J / floor |")),
    ("docs/results.md", "## Tracking controllers under protocol v1", "docs/results/best",
     ("| method | nominal: J / cubic+PID, P(improve) |", "| method | nominal: J / floor |")),
])
def test_the_result_tables_are_the_cited_summarys_cells(page, section, cited, headers):
    """Every cell of a page's tables of the control laws (results.md's protocol v2 and v1 sections) is the cell of
    the same method and column in the SUMMARY.md the section cites (written by the command shown beside them), not
    typed by hand."""
    text = (ROOT / page).read_text()
    text = text[text.index(section + "\n"):]
    text = text[:text.find("\n## ", 1) if "\n## " in text else None]
    summary = (ROOT / cited / "SUMMARY.md").read_text()
    link = cited.removeprefix("docs/") if page.startswith("docs/") else cited
    assert f"]({link}/SUMMARY.md)" in text and f"--out {cited}" in text
    for header in headers:
        shown, source = _table(text, header), _table(summary, header)
        assert shown and set(shown) <= set(source)
        for method, cells in shown.items():
            assert cells == {column: source[method][column] for column in cells}, method


@pytest.mark.slow
def test_the_env_pages_headline_example_prints_what_the_page_shows(tmp_path, monkeypatch):
    """docs/env.md's first example (the benchmark env on the paper's move, a video written) prints its pasted
    output, with no warning that the env is out of date."""
    import warnings

    page = (ROOT / "docs" / "env.md").read_text()
    found = blocks(page)
    k = next(i for i, (lang, body) in enumerate(found) if lang == "python" and 'task="paper"' in body)
    code, shown = found[k][1], found[k + 1][1]
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        with contextlib.redirect_stdout(out):
            exec(compile(code, "env.md", "exec"), {})
    assert out.getvalue() == shown and (tmp_path / "episode.mp4").stat().st_size > 0


@pytest.mark.parametrize("name", ["env-card", "cli-reference"])
def test_the_docs_generated_blocks_are_what_the_code_generates(name):
    """docs/env.md's env card and docs/cli.md's option reference are in the repository (readable without a build),
    and they are what `python docs/hooks.py` writes from the code now. argparse's layout differs between Python
    versions: under another version than the one that wrote the block, the reference must name the same commands and
    options."""
    import importlib.util
    import sys

    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    assert spec is not None and spec.loader is not None
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    committed, version = hooks.committed_block(name)
    current = hooks.generated_block(name)
    if name == "env-card" or version == ".".join(map(str, sys.version_info[:2])):
        assert committed == current, "run: python docs/hooks.py"
    else:
        def words(text):
            return sorted(re.findall(r"(?:^#+ mjtraj [\w ]+$|--[\w-]+)", text, flags=re.M))

        assert words(committed) == words(current), "run: python docs/hooks.py"


def test_the_readmes_policy_interface_is_the_benchmark_envs():
    """The README's one-screen interface (observation shape and layout, action shape, scale and saturation) is
    UR5Track-v2's, measured on the env: each number it quotes fails this test when the env changes."""
    import gymnasium as gym
    import mjtraj.envs  # noqa: F401
    import numpy as np

    text = " ".join((ROOT / "README.md").read_text().split())
    env = gym.make("UR5Track-v2")
    obs, _ = env.reset(seed=3)
    core = env.unwrapped
    size, = env.observation_space.shape
    assert f"the ({size},) of `UR5Track-v2`" in text and obs.shape == (size,)
    from mjtraj.rl.adapters import load_any

    declared_nothing = load_any(lambda o: np.zeros(3)).settings().obs_size  # what rl eval gives such a policy
    assert f"receives one observation of shape ({declared_nothing},)" in text and declared_nothing == size - 2
    assert f"shape ({env.action_space.shape[0]},) in [−1, 1]" in text
    assert env.action_space.low.min() == -1 and env.action_space.high.max() == 1
    scale = float(core.settings.residual_scale)
    assert f"times {scale:g} N m" in text
    q, qd = core.loop.measured()
    assert np.array_equal(obs[0:3], q[0]) and np.array_equal(obs[3:6], qd[0])
    assert "(entries 0-17, rad and rad/s" in text and np.allclose(obs[12:15], obs[6:9] - obs[0:3])
    assert "the phase k/N (18)" in text and obs[18] == pytest.approx(0.0)
    task = core.reference.info["task"] if "task" in core.reference.info else None
    move = float(np.max(np.abs(core.reference.q[-1] - core.reference.q[0]))) if task is None else task
    assert "the move and the time to the motion's end (19-20)" in text and obs[19] == pytest.approx(move)
    limit = float(np.max(core.settings.torque_limit))
    assert f"±{limit:g} N m saturation" in text
    env.close()


QUOTED = [  # (page, its words with the number as a group, the source that measures it: a function of the repo)
    ("docs/results.md", r"validation chose, at ([\d,]+) of the run's ([\d,]+) steps",
     lambda: _baseline_steps()),
    ("CITATION.cff", r"\nversion: (\S+)\n", lambda: (_version(),)),
    ("README.md", r"version = \{(\S+)\}", lambda: (_version(),)),
]
"""Numbers a page quotes from elsewhere, each beside its source: the test fails when they differ."""


def _baseline_steps() -> tuple[str, str]:
    """The checkpoint of ppo_batched_s1, the protocol v1 table's baseline (baseline:best under v1's rule)."""
    import json

    run = json.loads((ROOT / "mjtraj/rl/baselines/ppo_batched_s1/run.json").read_text())
    return f"{int(run['best']['timesteps']):,}", f"{int(run['timesteps']):,}"


def _version() -> str:
    import mjtraj

    return mjtraj.__version__


@pytest.mark.parametrize("page, words, source", QUOTED, ids=[q[0] + ":" + q[1][:20] for q in QUOTED])
def test_a_quoted_number_is_its_sources(page, words, source):
    found = re.search(words, " ".join((ROOT / page).read_text().split()) if page.endswith(".md") else
                      (ROOT / page).read_text())
    assert found, (page, words)
    assert found.groups() == tuple(source())


def test_no_page_but_the_ones_that_measure_them_quotes_timings():
    """Timings live in the pages that measure them (docs/speed.md, docs/floor.md, docs/results.md, docs/benchmark.md,
    docs/testing.md and the CHANGELOG); the README, the env card, the command line's help and the other pages link
    there instead of quoting a number that goes stale."""
    from mjtraj.cli import build_parser

    duration = re.compile(r"\b\d+(?:\.\d+)? ?(?:s|ms|min|minutes|seconds|hours?) (?:a|per|each|on|in all)\b|"
                          r"\b(?:about|takes|took) \d+(?:\.\d+)? ?(?:s|ms|min|minutes|seconds|hours?)\b")
    pages = {"README.md": (ROOT / "README.md").read_text(), "docs/env.md": (ROOT / "docs/env.md").read_text()}
    parser = build_parser()
    pages["mjtraj --help"] = parser.format_help()
    for action in parser._subparsers._group_actions:  # type: ignore[union-attr]
        for name, sub in action.choices.items():
            pages[f"mjtraj {name} --help"] = " ".join(sub.format_help().split())
    for page, text in pages.items():
        assert not duration.findall(" ".join(text.split())), page


def test_the_published_v2_rows_that_succeeded_are_at_rest_and_not_below_their_floor():
    """docs/results/v2/eval.csv (protocol v2, 200 held-out scenarios per family, every method): every row whose status
    is ok ends within the settling band of its goal (2 % of the move) and below 0.05 rad/s, and scores at or above
    its scenario's floor (to the replay's tolerance, 1e-6): every control law's row, and on the nominal and
    aggressive families every row. On mismatched plants (the noisy family's too) the floor is the best minimum found
    from the laws' executions, an upper estimate, which a policy's execution may beat (docs/results.md says where
    one does)."""
    import csv

    from mjtraj.core.settle import SETTLE_BAND, SETTLE_SPEED

    with open(ROOT / "docs/results/v2/eval.csv", newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["status"] == "ok"]
    families = {r["family"] for r in rows}
    assert families == {"nominal", "aggressive", "mismatch", "noisy"} and len(rows) > 4000
    for r in rows:
        assert float(r["end_err"]) <= SETTLE_BAND * float(r["max_displacement"]), r["scenario"]
        assert float(r["end_speed"]) <= SETTLE_SPEED, r["scenario"]
        if not (r["policy"] and r["family"] in ("mismatch", "noisy")):
            assert float(r["cost_over_floor"]) >= 1.0 - 1e-6, (r["family"], r["scenario"], r["method"])
