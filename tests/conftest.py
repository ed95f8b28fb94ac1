"""Shared fixtures: the nominal model, the paper scenario, its task, and a virtual display."""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np
import pytest

from mjtraj.core.model import load_model
from mjtraj.core.task import Task
from mjtraj.domain.scenario import Scenario, load_scenario


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
    """A virtual X display for the test's duration: Xvfb chooses a free display number and writes it once it
    accepts clients (-displayfd), so a busy machine or a display left by another run cannot race the tests."""
    xvfb = shutil.which("Xvfb")
    assert xvfb is not None, "Xvfb is needed (apt-get install xvfb; .ci/run installs it)"
    read, write = os.pipe()
    proc = subprocess.Popen([xvfb, "-displayfd", str(write), "-screen", "0", "640x480x24"], pass_fds=(write,),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    with os.fdopen(read) as ready:
        number = ready.readline().strip()  # blocks until the server is ready (or has exited: '')
    assert number.isdigit(), f"Xvfb did not start (exit code {proc.poll()})"
    yield f":{number}"
    proc.terminate()
    proc.wait()
