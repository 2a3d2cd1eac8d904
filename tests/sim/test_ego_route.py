"""The ego's route in SUMO (real SUMO): placed by moveToXY anywhere inside a junction, even nearer another
connection's lane than its own, the ego keeps the route irlsim drives. SUMO's drivers see a moved vehicle
coming through a junction by its route's next edges: with a route cut to another connection's (SUMO's
mode 2 of moveToXY), a car turning on a minor green drove into the ego going straight on its green."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from irlsim.road import load_road
from irlsim.sim import simulation
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import EGO, Simulation
from tests.road.test_scenario import make_scenario
from tests.sim.test_yielding import X_EDGES, X_NODES


def _via(api, lane: str, to: str) -> str:
    """The internal lane of the connection from ``lane`` to ``to``."""
    return next(c[4] for c in api.lane.getLinks(lane) if c[0] == to)


@pytest.mark.parametrize("mode", [simulation.KEEP_ROUTE, 2])
def test_the_ego_keeps_its_route_where_another_turn_lies_nearer(tmp_path, monkeypatch, mode):
    folder = make_scenario(tmp_path / "x", X_NODES, X_EDGES, 'edges = ["wj", "je"]')  # straight on
    road = load_road(scenario=folder)
    (signal,) = road.signals
    cfg = EpisodeConfig(
        name="x", max_time=60.0, ego_start_random=False, ego_start_s=signal.s - 60.0, ego_start_speed=0.0
    )
    monkeypatch.setattr(simulation, "KEEP_ROUTE", mode)
    with Simulation(road, cfg) as sim:
        sim.reset(0)
        api = sim._api
        own = _via(api, "wj_0", "je_0")
        (_, y_own), _ = api.lane.getShape(own)
        # the ego veering left inside the junction, 1.5-2.5 m off its own lane: on the left turn's lane
        left = _via(api, "wj_0", "jn_0")
        shape = [*api.lane.getShape(left), *api.lane.getShape(_via(api, left, "jn_0"))]
        x, y = next(p for p in shape if 1.5 < p[1] - y_own < 2.5)
        s, d = road.to_frenet(np.array([x]), np.array([y]))
        sim.step(dataclasses.replace(sim.ego, x=x, y=y, yaw=0.3, s=float(s[0]), d=float(d[0]), v=5.0))
        assert api.vehicle.getPosition(EGO) == pytest.approx((x, y), abs=1e-6)  # its exact pose either way
        route, lane = api.vehicle.getRoute(EGO), api.vehicle.getLaneID(EGO)
    if mode == 2:  # the defect: SUMO took the ego for a car turning left
        assert route == ("wj", "jn") and lane != own
    else:
        assert route == ("wj", "je") and lane == own
