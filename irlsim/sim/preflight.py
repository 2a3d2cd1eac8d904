"""What a command checks of its roads once, before any work (collect, drive): each leaves the ego a
start and SUMO loads its files; a one-line IrlsimError otherwise, never an episode's error retried in a
worker. Apart from :mod:`.start` and :mod:`.simulation` because it needs both."""

from __future__ import annotations

import importlib
from dataclasses import replace
from pathlib import Path

from irlsim.road import Road, load_road
from irlsim.road.network import SUMO_NET_DIR, VTYPES_FILE
from irlsim.road.scenario import Scenarios
from irlsim.sim import simulation
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.inputs import probe
from irlsim.sim.start import check_start


def check_sumo_inputs(road: Road, vtypes_file: str | Path | None = None) -> None:
    """SUMO loads ``road``'s files, checked before a command's episodes (:func:`.inputs.probe`)."""
    if simulation._ACTIVE is not None:
        simulation._ACTIVE.close()  # libsumo: one simulation per process
    probe(
        importlib.import_module("libsumo"),
        road,
        Path(vtypes_file) if vtypes_file else SUMO_NET_DIR / VTYPES_FILE,
    )


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
