"""The ego's route in SUMO (real SUMO, a netgenerate grid): placed by moveToXY inside a junction nearer
another connection's lane than its own, SUMO counts it on that lane and cuts its route to that
connection's edges; back on an edge of its route, the ego has the rest of irlsim's route again. SUMO's
drivers see a moved vehicle coming through a junction by its route's next edges: with its route cut for
good, a car turning on its minor green at the next light drove into the ego going straight on its green."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from irlsim.road import load_road
from irlsim.sim import sumo_ego
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import EGO, Simulation
from tests.sim.test_turns import ROUTE, grid_scenario


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    return load_road(scenario=grid_scenario(tmp_path_factory.mktemp("egoroute"), 2))


def _place(sim, road, x: float, y: float, yaw: float) -> None:
    s, d = road.to_frenet(np.array([x]), np.array([y]))
    sim.step(dataclasses.replace(sim.ego, x=x, y=y, yaw=yaw, s=float(s[0]), d=float(d[0]), v=5.0))


@pytest.mark.parametrize("kept", [True, False])
def test_the_ego_has_its_route_again_once_back_on_it(grid, monkeypatch, kept):
    road = grid
    if not kept:  # the defect: the route stays cut
        monkeypatch.setattr(sumo_ego.EgoRoute, "keep", lambda self, api, ego: None)
    start = road.route_begin_s + 150.0  # on A0A1, 50 m before junction A1
    cfg = EpisodeConfig(
        name="g", n_vehicles=0, max_time=60.0, ego_start_random=False, ego_start_s=start, ego_start_speed=0.0
    )
    with Simulation(road, cfg) as sim:
        sim.reset(0)
        api = sim._api
        # inside junction A1, on the straight-on connection's lane (north), headed along it: not the ego's
        lane = road.net.getEdge(ROUTE[0]).getLane(1)
        via = next(c.getViaLaneID() for c in lane.getOutgoing() if c.getTo().getID() == "A1A2")
        (x0, y0), (x1, y1) = road.net.getLane(via).getShape()[:2]
        _place(sim, road, (x0 + x1) / 2, (y0 + y1) / 2, float(np.arctan2(y1 - y0, x1 - x0)))
        assert api.vehicle.getLaneID(EGO).startswith(":") and "A1A2" in api.vehicle.getRoute(EGO)  # cut
        # 20 m into the route's next edge, in its right lane
        (x0, y0), (x1, y1) = road.net.getEdge(ROUTE[1]).getLane(0).getShape()[:2]
        f = 20.0 / float(np.hypot(x1 - x0, y1 - y0))
        for k in range(3):
            _place(
                sim,
                road,
                x0 + f * (x1 - x0) + k * 0.5,
                y0 + f * (y1 - y0),
                float(np.arctan2(y1 - y0, x1 - x0)),
            )
        route = api.vehicle.getRoute(EGO)[api.vehicle.getRouteIndex(EGO) :]
    if kept:
        assert route == tuple(ROUTE[1:])
    else:
        assert route == (ROUTE[1],)
