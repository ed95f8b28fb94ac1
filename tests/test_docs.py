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


@pytest.mark.parametrize("page, cited, headers", [
    ("README.md", "docs/results/v2", ("| method | nominal: J / cubic+adaptive CT, P(improve) |",)),
    ("docs/results.md", "docs/results/best", ("| method | nominal: J / cubic+PID, P(improve) |",
                                              "| method | nominal: J / floor |")),
])
def test_the_result_tables_are_the_cited_summarys_cells(page, cited, headers):
    """Every cell of a page's tables of the control laws (the README's protocol v2 table, results.md's protocol v1
    tables) is the cell of the same method and column in the SUMMARY.md the page cites (written by the command shown
    beside them), not typed by hand."""
    text = (ROOT / page).read_text()
    summary = (ROOT / cited / "SUMMARY.md").read_text()
    link = cited.removeprefix("docs/") if page.startswith("docs/") else cited
    assert f"]({link}/SUMMARY.md)" in text and f"--out {cited}" in text
    for header in headers:
        shown, source = _table(text, header), _table(summary, header)
        assert shown and set(shown) <= set(source)
        for method, cells in shown.items():
            assert cells == {column: source[method][column] for column in cells}, method


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
