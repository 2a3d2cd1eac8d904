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
    return grid_scenario(tmp_path_factory.mktemp(f"turns{request.param}"), request.param)


def grid_scenario(folder: Path, lanes: int) -> Path:
    """A scenario folder: netgenerate's 4 x 4 grid of 200 m roads of ``lanes`` lanes, the route ROUTE."""
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


def test_a_car_following_the_next_lane_through_a_turn_is_no_wider_in_the_frame(grid_turns):
    """A car on the junction lane of the next lane's right turn, along that lane, is turned to the route's
    reference there (the two bend at different places) but sits in its own lane: in the route frame it
    is about as wide as it is, within its lane's band, where the rotated box's closed form about the
    reference's heading made it up to twice as wide (the planner then labelled every policy in the lane
    beside it a collision, and a learned reward turned into the car)."""
    from irlsim.planner.planner import BOX_TURN_MIN, route_frame_boxes
    from irlsim.road import wrap_angle
    from irlsim.sim.types import VehicleStates

    road = load_road(scenario=grid_turns)
    lane = road.net.getEdge(ROUTE[0]).getLane(0)  # the right lane, the turn's inner lane
    via = next(c.getViaLaneID() for c in lane.getOutgoing() if c.getTo().getID() == ROUTE[1])
    # the lane's way through the turn, every 0.1 m: the incoming lane's end, the junction lane
    path = np.asarray(lane.getShape()[-2:] + road.net.getLane(via).getShape()[1:])
    seg = np.hypot(*np.diff(path, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    fine = np.arange(0.0, arc[-1], 0.1)
    px, py = np.interp(fine, arc, path[:, 0]), np.interp(fine, arc, path[:, 1])
    # front bumpers in the junction, each car's body the chord to its back 4.5 m behind on the lane (as
    # SUMO places a car: its angle from its back to its front)
    front = np.flatnonzero(fine >= arc[-1] - float(road.net.getLane(via).getLength()))[::5]
    front = front[fine[front] >= 4.5]
    back = np.searchsorted(fine, fine[front] - 4.5)
    x, y = px[front], py[front]
    yaw = np.arctan2(y - py[back], x - px[back])
    s, d = road.to_frenet(x, y)
    n = len(x)
    cars = VehicleStates(tuple(f"v{i}" for i in range(n)), x, y, yaw, np.zeros(n), s, d,
                         np.full(n, 4.5), np.full(n, 1.8))  # fmt: skip
    theta = wrap_angle(yaw - road.heading(s))
    assert (np.abs(theta) > BOX_TURN_MIN).any()  # turned to the reference: its box is recomputed
    closed_form = 4.5 * np.abs(np.sin(theta)) + 1.8 * np.abs(np.cos(theta))
    out = route_frame_boxes(road, cars)
    assert closed_form.max() > 2.5 and (out.width < 2.4).all(), (closed_form, out.width)
    # and within the right lane's band
    centre = float(road.lane_center(0))
    assert (np.abs(out.d - centre) < road.lane_width / 2 + 0.5).all(), (out.d, centre)
