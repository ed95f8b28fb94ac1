"""The layers: every import (function-level ones included) goes down or sideways, never up, and forms no cycle;
envs and media never import study (they build on the domain and core); envs and rl use only the public names of the
layers below them; no public name hides a submodule."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = {"mjtraj": ROOT / "mjtraj", "mjtraj.envs": ROOT / "envs"}
"""Package name -> folder (envs/ is installed as mjtraj.envs)."""
BASE = ("mjtraj.exceptions", "mjtraj.checks", "mjtraj.files", "mjtraj.versions", "mjtraj.plugins", "mjtraj._lazy",
        "mjtraj._checkout", "mjtraj._registration", "mjtraj.threads")
APP = ("mjtraj", "mjtraj.cli", "mjtraj.bench", "mjtraj.bench_busy", "mjtraj.golden", "mjtraj.__main__")
LAYERS = ["base", "core", "domain", "study", "media", "envs", "rl", "app"]
PUBLIC_BASE = ("mjtraj.exceptions", "mjtraj.checks", "mjtraj.files", "mjtraj.versions", "mjtraj.plugins",
               "mjtraj.threads")


def layer(module: str) -> str:
    """The layer a module of mjtraj belongs to."""
    if module in BASE:
        return "base"
    if module in APP or module.startswith("mjtraj.cli."):  # the command, one module per subcommand
        return "app"
    part = module.split(".")[1]
    if part in ("core", "domain", "study", "media", "envs", "rl"):
        return part
    raise AssertionError(f"{module}: not placed in a layer; add it to a layer folder")


def modules() -> dict[str, Path]:
    """Every module of the package (as installed) and its source file."""
    out = {}
    for package, folder in SOURCES.items():
        for path in sorted(folder.rglob("*.py")):
            parts = list(path.relative_to(folder).with_suffix("").parts)
            if package == "mjtraj" and parts[0] == "envs":
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([package, *parts])] = path
    return out


def type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                lines.update(range(child.lineno, (child.end_lineno or child.lineno) + 1))
    return lines


def imports(path: Path, module: str) -> list[tuple[str, tuple[str, ...], bool]]:
    """(imported module, imported names, runtime?) for every import statement of mjtraj in the file, at any depth."""
    tree = ast.parse(path.read_text())
    typing_only = type_checking_lines(tree)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, (), node.lineno not in typing_only) for a in node.names if a.name.startswith("mjtraj")]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{module}: relative import at line {node.lineno}"
            if node.module and node.module.startswith("mjtraj"):
                out.append((node.module, tuple(a.name for a in node.names), node.lineno not in typing_only))
    return out


def exported(module: str) -> set[str]:
    """The __all__ of a package or module, read from its source."""
    tree = ast.parse(modules()[module].read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "__all__" for t in node.targets):
            return set(ast.literal_eval(node.value))
    return set()


def test_every_module_is_in_a_layer_and_imports_go_down():
    upward = []
    for module, path in modules().items():
        mine = LAYERS.index(layer(module))
        for target, _, _ in imports(path, module):
            theirs = LAYERS.index(layer(target))
            if theirs > mine:
                upward.append(f"{module} ({layer(module)}) imports {target} ({layer(target)})")
    assert upward == []


@pytest.mark.slow
def test_no_import_cycles():
    graph = {module: sorted({target for target, _, runtime in imports(path, module) if runtime and target != module})
             for module, path in modules().items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph.get(v, []):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    assert cycles == []


@pytest.mark.parametrize("user", ["envs", "media"])
def test_envs_and_media_never_import_study(user):
    """The env and the media layer stand on the domain layer and core alone: no import of study at any depth
    (TYPE_CHECKING ones included), so that the experiments can change without touching the env."""
    found = [f"{module} imports {target}" for module, path in modules().items() if layer(module) == user
             for target, _, _ in imports(path, module) if layer(target) == "study"]
    assert found == []


def test_the_study_rule_sees_a_study_import(tmp_path):
    """The oracle of the rule: an import of study, even a type-only one, is found in a file that has it."""
    path = tmp_path / "probe.py"
    path.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from mjtraj.study.sweep import Row\n")
    assert [layer(target) for target, _, _ in imports(path, "mjtraj.media.probe")] == ["study"]


@pytest.mark.parametrize("user", ["envs", "rl"])
def test_envs_and_rl_use_only_public_names(user):
    """Below their own layer, envs and rl import from a layer's package (names in its __all__) or from the public
    base modules, never from a layer's inner modules."""
    leaks = []
    for module, path in modules().items():
        if layer(module) != user:
            continue
        for target, names, _ in imports(path, module):
            if layer(target) == user or target in PUBLIC_BASE:
                continue
            if target == "mjtraj._lazy" and path.name == "__init__.py":
                continue
            if target not in ("mjtraj.core", "mjtraj.domain", "mjtraj.study", "mjtraj.media", "mjtraj.envs"):
                leaks.append(f"{module} imports the inner module {target}")
                continue
            leaks += [f"{module} imports {target}.{name}, not in its __all__" for name in names
                      if name not in exported(target)]
    assert leaks == []


def test_no_public_name_hides_a_submodule():
    """`mjtraj.study.compare` must not be a function where a module `mjtraj/study/compare.py` exists, and so on."""
    found = modules()
    hidden = []
    for package in ("mjtraj", "mjtraj.core", "mjtraj.domain", "mjtraj.study", "mjtraj.media", "mjtraj.envs",
                    "mjtraj.rl", "mjtraj.core.planners"):
        hidden += [f"{package}.{name}" for name in exported(package) if f"{package}.{name}" in found]
    assert hidden == []


def test_the_walk_sees_function_level_imports():
    """The oracle of the walk itself: a known function-level import is found."""
    found = imports(modules()["mjtraj.cli.compare"], "mjtraj.cli.compare")
    assert ("mjtraj.study.comparison", ("compare", "comparison_record"), True) in found
