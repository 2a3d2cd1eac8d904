"""Right of way at minor links (real SUMO): the yield points of a route against SUMO's link states, the
ego waiting for a platoon on the major road, and the violation counted when it does not."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from irlsim.planner.expert import ExpertDriver, planner_config_for
from irlsim.road import load_road
from irlsim.rollout.runner import EpisodeRunner
from irlsim.sim import minor_green, signals, yielding
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.episode import CourseMarks, Episode
from irlsim.sim.simulation import EGO, Simulation
from irlsim.sim.types import EgoState
from tests.road.test_scenario import make_scenario


def _expert(road, cfg):
    """The expert with 500 policies instead of 2,500: right of way is the simulation's, not the planner's
    resolution, and the smaller set runs these tests about 1.5 times as fast (44 s -> 29 s)."""
    return ExpertDriver(road, dataclasses.replace(planner_config_for(cfg), n_policies=500))


#: a T junction: the minor road sj (from the south) meets the major road wj -> je at j
T_NODES = (
    '<node id="w" x="-500" y="0"/><node id="j" x="0" y="0" type="{kind}"/><node id="e" x="250" y="0"/>'
    '<node id="s" x="0" y="-300"/>'
)
T_EDGES = (
    '<edge id="wj" from="w" to="j" numLanes="1" speed="13.9" priority="3"/>'
    '<edge id="je" from="j" to="e" numLanes="1" speed="13.9" priority="3"/>'
    '<edge id="sj" from="s" to="j" numLanes="1" speed="13.9" priority="1"/>'
)
#: a platoon on the major road every 2 s (too short a gap to turn into) for 70 s, then none for 40 s (the
#: ego enters after the 60 s warm-up, stands about 20 s at the line, turns and leaves on the 250 m of je)
PLATOON = """<routes>
    <vType id="car" length="4.5" minGap="2.5" sigma="0" speedDev="0"/>
    <flow id="p" type="car" begin="0" end="70" period="2" departSpeed="max"><route edges="wj je"/></flow>
    <flow id="q" type="car" begin="110" end="3600" period="30" departSpeed="max"><route edges="wj je"/></flow>
</routes>
"""


def t_junction(tmp_path, route: str, kind: str = "priority", demand: bool = False):
    more = '\n[traffic]\nroutes = ["demand.rou.xml"]\nwarmup = 60.0\n' if demand else ""
    folder = make_scenario(
        tmp_path / f"t_{kind}_{route[2:4]}", T_NODES.format(kind=kind), T_EDGES, f"edges = {route}", more=more
    )
    (folder / "demand.rou.xml").write_text(PLATOON)
    return load_road(scenario=folder)


def test_yield_points_are_the_minor_links_of_the_route(tmp_path):
    minor = t_junction(tmp_path, '["sj", "je"]')
    con = minor.net.getEdge("sj").getLane(0).getOutgoing()[0]
    assert con.getState() == "m"  # SUMO's link state: the minor road yields
    (p,) = minor.yield_points
    end = minor.net.getEdge("sj").getLane(0).getShape()[-1]
    assert p.node == "j" and (p.x, p.y) == pytest.approx(end)
    assert p.s == pytest.approx(minor.to_frenet(np.array([end[0]]), np.array([end[1]]))[0][0])
    assert not minor.stop_lines and not minor.signals
    assert "yield_points_s_m" in minor.describe()
    # the major road through the same junction has priority: no yield point
    major = t_junction(tmp_path, '["wj", "je"]')
    assert major.net.getEdge("wj").getLane(0).getOutgoing()[0].getState() == "M"
    assert major.yield_points == () and "yield_points_s_m" not in major.describe()
    # the same junction with a stop sign on the minor road: a stop line, not a yield point
    stop = t_junction(tmp_path, '["sj", "je"]', kind="priority_stop")
    assert stop.net.getEdge("sj").getLane(0).getOutgoing()[0].getState() == "s"
    assert stop.yield_points == () and len(stop.stop_lines) == 1


def test_shipped_routes_take_no_minor_link():
    """Their episodes keep their bytes: no yield point, so no foe is asked for and no key is added."""
    for name in ("oval", "corridor", "grid", "motorway", "ramp"):
        assert load_road(scenario=name).yield_points == (), name


def test_clear_time_and_foe_arrival_closed_form():
    t = yielding.clear_time(np.array([0.0, 8.0, 50.0]), 0.0, 2.0, 10.0)
    # 8 m from standing at 2 m/s^2: sqrt(2 * 8 / 2) = 2.83 s; 50 m: 5 s to reach 10 m/s (25 m), 2.5 s more
    assert t == pytest.approx([0.0, np.sqrt(8.0), 7.5])
    arr = yielding.foe_arrival(
        np.array([-1.0, 20.0, 20.0, -9.0]),
        np.array([2.0, 23.0, 23.0, -6.0]),
        np.array([5.0, 10.0, 0.0, 10.0]),
    )
    assert arr.tolist() == [0.0, 2.0, np.inf, np.inf]  # inside, moving, standing, past
    assert yielding.junction_of(":j_0_0") == "j" and yielding.junction_of(":a_b_12_3") == "a_b"


def _drive(road, seed: int = 0):
    cfg = EpisodeConfig(
        name="t",
        max_time=90.0,
        ego_start_random=False,
        ego_start_s=road.yield_points[0].s - 120.0,
        ego_start_speed=10.0,
    )
    with Simulation(road, cfg) as sim:
        res = EpisodeRunner(sim).run(_expert(road, cfg), seed)
        return res.stats, sim.odometry_arrays()


def test_sumo_is_asked_only_near_a_yield_line():
    """reach: YIELD_PAST beyond the nearest line within [line - YIELD_LOOKAHEAD, line + YIELD_PAST],
    capped at YIELD_LOOKAHEAD, wrapped on a loop; 0 (not asked) elsewhere."""
    w = object.__new__(yielding.YieldWatch)
    w.s, w.lap = np.array([100.0, 990.0]), 1000.0
    look, past = yielding.YIELD_LOOKAHEAD, yielding.YIELD_PAST
    assert w.reach(100.0 - look - 1.0) == 0.0  # too far before the first line
    assert w.reach(100.0 - look) == look  # at the edge of reach: capped
    assert w.reach(100.0 - 10.0) == pytest.approx(10.0 + past)
    assert w.reach(100.0 + past - 1.0) == pytest.approx(1.0)  # leaving the junction
    assert w.reach(100.0 + past + 1.0) == 0.0
    assert w.reach(985.0) == pytest.approx(5.0 + past)  # the second line
    assert w.reach(5.0) == pytest.approx(past - 15.0)  # 15 m past the second, across the lap's seam


def test_the_ego_waits_for_the_platoon_then_turns(tmp_path):
    road = t_junction(tmp_path, '["sj", "je"]', demand=True)
    st, od = _drive(road)
    line = road.yield_points[0].s
    waited = (od["v"] < 0.1) & (od["s"] <= line) & (od["s"] > line - 15.0)
    assert waited.sum() * 0.1 >= 10.0  # it stood at the line while the platoon passed
    assert st["sim/yields_passed"] == 1  # and turned in the gap after it
    assert st["sim/yield_violations"] == 0 and st["sim/collisions"] == 0 and st["sim/sumo_collisions"] == 0


def test_ignoring_the_yield_is_counted(tmp_path, monkeypatch):
    """The same episode with the yield point never binding: the ego turns into the platoon."""
    road = t_junction(tmp_path, '["sj", "je"]', demand=True)
    read = yielding.YieldWatch.read

    def never_binding(self, *args):
        new = read(self, *args)
        self.binding[:] = False
        return new

    monkeypatch.setattr(yielding.YieldWatch, "read", never_binding)
    st, _ = _drive(road)
    assert st["sim/yields_passed"] == 1 and st["sim/yield_violations"] == 1


def test_a_violation_is_counted_like_a_red_crossing():
    marks = CourseMarks(1000.0, (900.0,), (-1,), (), (), 4.8, route_end_s=950.0, yield_s=(100.0,))
    ep = Episode(marks, laps=1, max_time=100.0)
    ego = EgoState(t=0.0, x=0, y=0, yaw=0, v=10.0, a=0, s=90.0, d=0.0, d_dot=0, d_ddot=0, lane=0)
    ep.update(ego)
    ep.update(dataclasses.replace(ego, t=1.0, s=105.0), yield_violations=1)
    st = ep.stats()
    assert st["sim/yields_passed"] == 1 and st["sim/yield_violations"] == 1
    assert "sim/yield_violations" not in Episode(dataclasses.replace(marks, yield_s=()), 1, 100.0).stats()


#: a signalised crossing: the ego turns left from the west into the north, on SUMO's minor green 'g',
#: across a platoon going straight from the east on the same green
X_NODES = (
    '<node id="w" x="-400" y="0"/><node id="e" x="400" y="0"/><node id="n" x="0" y="300"/>'
    '<node id="s" x="0" y="-300"/><node id="j" x="0" y="0" type="traffic_light"/>'
)
X_EDGES = "".join(
    f'<edge id="{a}{b}" from="{a}" to="{b}" numLanes="1" speed="13.9"/>'
    for a, b in ("wj", "je", "ej", "jw", "nj", "jn", "sj", "js")
)
ONCOMING = """<routes>
    <vType id="car" length="4.5" minGap="2.5" sigma="0" speedDev="0"/>
    <flow id="p" type="car" begin="0" end="{end}" period="2" departSpeed="max"><route edges="ej jw"/></flow>
</routes>
"""


def _crossing(tmp_path, end: float, warmup: float = 0.0):
    """The crossing with a platoon leaving e until ``end`` (at the junction until about 30 s later), the ego
    entering after ``warmup`` 100 m before the light, SUMO's program giving its minor green from 45 s to
    87 s; the exit jn is 120 m long (an episode ends soon after the turn)."""
    more = f'\n[traffic]\nroutes = ["demand.rou.xml"]\nwarmup = {warmup}\n'
    nodes = X_NODES.replace('<node id="n" x="0" y="300"/>', '<node id="n" x="0" y="120"/>')
    folder = make_scenario(tmp_path / "x", nodes, X_EDGES, 'edges = ["wj", "jn"]', more=more)
    (folder / "demand.rou.xml").write_text(ONCOMING.format(end=end))
    road = load_road(scenario=folder)
    (signal,) = road.signals
    cfg = EpisodeConfig(
        name="x", max_time=120.0, ego_start_random=False, ego_start_s=signal.s - 100.0, ego_start_speed=10.0
    )
    return road, cfg


def test_the_ego_turning_on_a_minor_green_waits_for_the_oncoming_platoon(tmp_path, monkeypatch):
    # the ego enters at 35 s and reaches the light on its green (from 45 s), the platoon still passing
    road, cfg = _crossing(tmp_path, end=40.0, warmup=35.0)
    (signal,) = road.signals
    assert road.yield_points == ()  # a light, no minor link without one
    with Simulation(road, cfg) as sim:
        res = EpisodeRunner(sim).run(_expert(road, cfg), 0)
        od = sim.odometry_arrays()
    st = res.stats
    line = signal.s
    waited = (od["v"] < 0.1) & (od["s"] <= line) & (od["s"] > line - 15.0) & (od["t"] > 45.0)
    assert st["sim/red_crossings"] == 0 and st["sim/signals_passed"] == 1
    assert st["sim/yield_violations"] == 0 and st["sim/collisions"] == 0
    assert waited.sum() * 0.1 >= 5.0  # it stood at the line on its green while the platoon passed
    # the same episode with the minor green judged but not holding the ego: it turns across the platoon,
    # a violation; with no foe seen at all, no violation and a collision
    judge = signals.SignalWatch._minor_greens

    def not_holding(self, *args):
        judge(self, *args)
        self.binding &= ~self._yielding

    monkeypatch.setattr(signals.SignalWatch, "_minor_greens", not_holding)
    with Simulation(road, cfg) as sim:
        res = EpisodeRunner(sim).run(_expert(road, cfg), 0)
    assert res.stats["sim/yield_violations"] == 1
    monkeypatch.setattr(minor_green.MinorGreen, "too_soon", lambda self, *args: False)
    with Simulation(road, cfg) as sim:
        res = EpisodeRunner(sim).run(_expert(road, cfg), 0)
    assert res.stats["sim/yield_violations"] == 0 and res.stats["sim/collisions"] == 1


#: a priority crossing of a two-lane major road (west-east) and a one-lane minor one (south-north)
P_EDGES = "".join(
    f'<edge id="{a}{b}" from="{a}" to="{b}" numLanes="{2 if a + b in ("wj", "je", "ej", "jw") else 1}" '
    f'speed="13.9" priority="{3 if a + b in ("wj", "je", "ej", "jw") else 1}"/>'
    for a, b in ("wj", "je", "ej", "jw", "nj", "jn", "sj", "js")
)


def _left_turn(tmp_path):
    """The ego turns left from the major road (wj) into the minor one (jn): a minor link across the
    oncoming lanes, which SUMO builds in two internal lanes (an internal junction where it waits)."""
    folder = make_scenario(
        tmp_path / "p", X_NODES.replace("traffic_light", "priority"), P_EDGES, 'edges = ["wj", "jn"]'
    )
    return load_road(scenario=folder)


def test_a_yield_points_way_is_its_connections_chain_through_the_junction(tmp_path):
    road = _left_turn(tmp_path)
    (p,) = road.yield_points
    assert p.node == "j" and len(p.lanes) == 2 and all(yielding.junction_of(ln) == "j" for ln in p.lanes)
    # the chain runs from the end of the major road's left lane to the start of the minor road, joined
    shapes = {ln: road.net.getLane(ln).getShape() for ln in p.lanes}
    first = next(ln for ln in p.lanes if np.allclose(shapes[ln][0], road.net.getLane("wj_1").getShape()[-1]))
    (second,) = set(p.lanes) - {first}
    assert np.allclose(shapes[first][-1], shapes[second][0])
    assert np.allclose(shapes[second][-1], road.net.getLane("jn_0").getShape()[0])
    # the T junction's minor road into the major one: one lane, its connection's
    minor = t_junction(tmp_path, '["sj", "je"]')
    (q,) = minor.yield_points
    (con,) = minor.net.getEdge("sj").getLane(0).getOutgoing()
    assert q.lanes == (con.getViaLaneID(),) and q.lanes[0].startswith(":j_")


def test_sumo_places_the_turning_ego_on_other_links_lanes_which_are_not_its_way(tmp_path):
    """Moved by moveToXY through its left turn, the ego is on lanes of the junction's other links where
    they run together with its own (SUMO's foe answers there are that link's): the watch takes only the
    route's way through the junction."""
    road = _left_turn(tmp_path)
    (p,) = road.yield_points
    cfg = EpisodeConfig(
        name="t", max_time=30.0, ego_start_random=False, ego_start_s=p.s - 60.0, ego_start_speed=10.0
    )
    lanes: list[str] = []
    with Simulation(road, cfg) as sim:
        sim.step_listeners.append(lambda s: lanes.append(s._api.vehicle.getLaneID(EGO)))
        res = EpisodeRunner(sim).run(_expert(road, cfg), 0)
        watch = sim.yields
    inside = {ln for ln in lanes if yielding.junction_of(ln) == "j"}
    others = inside - set(p.lanes)
    assert set(p.lanes) <= inside and others, lanes  # its own way, and lanes of other links
    assert all(watch.on_way(ln) for ln in p.lanes) and not any(watch.on_way(ln) for ln in others)
    assert not watch.on_way(":k_0_0")  # another junction's
    assert res.stats["sim/yields_passed"] == 1 and res.stats["sim/yield_violations"] == 0


@pytest.mark.slow  # a generated network's 90 s episode, twice (about 12 s)
def test_a_foe_of_a_link_the_ego_is_not_taking_is_no_violation(tmp_path, monkeypatch):
    """Generated network 47 of seed 0 (the sweep's development draw), its first drawn route: the ego's
    left turn at junction 58 ends where another approach's link joins it, SUMO places the ego on that
    link's lane and lists that link's foes with priority. Taken as the ego's, they were a violation."""
    from irlsim.road.generate import build_network, network_params
    from irlsim.road.scenario import Scenarios
    from irlsim.workflows.scenarios import scenario_config

    net = build_network(network_params(0, 47), tmp_path)
    edges = ["626", "-674", "-624", "-459", "-59", "-9", "5", "17", "-264", "282"]
    path = tmp_path / "route.toml"
    path.write_text(f'name = "r"\n[network]\nfile = "{net}"\n[route]\nedges = {edges}\n'.replace("'", '"'))

    def drive() -> tuple[dict, list[str]]:
        scenarios = Scenarios()
        road = load_road(scenario=scenarios(str(path)))
        cfg = scenario_config(str(path), scenarios, max_time=90.0)
        lanes: list[str] = []
        with Simulation(road, cfg) as sim:
            sim.step_listeners.append(lambda s: lanes.append(s._api.vehicle.getLaneID(EGO)))
            return EpisodeRunner(sim).run(_expert(road, cfg), 0).stats, lanes

    stats, lanes = drive()
    assert {":58_1_0", ":58_12_0", ":58_5_0"} <= set(lanes)  # its way, then the other link's lane
    assert stats["sim/yields_passed"] >= 3 and stats["sim/yield_violations"] == 0
    monkeypatch.setattr(
        yielding.YieldWatch, "on_way", lambda self, lane: yielding.junction_of(lane) in self.nodes
    )
    stats, _ = drive()
    assert stats["sim/yield_violations"] == 1  # every foe of the junction taken as the ego's
