"""Plug-ins: a planner and a controller registered through entry points are accepted by name everywhere the built-in
ones are; a broken or clashing plug-in is one line from PluginError; a real package installed with pip works from the
command line."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from importlib.metadata import EntryPoint

import numpy as np
import pytest

from mjtraj import plugins
from mjtraj.core import planners
from mjtraj.core.closed_loop import ClosedLoop, LoopConfig
from mjtraj.core.planners import base
from mjtraj.exceptions import InvalidInputError, PluginError

MODULE = '''
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from mjtraj.core.controller import PID
from mjtraj.core.planners import Planner, sampled_reference


@dataclass(frozen=True)
class Ramp(Planner):
    """Constant speed from q0 to qg (a test plug-in)."""

    slope: float = 1.0
    name: ClassVar[str] = "ramp"

    def plan(self, task, model):
        s = task.times / task.duration
        return sampled_reference(self.name, task, s, np.full_like(s, 1.0 / task.duration), np.zeros_like(s))


def pid_again(config, dt, n, nsim):
    """The built-in PID law under another name."""
    return PID(config.gains.tiled(nsim), config.anti_windup)
'''


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """Entry points of a plug-in module written to tmp_path, as importlib.metadata would list them; the planner
    registry is restored afterwards."""
    (tmp_path / "toy_plugin.py").write_text(MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    points = {"mjtraj.planners": [EntryPoint("ramp", "toy_plugin:Ramp", "mjtraj.planners")],
              "mjtraj.controllers": [EntryPoint("pid_again", "toy_plugin:pid_again", "mjtraj.controllers")]}

    def use(points_by_group):
        monkeypatch.setattr(plugins, "group_entry_points", lambda group: points_by_group.get(group, []))
        plugins.plugins.cache_clear()

    registry, on_request = dict(base._REGISTRY), set(base._ON_REQUEST)
    use(points)
    yield use
    base._REGISTRY.clear()
    base._REGISTRY.update(registry)
    base._ON_REQUEST.clear()
    base._ON_REQUEST.update(on_request)
    plugins.plugins.cache_clear()


def test_a_plugin_planner_and_controller_work_by_name(installed, scenario):
    assert "ramp" in planners.available() and "ramp" not in planners.default_names()  # runs only when named
    reference = planners.make("ramp", slope=2.0).plan(scenario.task, scenario.model)
    np.testing.assert_allclose(reference.q[-1], scenario.task.qg)
    config = LoopConfig(scenario.loop.gains, controller="pid_again")
    mine = ClosedLoop(scenario.model, config).run([reference])
    built_in = ClosedLoop(scenario.model, scenario.loop).run([reference])
    np.testing.assert_array_equal(mine.dtau, built_in.dtau)  # the same law, by another name: the same numbers
    with pytest.raises(InvalidInputError, match=r"^planner 'ramp': unknown option 'speed'; valid: slope$"):
        planners.make("ramp", speed=1.0)


def test_broken_or_clashing_plugins_are_one_line_errors(installed):
    installed({"mjtraj.planners": [EntryPoint("lost", "no_such_module:Thing", "mjtraj.planners")]})
    with pytest.raises(PluginError, match=r"^plug-in 'lost' in mjtraj.planners: cannot load no_such_module:Thing "
                                          r"\(unknown package\): ModuleNotFoundError: No module named "
                                          r"'no_such_module'$"):
        planners.available()
    installed({"mjtraj.planners": [EntryPoint("cubic", "toy_plugin:Ramp", "mjtraj.planners")]})
    with pytest.raises(PluginError, match=r"^plug-in planner 'cubic': the name of a built-in planner$"):
        planners.make("cubic")
    installed({"mjtraj.controllers": [EntryPoint("pid", "toy_plugin:pid_again", "mjtraj.controllers")]})
    with pytest.raises(PluginError, match=r"^plug-in controller 'pid': the name of a built-in control law or "
                                          r"estimator$"):
        LoopConfig(_gains(), controller="pid")
    installed({"mjtraj.controllers": [EntryPoint("mpc_filter", "toy_plugin:pid_again", "mjtraj.controllers")]})
    with pytest.raises(PluginError, match=r"^plug-in controller 'mpc_filter': the name of a built-in control law or "
                                          r"estimator$"):
        LoopConfig(_gains(), controller="pid")
    installed({"mjtraj.planners": [EntryPoint("twice", "toy_plugin:Ramp", "mjtraj.planners"),
                                   EntryPoint("twice", "toy_plugin:pid_again", "mjtraj.planners")]})
    with pytest.raises(PluginError, match=r"^plug-in 'twice' in mjtraj.planners: registered twice, by "):
        planners.available()


def _gains():
    from mjtraj.domain.scenario import load_scenario

    return load_scenario().loop.gains


@pytest.mark.slow
def test_a_pip_installed_plugin_runs_in_mjtraj_compare(tmp_path):
    package = tmp_path / "toy"
    (package / "toy_plugin").mkdir(parents=True)
    (package / "toy_plugin" / "__init__.py").write_text(MODULE)
    (package / "pyproject.toml").write_text(textwrap.dedent('''
        [build-system]
        requires = ["setuptools>=61"]
        build-backend = "setuptools.build_meta"

        [project]
        name = "mjtraj-toy-plugin"
        version = "0.1"

        [project.entry-points."mjtraj.planners"]
        ramp = "toy_plugin:Ramp"

        [project.entry-points."mjtraj.controllers"]
        pid_again = "toy_plugin:pid_again"
        '''))
    pip = [sys.executable, "-m", "pip", "-q"]
    subprocess.run([*pip, "install", "--no-deps", "--no-build-isolation", str(package)], check=True)
    try:
        out = subprocess.run([sys.executable, "-m", "mjtraj", "compare", "--planners", "cubic,ramp", "--controller",
                              "pid_again", "--no-figures", "--out", str(tmp_path / "out")], check=True,
                             capture_output=True, text=True).stdout
    finally:
        subprocess.run([*pip, "uninstall", "-y", "mjtraj-toy-plugin"], check=True)
    assert "controller = pid_again," in out
    assert any(line.startswith("ramp ") for line in out.splitlines())


def test_the_documented_factory_signature_is_the_one_the_loop_calls(installed, scenario):
    """Every page that states a plug-in law factory's parameters states the four the loop passes: the toy plug-in
    takes exactly those (a fifth argument, or a missing one, would fail its call) and the loop builds its law."""
    import importlib
    import inspect
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    pages = [root / "docs" / name for name in ("api.md", "architecture.md", "design.md")]
    stated = {page.name: set(re.findall(r"factory\(([^)]*)\)", page.read_text())) for page in pages}
    assert stated == {page.name: {"config, dt, n, nsim"} for page in pages}
    assert re.findall(r"factory\(([^)]*)\)", inspect.getsource(plugins)) == ["config, dt, n, nsim"]
    pid_again = importlib.import_module("toy_plugin").pid_again
    assert ", ".join(inspect.signature(pid_again).parameters) == "config, dt, n, nsim"
    assert ClosedLoop(scenario.model, LoopConfig(scenario.loop.gains, controller="pid_again")).nsim == 1
