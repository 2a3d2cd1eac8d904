"""Roads as real networks make them: sidewalks, bike and bus lanes beside the car lanes (netgenerate's
and netconvert's guesses, as an OpenStreetMap import has them), and lanes of different widths on one
route. Every network here is built by SUMO's own tools into tmp_path."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import sumo_binary
from tests.road.test_scenario import STRAIGHT_NODES, make_scenario


def sumo_tool(tool: str, *args: str, cwd: Path) -> None:
    proc = subprocess.run([sumo_binary(tool), *args], cwd=cwd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def write_scenario(folder: Path, net: str, route: str) -> Path:
    (folder / "scenario.toml").write_text(f'[network]\nfile = "{net}"\n\n[route]\n{route}\n')
    return folder


@pytest.fixture(scope="module")
def walk_grid(tmp_path_factory) -> Path:
    """A 4 x 4 grid of two-lane roads with guessed sidewalks and bike lanes (SUMO lanes 0 and 1 of
    every edge; the car lanes are 2 and 3)."""
    folder = tmp_path_factory.mktemp("walkgrid")
    sumo_tool(
        "netgenerate",
        "--grid", "--grid.number", "4", "--grid.length", "200", "--default.lanenumber", "2",
        "--sidewalks.guess", "--bikelanes.guess", "--no-turnarounds", "true", "-o", "grid.net.xml",
        cwd=folder,
    )  # fmt: skip
    return write_scenario(folder, "grid.net.xml", 'edges = ["A0A1", "A1A2", "A2A3"]')


def lane_mid(road, lane_id: str) -> tuple[float, float]:
    """(s, d) of the middle of a SUMO lane's shape."""
    shape = np.asarray(road.net.getLane(lane_id).getShape())
    mid = shape[len(shape) // 2] if len(shape) > 2 else shape.mean(axis=0)
    s, d = road.to_frenet(np.array([mid[0]]), np.array([mid[1]]))
    return float(s[0]), float(d[0])


def test_sidewalks_and_bike_lanes_bound_the_road_but_are_not_its_lanes(walk_grid):
    road = load_road(scenario=walk_grid)
    assert road.n_lanes == 2 and road.lane_width == pytest.approx(3.2)
    assert road.layout.lanes == ((2, 3),) * 3
    for eid in road.edges:
        for k, sumo_lane in enumerate((2, 3)):  # the car lanes are route lanes 0 and 1, where SUMO has them
            _, d = lane_mid(road, f"{eid}_{sumo_lane}")
            assert d == pytest.approx(float(road.lane_center(k)), abs=0.05)
            assert int(road.lane_of_d(np.array(d))) == k
        for other in (0, 1):  # the sidewalk and the bike lane lie beyond the road's right edge: off-road
            _, d = lane_mid(road, f"{eid}_{other}")
            assert d < -road.half_road and int(road.lane_of_d(np.array(d))) == -1
    # the mission and the exits are about car lanes only: the right turns off the route are exits
    assert all(all(0 <= k < road.n_lanes for k in c.lanes) for c in road.checkpoints)
    assert {e.edge for e in road.exits} >= {"A1B1", "A2B2"}


def test_an_edge_without_a_car_lane_is_refused_by_name(tmp_path):
    folder = make_scenario(
        tmp_path / "bikeway",
        STRAIGHT_NODES,
        '<edge id="ab" from="a" to="b" numLanes="2"/>'
        '<edge id="bc" from="b" to="c" numLanes="1" allow="bicycle"/>',
        'edges = ["ab", "bc"]',
    )
    with pytest.raises(IrlsimError, match="edge 'bc' has no lane for passenger cars") as e:
        load_road(scenario=folder)
    assert "\n" not in str(e.value)


def test_lanes_of_different_widths_and_a_bus_lane_on_one_route(tmp_path):
    """400 m of a bus lane (3.5 m) and two car lanes 3.6 m wide, then 400 m of two lanes 3.0 m wide."""
    edges = (
        '<edge id="ab" from="a" to="b" numLanes="3" speed="20"><lane index="0" allow="bus" width="3.5"/>'
        '<lane index="1" width="3.6"/><lane index="2" width="3.6"/></edge>'
        '<edge id="bc" from="b" to="c" numLanes="2" speed="20" width="3.0"/>'
    )
    road = load_road(
        scenario=make_scenario(tmp_path / "widths", STRAIGHT_NODES, edges, 'edges = ["ab", "bc"]')
    )
    assert road.n_lanes == 2 and not road.lanes_vary
    assert road.layout.lanes == ((1, 2), (0, 1))
    assert road.lane_width in (3.0, 3.6)  # one width for the frame: the car lanes' median by length
    for lane_id, k in (("ab_1", 0), ("ab_2", 1), ("bc_0", 0), ("bc_1", 1)):
        _, d = lane_mid(road, lane_id)
        # the frame's approximation: a lane's real centre is within half the width difference of its own
        assert abs(d - float(road.lane_center(k))) <= 0.3 + 0.05
        assert int(road.lane_of_d(np.array(d))) == k
    _, d_bus = lane_mid(road, "ab_0")
    assert d_bus < -road.half_road  # the bus lane is off the road for the ego
    assert len(road.lane_shapes) == 2  # the lane shapes follow the car lanes on each edge
    for k, shape in enumerate(road.lane_shapes):
        _, d = road.to_frenet(shape[:, 0], shape[:, 1])
        assert (road.lane_of_d(d) == k).all()  # the junction's width step included


def test_a_line_that_meets_itself_is_found():
    """What makes a route frame project by progress (route.self_crossing) on plain polylines: a crossing,
    a route back along itself closer than the road is wide, and what is not either."""
    from irlsim.road.crossing import self_crossing

    cross = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [50.0, 100.0], [50.0, -50.0]])
    assert self_crossing(cross, False, 1.0) == pytest.approx((50.0, 0.0), abs=1.0)
    back = np.array([[0.0, 0.0], [300.0, 0.0], [300.0, 6.0], [0.0, 6.0]])  # a U-turn 6 m across
    assert self_crossing(back, False, 6.9) is not None and self_crossing(back, False, 5.0) is None
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 400, endpoint=False)) * 150.0] * 2, axis=1)
    circle[:, 1] = np.sin(np.linspace(0, 2 * np.pi, 400, endpoint=False)) * 150.0
    assert self_crossing(circle, True, 10.0) is None  # a loop meets itself only where it closes


def test_a_crossing_without_a_junction_is_refused_in_one_line():
    """route.check_same_level: the line crossing itself where both pieces touch one junction passes (at
    grade); where they share none (a bridge in a network without heights) it is refused in one line."""
    from irlsim.errors import IrlsimError
    from irlsim.road.crossing import check_same_level
    from irlsim.road.route import ReferenceShape

    cross = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [50.0, 100.0], [50.0, -50.0]])
    arcs = np.array([0.0, 100.0, 200.0, 250.0])  # one piece per segment
    at_grade = (frozenset("ab"), frozenset("bc"), frozenset("cd"), frozenset("da"))
    check_same_level(ReferenceShape(cross, np.zeros((4, 2)), arcs, at_grade), False)
    bridge = (frozenset("ab"), frozenset("bc"), frozenset("cd"), frozenset("de"))
    with pytest.raises(IrlsimError, match="crosses itself without a junction near \\(50, 0\\)") as e:
        check_same_level(ReferenceShape(cross, np.zeros((4, 2)), arcs, bridge), False)
    assert "\n" not in str(e.value)
