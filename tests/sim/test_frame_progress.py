"""Routes that come back near themselves (real SUMO, a two-way grid from the wheel's netgenerate): round a
block and back on the other carriageway, and through the same junction twice. The route frame projects
them by progress (``Road.to_frenet``'s ``near``): the same xy gets each pass's own s, the traffic keeps
its progress across the shared junction, and the expert drives them. A flat route keeps its bytes; a
short route loads and drives; one that leaves no start is refused in one line."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import sumo_binary, sumo_home
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
from irlsim.sim.start import check_start
from tests.road.test_scenario import make_scenario

#: round the block B0-C0-C1-B1 and back on the other carriageway of A0-B0 (junction B0 twice)
BACK = ["A0B0", "B0C0", "C0C1", "C1B1", "B1B0", "B0A0"]
#: east through junction B1, round the block, then south through B1 again (it crosses itself there)
CROSS = ["A1B1", "B1C1", "C1C2", "C2B2", "B2B1", "B1B0"]


@pytest.fixture(scope="module")
def grid(tmp_path_factory) -> Path:
    """A 3 x 3 two-way grid of 150 m edges, one lane each way, priority junctions."""
    out = tmp_path_factory.mktemp("grid") / "grid.net.xml"
    args = ["--grid", "--grid.number", "3", "--grid.length", "150", "-L", "1", "--no-turnarounds"]
    env = {**os.environ, "SUMO_HOME": sumo_home()}
    cmd = [sumo_binary("netgenerate"), *args, "--default-junction-type", "priority", "-o", str(out)]
    subprocess.run(cmd, env=env, check=True, capture_output=True)
    return out


def scenario(folder: Path, net: Path, edges: list[str]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    quoted = ", ".join(f'"{e}"' for e in edges)
    (folder / "scenario.toml").write_text(f'[network]\nfile = "{net}"\n\n[route]\nedges = [{quoted}]\n')
    return folder


def _passes(road, lane_d: float) -> tuple[np.ndarray, np.ndarray]:
    """Route positions (s_a, s_b) >= 50 m apart along the route whose points at offset ``lane_d`` lie
    within a metre of each other: where the route comes back on itself."""
    s = np.arange(road.route_begin_s, road.route_end_s, 1.0)
    x, y = road.to_xy(s, np.full(s.shape, lane_d))
    dist = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    a, b = np.nonzero((dist < 1.0) & (np.abs(s[:, None] - s[None, :]) > 50.0))
    return s[a], s[b]


@pytest.mark.parametrize("edges", [BACK, CROSS], ids=["back", "cross"])
def test_the_same_xy_gets_each_pass_its_own_s(grid, tmp_path, edges):
    road = load_road(scenario=scenario(tmp_path / "r", grid, edges))
    assert not road.flat and not road.closed
    # every point of both lanes round-trips with its own progress as the hint
    s = np.arange(road.route_begin_s, road.route_end_s, 0.7)
    for d0 in (-1.6, 0.0, 1.6):
        x, y = road.to_xy(s, np.full(s.shape, d0))
        s2, d2 = road.to_frenet(x, y, near=s + 3.0)  # a hint a step off
        assert np.abs(s2 - s).max() < 1e-6 and np.abs(d2 - d0).max() < 1e-6
    # one xy on two passes (the street's middle, the left edge of both carriageways): each hint gives
    # its own pass's s (and the xy back)
    half = road.lane_width / 2
    s_a, s_b = _passes(road, half)
    assert len(s_a) > 0
    x, y = road.to_xy(s_a, np.full(len(s_a), half))
    on_a, _ = road.to_frenet(x, y, near=s_a)
    on_b, d_b = road.to_frenet(x, y, near=s_b)
    assert np.abs(on_a - s_a).max() < 1e-6 and np.abs(on_b - s_b).max() < 2.0
    xb, yb = road.to_xy(on_b, d_b)
    assert np.hypot(xb - x, yb - y).max() < 1e-6
    # the stop lines' and edges' positions lie on their own passes: edges in route order
    starts = [a for _, a, _ in road.edge_bounds]
    assert starts == sorted(starts)


def test_traffic_keeps_its_progress_where_the_route_meets_itself(grid, tmp_path):
    road = load_road(scenario=scenario(tmp_path / "cross", grid, CROSS))
    cfg = EpisodeConfig(name="cross", n_vehicles=8, max_time=60.0, spawn_distance=120.0)
    with Simulation(road, cfg) as sim:
        sim.reset(0)
        last: dict[str, float] = {}
        jumps = []
        for _ in range(400):  # the ego stands; the traffic drives past it through both passes
            sim.step()
            veh = sim.vehicles
            for vid, s in zip(veh.ids, veh.s, strict=True):
                if vid in last:
                    jumps.append(abs(s - last[vid]))
                last[vid] = float(s)
            x, y = road.to_xy(veh.s, veh.d)
            assert np.hypot(x - veh.x, y - veh.y).max(initial=0.0) < 1e-6
        assert len(jumps) > 1000 and max(jumps) < 5.0  # 0.1 s steps: no vehicle jumps to the other pass


@pytest.mark.parametrize("edges", [BACK, CROSS], ids=["back", "cross"])
def test_the_expert_drives_a_route_that_comes_back(grid, tmp_path, edges):
    from irlsim.cli import main

    folder = scenario(tmp_path / "r", grid, edges)
    out = tmp_path / "sim.json"
    argv = ["sim", "--scenario", str(folder), "--driver", "expert", "--episodes", "1", "--seed", "3"]
    assert main([*argv, "--vehicles", "6", "--max-time", "40", "--json", str(out)]) == 0
    ep = json.loads(out.read_text())["episodes"][0]
    assert ep["sim/collisions"] == 0 and ep["sim/exits"] == 0 and ep["end_reason"] in ("route_end", "timeout")


def test_a_flat_route_projects_as_before():
    road = load_road()  # the oval
    assert road.flat
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-200.0, 900.0, 500), rng.uniform(-50.0, 350.0, 500)
    s, d = road.to_frenet(x, y)
    s2, d2 = road.to_frenet(x, y, near=rng.uniform(0.0, road.lap_length, 500))
    assert s.tobytes() == s2.tobytes() and d.tobytes() == d2.tobytes()


def test_a_short_route_loads_and_drives(grid, tmp_path):
    from irlsim.cli import main

    folder = scenario(tmp_path / "short", grid, ["A0B0"])
    road = load_road(scenario=folder)
    assert 120.0 < road.route_end_s - road.route_begin_s < 170.0
    out = tmp_path / "sim.json"
    argv = ["sim", "--scenario", str(folder), "--driver", "expert", "--episodes", "1"]
    assert main([*argv, "--vehicles", "3", "--max-time", "40", "--json", str(out)]) == 0
    ep = json.loads(out.read_text())["episodes"][0]
    assert ep["end_reason"] == "route_end" and ep["sim/collisions"] == 0 and ep["sim/exits"] == 0


def test_a_route_with_no_start_is_refused_in_one_line(tmp_path):
    """Two 35 m edges through a traffic light: every spot leaves too little room ahead or to stop."""
    nodes = (
        '<node id="a" x="0" y="0"/><node id="b" x="35" y="0" type="traffic_light"/>'
        '<node id="c" x="70" y="0"/>'
    )
    edges = '<edge id="ab" from="a" to="b" numLanes="1"/><edge id="bc" from="b" to="c" numLanes="1"/>'
    road = load_road(scenario=make_scenario(tmp_path / "tiny", nodes, edges, 'edges = ["ab", "bc"]'))
    with pytest.raises(IrlsimError, match="leaves no start for the ego") as e:
        check_start(road, EpisodeConfig(name="tiny"))
    assert "\n" not in str(e.value)
    too_short = make_scenario(tmp_path / "tinier", nodes, edges, 'edges = ["ab"]')
    with pytest.raises(IrlsimError, match="shorter than the 50 m") as e:
        load_road(scenario=too_short)
    assert "\n" not in str(e.value)
