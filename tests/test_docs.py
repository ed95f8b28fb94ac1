"""What the README and the docs show runs, and prints what they say it prints."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

from mjtraj.rl.evaluate import evaluate

ROOT = Path(__file__).resolve().parent.parent


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block of a Markdown text."""
    return re.findall(r"```(\w*)\n(.*?)```", text, flags=re.S)


def test_the_readmes_env_example_prints_what_the_readme_shows():
    found = blocks((ROOT / "README.md").read_text())
    index = next(i for i, (lang, body) in enumerate(found) if lang == "python" and "UR5TrackMismatch-v1" in body)
    code, (_, shown) = found[index][1], found[index + 1]
    out = io.StringIO()
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
