"""Routes that turn at junctions, right then left (real SUMO, a netgenerate grid in tmp_path): the
reference line follows the turn's junction lanes (also where the middle lane does not turn), and the
expert takes a turn as a driver does, at most about TURN_LAT_ACC of lateral acceleration on the
reference's curvature, slower than the road's limit; roads without such turns keep no turn speed."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from irlsim.planner.expert import ExpertDriver, planner_config_for
from irlsim.road import load_road
from irlsim.road.geometry import TURN_LAT_ACC
from irlsim.road.network import sumo_binary
from irlsim.road.route import offset_polyline
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation

ROUTE = ["A0A1", "A1B1", "B1B2", "B2B3"]  # north, right turn east, left turn north, on north


@pytest.fixture(scope="module", params=[2, 3])
def grid_turns(request, tmp_path_factory) -> Path:
    """A 4 x 4 grid of roads of 2 or 3 lanes (with 3, the middle lane turns neither right nor left)."""
    lanes = request.param
    folder = tmp_path_factory.mktemp(f"turns{lanes}")
    args = ["--grid", "--grid.number", "4", "--grid.length", "200", "--default.lanenumber", str(lanes)]
    proc = subprocess.run(
        [sumo_binary("netgenerate"), *args, "--no-turnarounds", "true", "-o", "grid.net.xml"],
        cwd=folder,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    edges = ", ".join(f'"{e}"' for e in ROUTE)
    (folder / "scenario.toml").write_text(f'[network]\nfile = "grid.net.xml"\n\n[route]\nedges = [{edges}]\n')
    return folder


def test_the_reference_follows_the_turns(grid_turns):
    road = load_road(scenario=grid_turns)
    heading = road.heading(np.array([road.route_begin_s + 50.0, road.route_end_s - 50.0]))
    assert heading[0] == pytest.approx(np.pi / 2, abs=0.05) and heading[1] == pytest.approx(
        np.pi / 2, abs=0.05
    )
    s = np.arange(road.route_begin_s, road.route_end_s, 1.0)
    kappa = road.curvature(s)
    assert kappa.min() < -1 / 30 and kappa.max() > 1 / 30  # a right (clockwise) and a left turn
    # the turn speed is finite at the turns only, and below the road's limit there
    v = np.array([road.turn_speed_over(float(a), float(a) + 1.0) for a in s])
    turning = np.isfinite(v)
    assert turning.any() and (v[turning] < road.max_speed_limit).all()
    # never faster than TURN_LAT_ACC allows on the curvature the planner reads (within 5 m: the planner
    # caps its target by the lowest turn speed within its horizon's reach)
    v5 = np.array([road.turn_speed_over(float(a) - 5.0, float(a) + 5.0) for a in s])
    assert (v5[turning] ** 2 * np.abs(kappa[turning]) <= TURN_LAT_ACC * 1.02).all()
    # the reference follows each turn's junction lane moved onto the middle of the road, also where the
    # middle lane turns neither way: no chord across the corner. Within 0.6 m: the smoothing's window
    # narrows in a tight turn (over +-8 m it cut this grid's right turns by 1.0-1.7 m, the ego's lane
    # into the next lane's turn)
    fine = np.arange(road.route_begin_s, road.route_end_s, 0.1)
    x, y = road.to_xy(fine, np.zeros_like(fine))
    middle = (road.n_lanes - 1) / 2
    gaps = []
    for a, b in zip(ROUTE, ROUTE[1:], strict=False):
        for ln in road.net.getEdge(a).getLanes():
            for c in ln.getOutgoing():
                if c.getTo().getID() == b:
                    via = np.asarray(road.net.getLane(c.getViaLaneID()).getShape())
                    via = offset_polyline(via, (middle - ln.getIndex()) * road.lane_width)
                    gap = np.hypot(via[:, 0][:, None] - x, via[:, 1][:, None] - y).min(axis=1)
                    gaps.append(gap.max())
    assert max(gaps) < 0.6, gaps
    # the shipped roads have no turn at a junction: no turn speed, their planners as before
    for name in ("oval", "ramp", "motorway", "corridor", "grid"):
        other = load_road(scenario=name)
        assert other.turn_speed_over(other.route_begin_s, other.route_begin_s + other.lap_length) == np.inf


def test_the_expert_takes_turns_as_a_driver(grid_turns):
    road = load_road(scenario=grid_turns)
    cfg = EpisodeConfig(name=str(grid_turns), n_vehicles=0, max_time=120.0)
    driver = ExpertDriver(road, planner_config_for(cfg))
    with Simulation(road, cfg) as sim:
        obs = sim.reset(2)
        while not sim.done:
            sim.execute(driver.plan(obs))
            obs = sim.observe()
        stats = sim.stats
        odo = sim.odometry
    assert stats["end_reason"] == "route_end" and stats["sim/collisions"] == 0 and stats["sim/exits"] == 0
    assert stats["sim/checkpoints_in_lane"] == stats["sim/checkpoints_passed"]
    t = np.array([e.t for e in odo])
    v = np.array([e.v for e in odo])
    yaw = np.unwrap(np.array([e.yaw for e in odo]))
    a_lat = np.abs(v[1:] * np.diff(yaw) / np.diff(t))
    a_lat = np.convolve(a_lat, np.ones(5) / 5, mode="same")  # over 0.5 s
    assert a_lat.max() <= TURN_LAT_ACC + 0.5  # the planner's own limit is 5 m/s^2
    assert v.max() > 1.5 * v[1:][a_lat.argmax()]  # slower in the turn than on the straight
