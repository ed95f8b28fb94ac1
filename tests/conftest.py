"""Shared fixtures: the nominal model, the paper scenario, and its task."""

from __future__ import annotations

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
