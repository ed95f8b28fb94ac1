"""MkDocs hooks: pages generated from the code (the env card from its docstring, the CLI reference from the
parser), and the repository's own files the docs show (videos/, AUDIT.md and its figures, CHANGELOG.md)."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parent.parent
SHOWN = ("videos", "AUDIT_figures")
"""Folders of the repository served under their own names."""
SHOWN_FILES = ("AUDIT.md", "CHANGELOG.md")


def on_files(files: Files, config: Any) -> Files:
    for folder in SHOWN:
        for path in sorted((ROOT / folder).glob("*")):
            if path.is_file():
                files.append(File(f"{folder}/{path.name}", str(ROOT), config["site_dir"],
                                  config["use_directory_urls"]))
    for name in SHOWN_FILES:
        files.append(File(name, str(ROOT), config["site_dir"], config["use_directory_urls"]))
    return files


def env_card() -> str:
    from mjtraj.envs import UR5TrackEnv

    return inspect.getdoc(UR5TrackEnv) or ""


def cli_reference() -> str:
    import argparse
    import os

    os.environ["COLUMNS"] = "110"  # argparse wraps to the terminal: the same page on every machine
    from mjtraj.cli import build_parser

    parser = build_parser()
    out = ["```text", parser.format_help().rstrip(), "```"]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out += ["", f"## mjtraj {name}", "", "```text", sub.format_help().rstrip(), "```"]
                for inner in sub._actions:
                    if isinstance(inner, argparse._SubParsersAction):
                        for name2, sub2 in inner.choices.items():
                            out += ["", f"### mjtraj {name} {name2}", "", "```text", sub2.format_help().rstrip(),
                                    "```"]
    return "\n".join(out)


MARKERS = {"<!-- env-card -->": env_card, "<!-- cli-reference -->": cli_reference}


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    for marker, make in MARKERS.items():
        if marker in markdown:
            markdown = markdown.replace(marker, make())
    return site_links(markdown, page.file.src_uri)


def site_links(markdown: str, page: str) -> str:
    """The repository's links as the site serves them: a page at docs/X.md links `../videos/...` and
    `../AUDIT.md` (right on GitHub and in a checkout), which the site serves beside the page (on_files)."""
    depth = page.count("/")
    up = "../" * (depth + 1)
    for name in (*SHOWN, *SHOWN_FILES):
        markdown = markdown.replace(f"]({up}{name}", f"]({'../' * depth}{name}")
    return markdown
