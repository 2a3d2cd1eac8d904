"""Where a vehicle inside a junction goes (real SUMO on a netgenerate grid, a scenario's own traffic):
one turning into the route has its way ahead along SUMO's lanes into the route's lane; one crossing the
route, or turning off it, has none."""

from __future__ import annotations

import numpy as np

from irlsim.road import load_road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
from tests.sim.test_turns import grid_scenario

#: from the street north of A1: left into the route's A1B1, or straight on south, across it
DEMAND = """<routes>
  <flow id="in" begin="0" end="90" period="3" from="A2A1" to="B1C1" departLane="best"/>
  <flow id="across" begin="1" end="90" period="3" from="A2A1" to="A1A0" departLane="best"/>
</routes>
"""


def test_a_car_turning_into_the_route_has_its_way_and_a_crossing_car_none(tmp_path):
    folder = grid_scenario(tmp_path, 2)
    (folder / "demand.rou.xml").write_text(DEMAND)
    toml = (folder / "scenario.toml").read_text()
    (folder / "scenario.toml").write_text(toml + '\n[traffic]\nroutes = ["demand.rou.xml"]\nwarmup = 20.0\n')
    road = load_road(scenario=folder)
    cfg = EpisodeConfig(name=str(folder), n_vehicles=0, max_time=25.0)
    ways, none = 0, 0
    with Simulation(road, cfg) as sim:
        sim.reset(0)
        while not sim.done:
            veh = sim.vehicles
            for i, vid in enumerate(veh.ids):
                lane = sim._api.vehicle.getLaneID(vid)
                if not lane.startswith(":A1_"):
                    continue
                way = None if veh.path is None else veh.path[i]
                if vid.startswith("across"):
                    assert way is None or np.isnan(way).all(), vid  # it leaves the route
                    none += 1
                    continue
                assert way is not None and np.isfinite(way).all(), vid
                ways += 1
                # it starts at the car's front and ends along the centre of one of the route's lanes
                assert np.hypot(way[0, 0] - veh.x[i], way[0, 1] - veh.y[i]) < 1.0
                s, d = road.to_frenet(way[-20:, 0], way[-20:, 1])
                assert np.abs(d[:, None] - road.lane_centres[None, :]).min(axis=1).max() < 0.2
                assert (np.diff(s) > 0.9).all()  # along the route, a metre a point
            sim.step()  # the ego stands at its start on the route's first edge
    assert ways > 5 and none > 5, (ways, none)
