"""Routes whose lane count changes to one and back (real SUMO): off a motorway onto a one-lane ramp (the
wheel's game network ``ramp``), a motorway, a one-lane link and a three-lane road (the wheel's A10
network), three lanes that leave as one (netconvert). Every part that walks the route's edges (the
lane numbering, the reference line, the mission, the spawner, the ego's start, the picture) takes them,
and the expert drives them through ``irlsim sim``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
from irlsim.sim.traffic import lane_runways
from tests.road.test_scenario import STRAIGHT_NODES, make_scenario

RAMP_EXIT = ["gneE2", "offramp", "gneE4", "gneE16", "gneE18", "gneE9"]  # 3 lanes, then a one-lane ramp
A10_LINK = ["290296351", "240042212", "151495018", "222448597#0"]  # 3, 4 lanes, a one-lane link, 3 lanes


def wheel_scenario(folder: Path, network: str, edges: list[str]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    quoted = ", ".join(f'"{e}"' for e in edges)
    (folder / "scenario.toml").write_text(
        f'[network]\nsumo_tools = "{network}"\n\n[route]\nedges = [{quoted}]\n'
    )
    return folder


def test_off_the_motorway_onto_a_one_lane_ramp(tmp_path):
    road = load_road(scenario=wheel_scenario(tmp_path / "rampexit", "game/ramp/ramp.net.xml", RAMP_EXIT))
    assert road.n_lanes == 3 and road.layout.count == (3, 3, 1, 1, 1, 1)
    on_ramp = np.linspace(road.route_end_s - 300.0, road.route_end_s - 5.0, 50)
    lo, hi = road.lane_bounds(on_ramp)
    assert (lo == 0).all() and (hi == 0).all()  # one lane on the ramp: the rightmost
    # the mission: only the rightmost lane goes on onto the ramp; then the route's end, any lane
    assert [c.lanes for c in road.checkpoints] == [(0,), ()]
    # lanes 1 and 2 of the motorway stop going on (1 and 2 lane changes short of the ramp)
    assert lane_runways(road)[(0, 2)] == (pytest.approx(53.0, abs=1.0), 2)
    # the picture and the spawner's edge table take the one-lane edges
    from irlsim.viz.road_map import draw_scenario

    assert draw_scenario(road, tmp_path / "rampexit.png").read_bytes()[:4] == b"\x89PNG"
    with Simulation(road, EpisodeConfig(name="rampexit", max_time=60.0)) as sim:
        for seed in range(4):
            sim.reset(seed)
            assert sim.ego is not None
            lo, hi = road.lane_bounds(np.array(sim.ego.s))
            assert lo <= sim.ego.lane <= hi  # the ego starts in a lane that exists there
            for _ in range(20):
                sim.step()
            veh = sim.vehicles
            assert veh.count >= 5
            lo, hi = road.lane_bounds(veh.s)
            lane = road.lane_of_d(veh.d)
            assert ((lane >= lo - 1) & (lane <= hi + 1)).all()  # (a lane change may be under way)


def test_three_lanes_that_leave_as_one(tmp_path):
    edges = '<edge id="ab" from="a" to="b" numLanes="3"/><edge id="bc" from="b" to="c" numLanes="1"/>'
    road = load_road(
        scenario=make_scenario(tmp_path / "three1", STRAIGHT_NODES, edges, 'edges = ["ab", "bc"]')
    )
    # netconvert goes on from the leftmost lane only: the one lane is route lane 2
    assert road.layout.first == (0, 2) and road.layout.count == (3, 1)
    assert [c.lanes for c in road.checkpoints] == [(2,), ()]
    with Simulation(road, EpisodeConfig(name="three1", max_time=30.0)) as sim:
        sim.reset(1)
        for _ in range(50):
            sim.step()


@pytest.mark.parametrize(
    ("name", "network", "edges"),
    [("rampexit", "game/ramp/ramp.net.xml", RAMP_EXIT), ("a10link", "game/A10KW/osm.net.xml", A10_LINK)],
)
def test_the_expert_drives_through_one_lane_links(name, network, edges, tmp_path, capsys):
    from irlsim.cli import main

    folder = wheel_scenario(tmp_path / name, network, edges)
    out = tmp_path / "sim.json"
    argv = ["sim", "--scenario", str(folder), "--driver", "expert", "--episodes", "1", "--seed", "2"]
    assert main([*argv, "--max-time", "150", "--vehicles", "8", "--json", str(out)]) == 0
    assert "Traceback" not in capsys.readouterr().err
    ep = json.loads(out.read_text())["episodes"][0]
    assert ep["end_reason"] == "route_end" and ep["sim/collisions"] == 0 and ep["sim/exits"] == 0
    assert ep["sim/checkpoints_in_lane"] == ep["sim/checkpoints_passed"] >= 1


def test_a_route_that_crosses_itself_is_refused_in_one_line(tmp_path):
    """The A10's link loops back under its own motorway, with no junction where they cross: a bridge in a
    network without heights, where the vehicles of the other level would overlap the ego."""
    folder = wheel_scenario(tmp_path / "cross", "game/A10KW/osm.net.xml", [*A10_LINK, "308396219"])
    with pytest.raises(
        IrlsimError, match="crosses itself without a junction near .* end the route before it does"
    ) as e:
        load_road(scenario=folder)
    assert "\n" not in str(e.value)


def test_the_ego_departs_in_a_lane_of_its_own_edge(tmp_path):
    """A sweep's random network (seed 0, network 224) whose route's lanes vary: the start's lane is one of
    the edge it departs from (SUMO refused departure lane -1 there, a crash), and the episode runs."""
    from irlsim.cli import main
    from irlsim.road.generate import build_network, network_params

    net = build_network(network_params(0, 224), tmp_path)
    edges = ["38", "-39", "-39.316.29", "-11", "-11.270.83", "13", "13.317.09", "46", "46.161.76", "93"]
    edges += ["93.342.35", "124"]
    scenario = tmp_path / "scenario.toml"
    scenario.write_text(
        f'name = "r224"\n[network]\nfile = "{net}"\n[route]\nedges = {edges!r}\n'.replace("'", '"')
    )
    out = tmp_path / "sim.json"
    argv = ["sim", "--scenario", str(scenario), "--driver", "expert", "--episodes", "1", "--seed", "0"]
    assert main([*argv, "--max-time", "5", "--json", str(out)]) == 0
