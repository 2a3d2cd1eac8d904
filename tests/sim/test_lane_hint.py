"""irlsim.sim.sumo_ego.ego_lane_hint in real SUMO: a moveToXY ego that changes lanes is counted by SUMO on
the lane its body has entered (so that lane's drivers see it), and on its centre's lane without the hint
or when its body sticks into a lane it is leaving."""

from __future__ import annotations

import numpy as np
import pytest

from irlsim.road import load_road
from irlsim.road.network import sumo_binary
from irlsim.sim.sumo_ego import NO_HINT, ego_lane_hint
from irlsim.sim.types import EgoState

EDGE = "A_S1"


@pytest.fixture()
def sumo():
    import libsumo

    road = load_road(scenario="oval")
    libsumo.start([sumo_binary("sumo"), "-n", str(road.net_file), "--step-length", "0.1", "--no-step-log"])
    libsumo.route.add("r", [EDGE, "S1_X1"])
    libsumo.vehicle.add("ego", "r", departLane="2", departPos="30", departSpeed="0")
    libsumo.vehicle.setSpeedMode("ego", 0)
    libsumo.simulationStep()
    yield libsumo, road
    libsumo.close()


def _state(road, s: float, d: float, d_dot: float) -> EgoState:
    x, y = road.to_xy(np.array([s]), np.array([d]))
    lane = int(road.lane_of_d(np.array([d]))[0])
    return EgoState(t=0.0, x=float(x[0]), y=float(y[0]), yaw=0.0, v=0.0, a=0.0, s=s, d=d, d_dot=d_dot,
                    d_ddot=0.0, lane=lane)  # fmt: skip


def _placed(api, road, state: EgoState, on: bool) -> int:
    """The route lane SUMO counts the ego on after placing it at ``state``."""
    hint = ego_lane_hint(on, api, "ego", road, state, 1.8)
    api.vehicle.moveToXY("ego", *hint, state.x, state.y, 90.0, keepRoute=2)
    api.simulationStep()
    return road.layout.route_lane(road.edges.index(EDGE), api.vehicle.getLaneIndex("ego"))


def test_sumo_counts_a_changing_ego_on_the_lane_its_body_entered(sumo):
    api, road = sumo
    x, y = api.vehicle.getPosition("ego")
    s0 = float(road.to_frenet(np.array([x]), np.array([y]))[0][0])  # where it departed, lane 2
    centre = float(road.lane_center(2))
    # moving right from lane 2 (its centre 3.2 m left of lane 1's): within the lane, no hint, lane 2
    inside = _state(road, s0, centre - 0.5, -1.0)
    assert (
        ego_lane_hint(True, api, "ego", road, inside, 1.8) == NO_HINT
        and _placed(api, road, inside, True) == 2
    )
    # the body 0.3 m into lane 1 and moving there: with the hint SUMO counts it on lane 1, without on lane 2
    entered = _state(road, s0 + 1.0, centre - 1.0, -1.0)
    assert _placed(api, road, entered, False) == 2
    assert _placed(api, road, entered, True) == 1
    # the same offset while moving back into lane 2 (a lane change given up): its centre's lane
    assert ego_lane_hint(True, api, "ego", road, _state(road, s0 + 2.0, centre - 1.0, +1.0), 1.8) == NO_HINT
    # past the boundary, the centre in lane 1, the body still in lane 2 and leaving it: lane 1 either way
    past = _state(road, s0 + 3.0, centre - 1.9, -1.0)
    assert ego_lane_hint(True, api, "ego", road, past, 1.8) == NO_HINT and _placed(api, road, past, True) == 1
    assert ego_lane_hint(False, api, "ego", road, entered, 1.8) == NO_HINT  # off: never a hint
