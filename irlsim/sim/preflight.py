"""What a command checks of its roads once, before any work (collect, drive): each leaves the ego a
start and SUMO loads its files; a one-line IrlsimError otherwise, never an episode's error retried in a
worker. Apart from :mod:`.start` and :mod:`.simulation` because it needs both."""

from __future__ import annotations

from dataclasses import replace

from irlsim.road import load_road
from irlsim.road.scenario import Scenarios
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import check_sumo_inputs
from irlsim.sim.start import check_start


def check_starts(scenario: EpisodeConfig, names: tuple[str, ...], scenarios: Scenarios | None = None) -> None:
    """Every road ``names`` (scenario names) leaves the ego a start with the episode settings
    ``scenario``, and SUMO loads its files (network, vehicle types, demand): a one-line IrlsimError
    otherwise, before a command's work (collect, drive), not an episode's error retried in a worker.
    ``scenarios``: the command's, which reads each scenario file once (None: read here)."""
    scenarios = scenarios or Scenarios()
    for name in names:
        road = load_road(scenario=scenarios(name))
        check_start(road, replace(scenario, name=name))
        check_sumo_inputs(road)
