"""Traffic on roads other than the oval (real SUMO): irlsim's spawner on an open route, a scenario's
own SUMO demand (flows that enter and leave), and traffic lights read every step."""

from __future__ import annotations

import numpy as np

from irlsim.road import load_road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
from tests.road.test_scenario import STRAIGHT_NODES, make_scenario

FLOW = """<routes>
    <vType id="car" length="4.5" minGap="2.5" sigma="0"/>
    <flow id="f" type="car" begin="0" end="3600" period="6" departLane="random" departSpeed="max">
        <route edges="ab bc"/>
    </flow>
</routes>
"""


def test_scenario_with_its_own_demand(tmp_path):
    edges = (
        '<edge id="ab" from="a" to="b" numLanes="2" speed="20"/>'
        '<edge id="bc" from="b" to="c" numLanes="2" speed="20"/>'
    )
    more = '\n[traffic]\nroutes = ["demand.rou.xml"]\nwarmup = 40.0\n'
    folder = make_scenario(tmp_path / "demand", STRAIGHT_NODES, edges, 'edges = ["ab", "bc"]', more=more)
    (folder / "demand.rou.xml").write_text(FLOW)
    road = load_road(scenario=folder)
    assert road.demand == (folder / "demand.rou.xml",) and road.warmup == 40.0
    with Simulation(road, EpisodeConfig(name=str(folder), max_time=30.0)) as sim:
        obs = sim.reset(3)
        assert obs.ego.t >= 40.0  # the warm-up ran before the ego entered
        ids = set(obs.vehicles.ids)
        assert ids and all(v.startswith("f.") for v in ids)  # the flow's vehicles, none of irlsim's
        ahead = np.abs(obs.vehicles.s - obs.ego.s)
        assert ahead.min() >= 20.0 - 5.0  # the start kept clear of them (they moved one step since)
        seen = set(ids)
        for _ in range(100):
            sim.step()
            seen |= set(sim.vehicles.ids)
        assert len(seen) > len(ids)  # vehicles keep entering (and leaving at the route's end)


def test_traffic_lights_are_read_every_step():
    road = load_road(scenario="corridor")
    assert len(road.signals) == 3
    with Simulation(road, EpisodeConfig(name="corridor", n_vehicles=0, max_time=200.0)) as sim:
        sim.reset(1)
        states = []
        for _ in range(900):  # 90 s: every light goes through its cycle
            sim.step()
            states.append(sim.signals.binding.copy())
        seen = np.array(states)
        assert seen.any(axis=0).all() and (~seen).any(axis=0).all()  # each light both binds and frees


def test_crossing_a_red_light_is_counted_and_a_green_one_is_not():
    import dataclasses

    from irlsim.sim.episode import CourseMarks, Episode
    from irlsim.sim.types import EgoState

    marks = CourseMarks(1000.0, (900.0,), (-1,), (), (), 4.8, route_end_s=950.0, signal_s=(100.0, 300.0))
    ep = Episode(marks, laps=1, max_time=100.0)
    ego = EgoState(t=0.0, x=0, y=0, yaw=0, v=10.0, a=0, s=90.0, d=0.0, d_dot=0, d_ddot=0, lane=1)
    ep.update(ego)
    ep.update(dataclasses.replace(ego, t=1.0, s=105.0), red=(True, False))  # through the first on red
    ep.update(dataclasses.replace(ego, t=2.0, s=305.0), red=(True, False))  # the second on green
    st = ep.stats()
    assert st["sim/signals_passed"] == 2 and st["sim/red_crossings"] == 1
    ep.update(dataclasses.replace(ego, t=3.0, s=951.0))
    assert ep.done and ep.end_reason == "route_end"
    # a road without lights keeps the figures it always had
    plain = Episode(CourseMarks(1000.0, (900.0,), (2,), (), (), 4.8), laps=1, max_time=100.0)
    plain.update(ego)
    assert "sim/red_crossings" not in plain.stats()


def test_a_red_light_forbids_crossing_even_after_standing():
    """At an all-way stop a policy that stood may cross; at a red light none may."""
    import dataclasses

    from irlsim.planner.config import PlannerConfig
    from irlsim.planner.planner import Planner
    from tests.planner.conftest import make_obs

    road = load_road()
    planner = Planner(road, PlannerConfig())
    line = road.stop_lines[0].s
    obs = make_obs(road, line - 2.0, 0.0, 0.0, stop_s=line)  # standing just before the line
    stop = planner.plan(obs).features[:, 11]
    red = planner.plan(dataclasses.replace(obs, stop_red=True)).features[:, 11]
    assert (stop == 0).all()  # it stood (v = 0): every crossing is allowed
    assert (red > 0).any()  # on red, the policies that cross pay the stop_line event


def test_a_street_slower_than_the_traffic_takes_its_vehicles_and_the_ego(tmp_path):
    """A 10 km/h street (a living street of an OpenStreetMap import): SUMO refuses a departure faster
    than the lane's limit, so the traffic (25-35 km/h) and the ego (up to 54 km/h) enter at it."""
    edges = (
        '<edge id="ab" from="a" to="b" numLanes="2" speed="2.78"/>'
        '<edge id="bc" from="b" to="c" numLanes="2" speed="2.78"/>'
    )
    road = load_road(scenario=make_scenario(tmp_path / "slow", STRAIGHT_NODES, edges, 'edges = ["ab", "bc"]'))
    cfg = EpisodeConfig(name="slow", n_vehicles=6, max_time=20.0, ego_start_speed_min=10.0)
    with Simulation(road, cfg) as sim:
        for seed in range(3):
            obs = sim.reset(seed)
            assert obs.ego.v >= 10.0  # the ego keeps its own start speed (it is placed by moveToXY)
            for _ in range(10):
                sim.step()
            assert sim.vehicles.count >= 3
