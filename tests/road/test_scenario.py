"""Scenario files and roads on networks other than the oval: small hand-made networks built with SUMO's
netconvert whose answer is known (lanes, exits, stops, the mission), the shipped scenarios, and the
one-line refusals of what the tool cannot drive."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.scenario import load_scenario, shipped_scenarios

CFG = """<configuration>
    <input><node-files value="net.nod.xml"/><edge-files value="net.edg.xml"/>{con}</input>
    <processing><no-turnarounds value="true"/>{extra}</processing>
    <report><no-warnings value="true"/></report>
</configuration>
"""


def make_scenario(
    folder: Path,
    nodes: str,
    edges: str,
    route: str,
    *,
    connections: str = "",
    extra: str = "",
    more: str = "",
) -> Path:
    """A scenario folder with plain-XML sources, a netconvert configuration and a scenario.toml."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "net.nod.xml").write_text(f"<nodes>{nodes}</nodes>")
    (folder / "net.edg.xml").write_text(f"<edges>{edges}</edges>")
    con = ""
    if connections:
        (folder / "net.con.xml").write_text(f"<connections>{connections}</connections>")
        con = '<connection-files value="net.con.xml"/>'
    (folder / "netconvert.cfg").write_text(CFG.format(con=con, extra=extra))
    (folder / "scenario.toml").write_text(
        textwrap.dedent(f"""\
        [network]
        netconvert = "netconvert.cfg"

        [route]
        {route}
        """)
        + more
    )
    return folder


STRAIGHT_NODES = '<node id="a" x="0" y="0"/><node id="b" x="400" y="0"/><node id="c" x="800" y="0"/>'


def two_lane_road(tmp_path: Path, b_type: str = "priority") -> Path:
    nodes = STRAIGHT_NODES.replace('id="b" x="400" y="0"', f'id="b" x="400" y="0" type="{b_type}"')
    nodes += '<node id="x" x="600" y="-150"/>'
    edges = (
        '<edge id="ab" from="a" to="b" numLanes="2" speed="27.8"/>'
        '<edge id="bc" from="b" to="c" numLanes="2" speed="27.8"/>'
        '<edge id="bx" from="b" to="x" numLanes="1" speed="20"/>'
    )
    return make_scenario(tmp_path / "two_lane", nodes, edges, 'edges = ["ab", "bc"]')


def test_the_oval_scenario_file_is_the_default_road(road):
    scn = load_road(scenario="oval")
    # the same road (the cache holds 8 roads: after many others the object may be a new one)
    assert scn.scenario_file == road.scenario_file and scn.edges == road.edges
    assert np.array_equal(scn.ref_xy, road.ref_xy)
    assert "oval" in shipped_scenarios()
    spec = load_scenario("oval")
    assert spec.edges == road.edges and len(spec.checkpoints) == 4
    assert [c.lane for c in road.checkpoints] == [lane for _, _, lane in spec.checkpoints]
    assert road.closed and road.n_lanes == 3 and math.isinf(road.route_end_s)


def test_two_lane_open_road_has_its_reference_between_the_lanes(tmp_path):
    road = load_road(scenario=two_lane_road(tmp_path))
    assert not road.closed and road.n_lanes == 2
    np.testing.assert_allclose(road.lane_centres, [-1.6, 1.6])
    assert road.half_road == pytest.approx(3.2)
    # each SUMO lane's centreline lies at its lane centre in the route frame (away from the junction)
    for k in range(2):
        shape = np.asarray(road.net.getEdge("ab").getLane(k).getShape())
        s, d = road.to_frenet(shape[:, 0], shape[:, 1])
        np.testing.assert_allclose(d[1:-1], road.lane_center(k), atol=0.01)
    assert road.route_end_s - road.route_begin_s == pytest.approx(800.0, abs=2.0)
    assert road.lane_of_d(np.array([-1.6, 1.6, 3.3])).tolist() == [0, 1, -1]
    # the route frame's round trip on and around the road, with the straight runs beyond both ends
    rng = np.random.default_rng(0)
    s = rng.uniform(road.route_begin_s - 200.0, road.route_end_s + 200.0, 5000)
    d = rng.uniform(-6.0, 6.0, 5000)
    x, y = road.to_xy(s, d)
    s2, d2 = road.to_frenet(x, y)
    assert np.abs(s2 - s).max() < 0.01 and np.abs(d2 - d).max() < 0.01


def test_exit_and_open_end_are_derived_from_the_network(tmp_path):
    road = load_road(scenario=two_lane_road(tmp_path))
    assert [e.edge for e in road.exits] == ["bx"]
    assert road.exits[0].s_start == pytest.approx(road.route_begin_s + 400.0, abs=15.0)
    # no checkpoint given: the open route's end, where any lane will do
    (cp,) = road.checkpoints
    assert cp.lane == -1 and cp.s == pytest.approx(road.route_end_s, abs=1.0)
    assert road.required_lane(0, 1.6) == 1 and road.required_lane(0, -1.6) == 0
    assert road.stop_lines == ()


def test_allway_stop_on_the_route_is_a_stop_line(tmp_path):
    road = load_road(scenario=two_lane_road(tmp_path, b_type="allway_stop"))
    (line,) = road.stop_lines
    assert line.node == "b"
    assert line.s == pytest.approx(road.route_begin_s + 400.0, abs=15.0)
    assert line.s < road.exits[0].s_start + 1.0  # the line is where the lanes end, before the junction


def test_a_lane_that_turns_off_makes_a_mission_checkpoint(tmp_path):
    """Only lane 1 of 'ab' goes on to 'bc' (lane 0 turns into the exit): the route requires lane 1 at
    the end of 'ab'."""
    nodes = STRAIGHT_NODES + '<node id="x" x="600" y="-150"/>'
    edges = (
        '<edge id="ab" from="a" to="b" numLanes="2" speed="27.8"/>'
        '<edge id="bc" from="b" to="c" numLanes="2" speed="27.8"/>'
        '<edge id="bx" from="b" to="x" numLanes="1" speed="20"/>'
    )
    cons = (
        '<connection from="ab" to="bc" fromLane="1" toLane="1"/>'
        '<connection from="ab" to="bc" fromLane="1" toLane="0"/>'
        '<connection from="ab" to="bx" fromLane="0" toLane="0"/>'
    )
    folder = make_scenario(tmp_path / "turn", nodes, edges, 'edges = ["ab", "bc"]', connections=cons)
    road = load_road(scenario=folder)
    mission = [c for c in road.checkpoints if c.lane >= 0]
    assert [c.lane for c in mission] == [1] and mission[0].lanes == (1,)
    assert mission[0].s == pytest.approx(road.route_begin_s + 400.0, abs=15.0)
    assert mission[0].meets(1) and not mission[0].meets(0)


def test_from_to_route_is_the_shortest_path(tmp_path):
    folder = two_lane_road(tmp_path)
    toml = folder / "scenario.toml"
    toml.write_text(toml.read_text().replace('edges = ["ab", "bc"]', 'from = "ab"\nto = "bc"'))
    assert load_road(scenario=folder).edges == ("ab", "bc")


@pytest.mark.parametrize(
    "route, match",
    [
        ('from = "bc"\nto = "ab"', "no path from 'bc' to 'ab'"),
        ('edges = ["ab", "zz"]', "edge 'zz' is not in the network"),
        ('edges = ["bc", "ab"]', "does not lead into"),
    ],
)
def test_routes_the_network_cannot_drive_are_one_line(tmp_path, route, match):
    folder = two_lane_road(tmp_path)
    toml = folder / "scenario.toml"
    toml.write_text(toml.read_text().replace('edges = ["ab", "bc"]', route))
    with pytest.raises(IrlsimError, match=match) as e:
        load_road(scenario=folder)
    assert "\n" not in str(e.value)


def test_networks_the_tool_cannot_handle_are_one_line(tmp_path):
    short = make_scenario(
        tmp_path / "short",
        '<node id="a" x="0" y="0"/><node id="b" x="40" y="0"/>',
        '<edge id="ab" from="a" to="b" numLanes="2"/>',
        'edges = ["ab"]',
    )
    with pytest.raises(IrlsimError, match="shorter than"):
        load_road(scenario=short)
    left = make_scenario(
        tmp_path / "left",
        STRAIGHT_NODES,
        '<edge id="ab" from="a" to="b" numLanes="2"/>',
        'edges = ["ab"]',
        extra='<lefthand value="true"/>',
    )
    with pytest.raises(IrlsimError, match="drives on the left"):
        load_road(scenario=left)
    bikes = make_scenario(
        tmp_path / "bikes",
        STRAIGHT_NODES,
        '<edge id="ab" from="a" to="b" numLanes="1" allow="bicycle"/>',
        'edges = ["ab"]',
    )
    with pytest.raises(IrlsimError, match="edge .ab. has no lane for passenger cars"):
        load_road(scenario=bikes)
    with pytest.raises(IrlsimError, match="scenario 'nowhere' not found: name a shipped one"):
        load_scenario("nowhere")
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "scenario.toml").write_text('[route]\nedges = ["a"]\n')
    with pytest.raises(IrlsimError, match="needs \\[network\\] and \\[route\\]"):
        load_scenario(bad)
    (bad / "scenario.toml").write_text(
        '[network]\nfile = "x.net.xml"\nosm = "y.osm"\n[route]\nedges = ["a"]\n'
    )
    with pytest.raises(IrlsimError, match="exactly one of"):
        load_scenario(bad)


def test_motorway_from_the_sumo_wheel_loads_as_an_open_three_lane_route():
    road = load_road(scenario="motorway")
    assert not road.closed and road.n_lanes == 3 and road.stop_lines == ()
    assert road.route_end_s - road.route_begin_s == pytest.approx(1207.0, abs=5.0)
    # the network is read where the wheel installed it, not copied into the project
    assert "site-packages" in str(road.net_file) and road.net_file.name == "osm.net.xml"
    s = np.linspace(road.route_begin_s, road.route_end_s, 4000)
    d = np.random.default_rng(1).uniform(-4.8, 4.8, 4000)
    x, y = road.to_xy(s, d)
    s2, d2 = road.to_frenet(x, y)
    assert np.abs(s2 - s).max() < 0.01 and np.abs(d2 - d).max() < 0.01


def test_scenario_command_lists_shows_and_draws(capsys, tmp_path):
    from pipelines.commands import main

    assert main(["scenario", "list"]) == 0
    listed = capsys.readouterr().out
    assert "oval" in listed and "motorway" in listed
    png = tmp_path / "motorway.png"
    assert main(["scenario", "show", "motorway", "--out", str(png)]) == 0
    out = capsys.readouterr().out
    assert "route: 2 edges, open" in out and "lanes: 3 x 3.20 m" in out and str(png) in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["scenario", "show", "nowhere"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "scenario 'nowhere' not found" in err


def lane_drop_road(tmp_path: Path) -> Path:
    """Three lanes for 400 m, then two: the rightmost lane ends (it merges into the middle one)."""
    edges = (
        '<edge id="ab" from="a" to="b" numLanes="3" speed="27.8"/>'
        '<edge id="bc" from="b" to="c" numLanes="2" speed="27.8"/>'
    )
    cons = (
        '<connection from="ab" to="bc" fromLane="1" toLane="0"/>'
        '<connection from="ab" to="bc" fromLane="2" toLane="1"/>'
    )
    return make_scenario(tmp_path / "drop", STRAIGHT_NODES, edges, 'edges = ["ab", "bc"]', connections=cons)


def test_a_dropped_lane_exists_only_up_to_where_it_ends(tmp_path):
    road = load_road(scenario=lane_drop_road(tmp_path))
    assert road.lanes_vary and road.n_lanes == 3
    assert road.layout.first == (0, 1) and road.layout.count == (3, 2)
    b = road.route_begin_s + 400.0
    lo, hi = road.lane_bounds(np.array([b - 100.0, b + 100.0]))
    assert lo.tolist() == [0, 1] and hi.tolist() == [2, 2]
    right, left = road.road_edges(np.array([b - 100.0, b + 100.0]))
    np.testing.assert_allclose(right, [-4.8, -1.6])
    np.testing.assert_allclose(left, [4.8, 4.8])
    # the lanes keep their place across the junction: 'bc' lane 0 lies where 'ab' lane 1 did
    shape = np.asarray(road.net.getEdge("bc").getLane(0).getShape())
    _, d = road.to_frenet(shape[:, 0], shape[:, 1])
    np.testing.assert_allclose(d, 0.0, atol=0.05)
    # lane 0 of 'ab' does not go on: the route requires one of the lanes that do at the end of 'ab'
    mission = [c for c in road.checkpoints if c.lane >= 0]
    assert [c.lane for c in mission] == [1] and mission[0].lanes == (1, 2)
    assert mission[0].meets(2) and not mission[0].meets(0)
    i = mission[0].index
    assert road.required_lane(i, 3.2) == 2 and road.required_lane(i, -3.2) == 1  # the nearest that goes on


def test_an_on_ramp_adds_a_lane_on_the_right(tmp_path):
    nodes = STRAIGHT_NODES + '<node id="r" x="100" y="-120"/>'
    edges = (
        '<edge id="ab" from="a" to="b" numLanes="2" speed="27.8"/>'
        '<edge id="rb" from="r" to="b" numLanes="1" speed="20"/>'
        '<edge id="bc" from="b" to="c" numLanes="3" speed="27.8"/>'
    )
    cons = (
        '<connection from="ab" to="bc" fromLane="0" toLane="1"/>'
        '<connection from="ab" to="bc" fromLane="1" toLane="2"/>'
        '<connection from="rb" to="bc" fromLane="0" toLane="0"/>'
    )
    folder = make_scenario(tmp_path / "onramp", nodes, edges, 'edges = ["ab", "bc"]', connections=cons)
    road = load_road(scenario=folder)
    assert road.layout.first == (1, 0) and road.n_lanes == 3
    b = road.route_begin_s + 400.0
    assert road.lane_bounds(np.array(b - 100.0))[0] == 1 and road.lane_bounds(np.array(b + 100.0))[0] == 0
    assert [c.lane for c in road.checkpoints] == [-1]  # both lanes go on: no mission but the end
    assert road.exits == ()  # a lane that joins is no way off the route


def test_planner_sends_no_policy_into_a_lane_that_ends(tmp_path):
    """30 m before the drop at 15 m/s: a policy in lane 0 at any step past its end is labelled off the
    road; policies that stay in lane 0 and stand before its end are offered and not labelled (so the ego
    can wait in its lane behind a queue in the lane it needs); the expert, with the road free, changes
    lanes and does not choose a policy off the road."""
    from irlsim.planner.config import PlannerConfig
    from irlsim.planner.expert import ExpertDriver
    from tests.planner.conftest import make_obs

    road = load_road(scenario=lane_drop_road(tmp_path))
    b = road.route_begin_s + 400.0
    driver = ExpertDriver(road, PlannerConfig())
    obs = make_obs(road, b - 30.0, float(road.lane_center(0)), 15.0)
    ps = driver.planner.plan(obs)
    offroad = ps.labels[:, 1]
    in_lane0_past_end = ((ps.d < -1.6) & (ps.s > b + 5.0)).any(axis=1)  # the junction: ~3 m
    assert in_lane0_past_end.any()
    assert offroad[in_lane0_past_end].all()
    stays = (ps.d < -1.6).all(axis=1) & (ps.s[:, -1] < b - 1.0)
    assert stays.any() and not offroad[stays].any()
    idx = driver.select(ps, obs)
    assert not offroad[idx]
    assert road.lane_of_d(ps.d[idx, -1:])[0] >= 1


def crossing(tmp_path: Path, b_type: str, minor_route: bool) -> Path:
    """A four-way junction at b: the route runs west-east (a -> b -> c) and a side road crosses it
    north-south (n -> b -> s), priority 10 on the main road, 5 on the side road. ``minor_route``: the
    route is the side road (n -> b -> s) instead."""
    nodes = STRAIGHT_NODES.replace('id="b" x="400" y="0"', f'id="b" x="400" y="0" type="{b_type}"')
    nodes += '<node id="n" x="400" y="300"/><node id="s" x="400" y="-300"/>'
    edges = (
        '<edge id="ab" from="a" to="b" numLanes="1" speed="13.9" priority="10"/>'
        '<edge id="bc" from="b" to="c" numLanes="1" speed="13.9" priority="10"/>'
        '<edge id="nb" from="n" to="b" numLanes="1" speed="13.9" priority="5"/>'
        '<edge id="bs" from="b" to="s" numLanes="1" speed="13.9" priority="5"/>'
    )
    route = 'edges = ["nb", "bs"]' if minor_route else 'edges = ["ab", "bc"]'
    return make_scenario(tmp_path / f"{b_type}_{minor_route}", nodes, edges, route)


def test_a_traffic_light_on_the_route_is_a_signal(tmp_path):
    road = load_road(scenario=crossing(tmp_path, "traffic_light", minor_route=False))
    (sig,) = road.signals
    assert sig.node == "b" and sig.tls == "b" and sig.link >= 0
    assert sig.s == pytest.approx(road.route_begin_s + 400.0, abs=15.0)
    assert road.stop_lines == ()  # a light is no stop sign
    assert road.max_speed_limit == pytest.approx(13.9)


def test_a_stop_sign_binds_the_minor_road_only(tmp_path):
    """SUMO's priority_stop: the side road stops (link state 's'), the main road does not."""
    minor = load_road(scenario=crossing(tmp_path, "priority_stop", minor_route=True))
    (line,) = minor.stop_lines
    assert line.node == "b" and minor.signals == ()
    assert line.s == pytest.approx(minor.route_begin_s + 300.0, abs=15.0)
    major = load_road(scenario=crossing(tmp_path, "priority_stop", minor_route=False))
    assert major.stop_lines == () and major.signals == ()


def test_a_scenario_file_sets_its_episode_defaults_and_a_config_overrides_them(tmp_path):
    from irlsim.config import load_config
    from irlsim.data.collection import CollectConfig
    from irlsim.sim.config import scenario_config

    folder = two_lane_road(tmp_path)
    toml = folder / "scenario.toml"
    toml.write_text(toml.read_text() + "\n[defaults]\nn_vehicles = 4\nego_start_speed_max = 9.0\n")
    cfg = load_config(CollectConfig, None, {"scenario.name": str(folder)})
    assert cfg.scenario.n_vehicles == 4 and cfg.scenario.ego_start_speed_max == 9.0
    cfg = load_config(CollectConfig, None, {"scenario.name": str(folder), "scenario.n_vehicles": 7})
    assert cfg.scenario.n_vehicles == 7 and cfg.scenario.ego_start_speed_max == 9.0  # the config wins
    assert scenario_config(str(folder)).n_vehicles == 4
    assert load_config(CollectConfig, None).scenario.n_vehicles == 15  # the oval: no file, no defaults
    toml.write_text(toml.read_text() + "lanes = 3\n")
    with pytest.raises(IrlsimError, match="'lanes', which is not an episode setting"):
        load_config(CollectConfig, None, {"scenario.name": str(folder)})


def test_an_open_route_that_ends_on_its_start_s_run_on_has_its_whole_length(tmp_path):
    """East from a, round a block and back heading east, ending at g 50 m short of a: the end lies on the
    start's straight run-on of the route frame (the line the frame extends back from a). Projected
    globally, the end landed 50 m before the start (1.1 km routes of the sweep refused as -53 m long);
    projected by progress the route has its length."""
    nodes = (
        '<node id="a" x="0" y="0"/><node id="b" x="300" y="0"/><node id="c" x="300" y="300"/>'
        '<node id="d" x="-300" y="300"/><node id="e" x="-300" y="0"/><node id="g" x="-50" y="0"/>'
    )
    edges = "".join(
        f'<edge id="{u}{v}" from="{u}" to="{v}" numLanes="1" speed="13.9"/>'
        for u, v in ("ab", "bc", "cd", "de", "eg", "ga")
    )
    folder = make_scenario(tmp_path / "block", nodes, edges, 'edges = ["ab", "bc", "cd", "de", "eg"]')
    road = load_road(scenario=folder)
    assert not road.closed and not road.flat
    assert 1650.0 < road.route_end_s - road.route_begin_s < 1800.0
