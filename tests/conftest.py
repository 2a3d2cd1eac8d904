"""Shared fixtures: the oval's Road (built once per session) and a headless libsumo Simulation.

libsumo holds one simulation per process: tests share the session ``sim`` (``reset(seed)`` reloads it in
a few ms); a test that makes its own Simulation closes the shared one, which restarts on its next reset.
"""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def road():
    from irlsim.road import load_road

    return load_road()


@pytest.fixture(scope="session")
def sim(road):
    from irlsim.sim.config import ScenarioConfig
    from irlsim.sim.simulation import Simulation

    s = Simulation(road, ScenarioConfig(laps=10, max_time=2000.0))
    yield s
    s.close()
