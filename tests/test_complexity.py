"""No function of mjtraj/ or envs/ above cyclomatic complexity LIMIT (radon's count) outside numba kernels: a hub is
split into named stages, each a small function with one job (issue #56). Numba kernels stay whole: a call between
compiled functions costs, and their loops are the arithmetic itself."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

from radon.complexity import add_inner_blocks, cc_visit

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("mjtraj", "envs")
LIMIT = 25
BEING_SPLIT: set[tuple[str, str]] = set()
"""Functions still above LIMIT while their split is under way in a change of its own: none now. An entry is removed
as its function comes down to LIMIT (the test fails on an entry no longer needed)."""
NUMBA_MODULES = ("numba", "mjtraj.core.planners.numba_cache")
"""Where the compiling decorators come from: numba, or mjtraj's cache-aware re-export of its njit."""


def _name(node: ast.expr) -> str:
    """`njit` for `njit`, `numba.njit`, `njit(...)` and `numba.njit(...)`; '' for anything else."""
    if isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "numba":
        return node.attr
    return node.id if isinstance(node, ast.Name) else ""


def numba_kernels(tree: ast.Module) -> set[int]:
    """The lines of the functions numba compiles: decorated by numba's njit or jit (imported from NUMBA_MODULES, or
    `numba.njit`), directly, called with options, or through a module-level alias (`_compiled = njit(...)`)."""
    compilers = {"njit", "jit"} if any(isinstance(node, ast.Import) and any(a.name == "numba" for a in node.names)
                                       for node in tree.body) else set()
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.module in NUMBA_MODULES:
            compilers |= {a.asname or a.name for a in node.names if a.name in ("njit", "jit")}
    for node in tree.body:
        if isinstance(node, ast.Assign) and _name(node.value) in compilers and isinstance(node.value, ast.Call):
            compilers |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    return {node.lineno for node in ast.walk(tree) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            and any(_name(d) in compilers for d in node.decorator_list)}


@functools.cache
def complexities() -> dict[tuple[str, str], int]:
    """(file, function) -> radon's cyclomatic complexity, for every function, method and closure outside numba
    kernels; a method is named Class.method. Computed once per session (about a second)."""
    out = {}
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            source = path.read_text()
            kernels = numba_kernels(ast.parse(source))
            for block in add_inner_blocks(cc_visit(source)):
                if not hasattr(block, "is_method") or block.lineno in kernels:  # a class, or a kernel
                    continue
                name = f"{block.classname}.{block.name}" if block.classname else block.name
                out[(path.relative_to(ROOT).as_posix(), name)] = block.complexity
    return out


def test_no_function_outside_numba_kernels_is_above_the_limit():
    """Split a function above LIMIT into named stages (each with one job and a docstring)."""
    above = {key: value for key, value in complexities().items() if value > LIMIT}
    new = sorted(f"{path}: {name} ({value})" for (path, name), value in above.items()
                 if (path, name) not in BEING_SPLIT)
    assert new == [], f"cyclomatic complexity above {LIMIT}: {', '.join(new)}"
    done = sorted(f"{path}: {name}" for path, name in BEING_SPLIT - set(above))
    assert done == [], f"no longer above {LIMIT} (remove from BEING_SPLIT): {', '.join(done)}"


def test_the_walk_counts_and_recognises_kernels():
    """The oracles of the walk: a known kernel of each kind is recognised and left out, a function and a method (by
    its class's name) are counted, and every way of naming numba's decorators is recognised."""
    kernels = {path: numba_kernels(ast.parse((ROOT / path).read_text())) for path in (
        "mjtraj/core/planners/tracking.py", "mjtraj/core/planners/tree_dynamics.py")}
    source = (ROOT / "mjtraj/core/planners/tracking.py").read_text()
    riccati = next(b for b in cc_visit(source) if b.name == "_riccati")
    assert riccati.lineno in kernels["mjtraj/core/planners/tracking.py"]  # @njit
    source = (ROOT / "mjtraj/core/planners/tree_dynamics.py").read_text()
    rk4 = next(b for b in cc_visit(source) if b.name == "_rk4_steps")
    assert rk4.lineno in kernels["mjtraj/core/planners/tree_dynamics.py"]  # @_compiled, _compiled = njit(...)
    found = complexities()
    assert ("mjtraj/core/planners/tracking.py", "_riccati") not in found
    assert ("mjtraj/core/planners/sqp.py", "gauss_newton_sqp") in found
    assert ("envs/settings.py", "TrackSettings.scenario") in found
    tree = ast.parse("import numba\nfrom numba import njit as fast\nwrapped = numba.njit(cache=True)\n"
                     "@fast\ndef a(): pass\n@numba.jit(nopython=True)\ndef b(): pass\n@wrapped\ndef c(): pass\n"
                     "@other\ndef d(): pass\n")
    assert numba_kernels(tree) == {5, 7, 9}
