"""Shared fixtures: the nominal model, the paper scenario, its task, and a virtual display."""

from __future__ import annotations

import os
import shutil
import subprocess
import time

import numpy as np
import pytest

from mjtraj.core.model import load_model
from mjtraj.core.task import Task
from mjtraj.study.scenario import Scenario, load_scenario


@pytest.fixture(scope="session")
def model():
    return load_model()


@pytest.fixture(scope="session")
def scenario() -> Scenario:
    return load_scenario()


@pytest.fixture(scope="session")
def task(scenario: Scenario) -> Task:
    return scenario.task


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


@pytest.fixture(scope="session")
def display():
    """A virtual X display for the test's duration."""
    xvfb = shutil.which("Xvfb")
    assert xvfb is not None, "Xvfb is needed (apt-get install xvfb; .ci/run installs it)"
    number = 90 + os.getpid() % 9
    proc = subprocess.Popen([xvfb, f":{number}", "-screen", "0", "640x480x24"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    time.sleep(1.0)
    yield f":{number}"
    proc.terminate()
    proc.wait()
