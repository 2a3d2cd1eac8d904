"""Drivers by name for ``irlsim sim --driver``: ``simple`` (:class:`irlsim.sim.drivers.SimpleDriver`) and
``expert`` (:class:`irlsim.planner.expert.ExpertDriver`) and ``sumo`` (SUMO's own driver model,
:class:`irlsim.sim.drivers.SumoDriver`). The registry sits above both layers, so the
simulator never imports the planner."""

from __future__ import annotations

from collections.abc import Callable

from irlsim.errors import IrlsimError
from irlsim.planner.expert import make_expert_driver
from irlsim.road import Road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.drivers import Driver, SimpleDriver, SumoDriver

#: driver name -> factory(road, scenario config)
DRIVERS: dict[str, Callable[[Road, EpisodeConfig], Driver]] = {
    "simple": lambda road, cfg: SimpleDriver(road, cfg),
    "expert": make_expert_driver,
    "sumo": lambda road, cfg: SumoDriver(road, cfg),
}


def make_driver(name: str, road: Road, cfg: EpisodeConfig) -> Driver:
    """Instantiate a registered driver; unknown names give a one-line error listing the known ones."""
    if name not in DRIVERS:
        raise IrlsimError(f"unknown driver '{name}': choose one of {', '.join(sorted(DRIVERS))}")
    return DRIVERS[name](road, cfg)
