"""Packaging: the public names import, documented defaults match, and the wheel carries its data files."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import mjtraj

ROOT = Path(__file__).resolve().parents[1]



def test_all_names_import():
    for name in mjtraj.__all__:
        assert getattr(mjtraj, name) is not None



def _design_table(heading: str) -> dict[str, tuple[str, str]]:
    """docs/design.md's table under `heading`: option -> (default, values), as written."""
    text = (ROOT / "docs" / "design.md").read_text()
    section = text[text.index(heading):]
    rows = {}
    for line in section.splitlines()[1:]:
        if line.startswith("#"):
            break
        cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
        if line.startswith("|") and len(cells) == 3 and cells[0] not in ("option", "setting", "") \
                and set(cells[0]) != {"-"}:
            rows[cells[0]] = (cells[1], cells[2])
    return rows


def test_documented_loop_defaults_match_the_docs():
    """docs/design.md's table "Loop options, declared once" names every LoopConfig option with its default and, for
    a named choice, its valid values: the page is read here, and each default is parsed from its text."""
    import dataclasses
    import math

    from mjtraj.core.closed_loop import LoopConfig
    from mjtraj.core.options import declared_options, resolved_choices

    table = _design_table("### Loop options, declared once")
    declared = {f.name: (f.default, declaration) for f, declaration, _ in declared_options(LoopConfig)}
    assert list(table) == list(declared)
    for name, (default, declaration) in declared.items():
        written, values = table[name]
        assert default is not dataclasses.MISSING, name
        if isinstance(default, str):
            assert written == default, name
        elif written == "π rad":
            assert default == math.pi, name
        else:
            assert float(written) == default and type(default)(written) == default, name
        choices = resolved_choices(declaration)
        if choices is not None and isinstance(default, str):
            assert values == ", ".join(choices), name
        elif choices is not None:
            assert values.startswith(" or ".join(map(str, choices)) + " "), name
        elif declaration.minimum is not None:
            assert values.startswith(f"≥ {declaration.minimum:g}"), name
        else:
            assert declaration.positive and values.startswith("> 0"), name


def test_documented_nonlinear_settings_match_the_code():
    """docs/design.md's table "The nonlinear planners' settings" names every field of NonlinearSettings and, as
    sqp.NAME, of SqpSettings, in order, each with its default as written in the code (a Python expression)."""
    import dataclasses

    from mjtraj.core.planners.nonlinear import NonlinearSettings
    from mjtraj.core.planners.sqp import SqpSettings

    table = _design_table("### The nonlinear planners' settings")
    code = {**{f.name: getattr(NonlinearSettings(), f.name) for f in dataclasses.fields(NonlinearSettings)
               if f.name != "sqp"},
            **{f"sqp.{f.name}": getattr(SqpSettings(), f.name) for f in dataclasses.fields(SqpSettings)}}
    assert list(table) == list(code)
    for name, (written, _) in table.items():
        assert eval(written, {"__builtins__": {}}) == code[name], name  # noqa: S307 - the page's own literals


@pytest.mark.slow
def test_wheel_contains_model_and_scenario(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True, capture_output=True)
    wheel = next(tmp_path.glob("mjtraj-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    assert "mjtraj/assets/ur5_3dof.xml" in names
    assert "mjtraj/domain/scenarios/paper.toml" in names
    assert {"mjtraj/envs/__init__.py", "mjtraj/envs/ur5_track.py", "mjtraj/core/closed_loop.py"} <= set(names)
    assert "mjtraj/py.typed" in names
    assert not any(n.startswith(("envs/", "tests/")) for n in names)
    from mjtraj.rl.baselines import baseline_names, baseline_path

    for name in baseline_names():  # the shipped baselines, policy and record, so that baseline:NAME loads anywhere
        if baseline_path(name).suffix in (".pt", ".npz"):  # a batched run's module or a plan carries its record
            wanted = {f"mjtraj/rl/baselines/{name}/policy{baseline_path(name).suffix}",
                      f"mjtraj/rl/baselines/{name}/run.json"}
        else:
            wanted = {f"mjtraj/rl/baselines/{name}/policy.zip", f"mjtraj/rl/baselines/{name}/policy.json"}
        assert wanted <= set(names), name
    assert any(n.endswith("LICENSE") for n in names)



def _fresh(code: str, **env: str) -> str:
    """Run `code` in a new interpreter without MUJOCO_GL (unless given); its stdout."""
    import os

    clean = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    done = subprocess.run([sys.executable, "-c", code], env={**clean, **env}, capture_output=True, text=True,
                          check=True)
    return done.stdout.strip()


def test_import_is_light_and_sets_no_environment():
    """`import mjtraj` and the pure-numpy `mjtraj.core.lqr` load neither MuJoCo, SciPy nor Gymnasium, and leave
    MUJOCO_GL unset."""
    out = _fresh("import os, sys; import mjtraj, mjtraj.core.lqr; "
                 "print([m for m in ('mujoco', 'scipy', 'gymnasium', 'mjtraj.core.closed_loop') if m in sys.modules]);"
                 " print(os.environ.get('MUJOCO_GL'))")
    assert out.splitlines() == ["[]", "None"]


@pytest.mark.slow
def test_lazy_names_resolve_to_their_modules():
    out = _fresh("import sys, mjtraj; c = mjtraj.compare; "
                 "print(c.__module__, 'mjtraj.study.comparison' in sys.modules)")
    assert out == "mjtraj.study.comparison True"


@pytest.mark.slow
def test_an_episode_loads_nothing_of_study():
    """The env stands on the domain layer and core at run time too (the layer test reads the imports): a mismatch
    episode with its clairvoyant floor, rendered, loads no module of mjtraj.study."""
    out = _fresh("import sys, gymnasium as gym, numpy as np; import mjtraj.envs; "
                 "env = gym.make('UR5TrackMismatch-v1', floor=True, render_mode='rgb_array', width=64, height=48); "
                 "env.reset(seed=0); done = False\n"
                 "while not done: *_, done, _, info = env.step(np.zeros(3, np.float32))\n"
                 "env.render(); print(np.isfinite(info['metrics']['floor']), "
                 "sorted(m for m in sys.modules if m.startswith('mjtraj.study')))", MUJOCO_GL="osmesa")
    assert out.splitlines()[-1] == "True []"


@pytest.mark.slow
@pytest.mark.parametrize(("code", "made"), [
    ("import gymnasium as gym; import mjtraj; env = gym.make('UR5Track-v0')", "UR5TrackEnv"),
    ("import mjtraj; import gymnasium as gym; env = gym.make('UR5Track-v0')", "UR5TrackEnv"),
    ("import mjtraj.core.lqr, gymnasium as gym; env = gym.make_vec('UR5Track-v0', num_envs=2, "
     "vectorization_mode='vector_entry_point')", "UR5TrackVectorEnv"),
    ("import mjtraj.envs, gymnasium as gym; env = gym.make('UR5Track-v0')", "UR5TrackEnv"),
    ("import gymnasium as gym; env = gym.make('mjtraj:UR5Track-v0')", "UR5TrackEnv"),
])
def test_env_registration(code, made):
    """Every import order registers UR5Track-v0 with mjtraj's env class (or its native vector env), and the env it
    makes resets to an observation inside its own observation space."""
    out = _fresh(code + "; obs, _ = env.reset(seed=0); u = env.unwrapped; "
                 "print(env.spec.id, type(u).__module__, type(u).__name__, env.observation_space.contains(obs))",
                 MUJOCO_GL="osmesa")
    module = "vector" if made == "UR5TrackVectorEnv" else "ur5_track"
    assert out.splitlines()[-1] == f"UR5Track-v0 mjtraj.envs.{module} {made} True"


def test_recorded_versions_are_the_installed_distributions():
    """versions() reads an imported module's __version__; importlib.metadata is the oracle."""
    from importlib import metadata

    import gymnasium  # noqa: F401 - imported, so that versions() reads its __version__
    import mujoco  # noqa: F401
    import scipy  # noqa: F401

    from mjtraj.versions import LIBRARIES, library_version, versions

    recorded = versions()
    assert recorded["mjtraj"] == mjtraj.__version__
    for name in LIBRARIES:
        assert recorded[name] == library_version(name) == metadata.version(name)
    assert library_version("no-such-distribution-mjtraj") == ""


def test_one_version_string_everywhere():
    """The package, its metadata, CITATION.cff and the README's BibTeX name one version."""
    import re

    from mjtraj.versions import __version__

    citation = re.search(r"^version: (\S+)$", (ROOT / "CITATION.cff").read_text(), flags=re.M)
    bibtex = re.search(r"version = \{([^}]+)\}", (ROOT / "README.md").read_text())
    project = re.search(r'^version = "([^"]+)"$', (ROOT / "pyproject.toml").read_text(), flags=re.M)
    assert citation and bibtex and project
    assert {citation.group(1), bibtex.group(1), project.group(1)} == {__version__}


def test_every_shipped_baseline_folder_is_a_declared_package():
    """setuptools ships a data-only folder without warning only where it is declared (pyproject.toml's packages):
    a baseline added without its line would warn at every build (and a future setuptools may leave it out)."""
    from mjtraj.domain.scenario import tomllib

    declared = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    folders = {f"mjtraj.rl.baselines.{p.name}" for p in (ROOT / "mjtraj/rl/baselines").iterdir()
               if p.is_dir() and p.name != "__pycache__"}
    assert folders and folders <= declared, sorted(folders - declared)
