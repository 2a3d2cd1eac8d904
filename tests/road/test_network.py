"""The SUMO network of the oval: topology, reproducible build (the one network builder and its staleness
rule), route-frame geometry, route distances."""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest

from irlsim.road.network import SUMO_NET_DIR, config_sources, is_stale
from irlsim.road.scenario import load_scenario

#: the oval's scenario folder and the files its network is built from
OVAL_DIR = SUMO_NET_DIR / "oval"
OVAL_FILES = ("scenario.toml", "netconvert.cfg", "oval.nod.xml", "oval.edg.xml")

#: the oval's route, as its scenario file (sumo_net/oval/scenario.toml) writes it
LOOP_EDGES = load_scenario("oval", build=False).edges


def test_loop_has_three_lanes(road):
    assert road.edges == LOOP_EDGES == ("A_S1", "S1_X1", "X1_B", "B_S2", "S2_X2", "X2_A")
    for eid in LOOP_EDGES:
        assert road.net.getEdge(eid).getLaneNumber() == 3


def test_exits_branch_from_lane_zero(road):
    """Every lane connection that leaves the loop (to an edge not on the route) is an exit, from lane 0."""
    exits = set()
    for eid in LOOP_EDGES:
        for k, lane in enumerate(road.net.getEdge(eid).getLanes()):
            for c in lane.getOutgoing():
                if c.getTo().getID() not in LOOP_EDGES:
                    assert k == 0, f"exit {c.getTo().getID()} reachable from lane {k}"
                    exits.add(c.getTo().getID())
    assert exits == {e.edge for e in road.exits} == {"exit1", "exit2"}


def test_two_allway_stops(road):
    stops = [n for n in road.net.getNodes() if n.getType() == "allway_stop"]
    assert len(stops) == 2
    assert len(road.stop_lines) == 2


def _oval_copy(folder):
    """The oval's scenario folder without its network: what the builder starts from."""
    folder.mkdir()
    for s in OVAL_FILES:
        shutil.copy(OVAL_DIR / s, folder / s)
    return folder / "scenario.toml"


def test_build_is_byte_identical(road, tmp_path):
    """Built twice elsewhere, the oval's network has the shipped build's bytes, without the time stamp."""
    scenario = _oval_copy(tmp_path / "oval")
    first = load_scenario(scenario, force=True).net_file.read_bytes()
    second = load_scenario(scenario, force=True).net_file.read_bytes()
    assert first == second == road.net_file.read_bytes()
    assert b"generated on" not in first


def test_net_is_rebuilt_when_missing_or_older_than_a_source(tmp_path):
    scenario = _oval_copy(tmp_path / "oval")
    sources = config_sources(tmp_path / "oval" / "netconvert.cfg")
    assert sorted(p.name for p in sources) == ["netconvert.cfg", "oval.edg.xml", "oval.nod.xml"]
    for s in sources:
        os.utime(s, (1_000_000.0, 1_000_000.0))
    net = tmp_path / "oval" / "oval.net.xml"
    assert is_stale(net, sources)  # missing
    assert load_scenario(scenario).net_file == net and net.is_file() and not is_stale(net, sources)
    os.utime(net, (2_000_000.0, 2_000_000.0))
    load_scenario(scenario)  # up to date: not rebuilt, so the file keeps its time stamp
    assert net.stat().st_mtime == 2_000_000.0
    for s in sources:  # any one source newer than the net makes it stale
        os.utime(s, (3_000_000.0, 3_000_000.0))
        assert is_stale(net, sources), s
        load_scenario(scenario)
        assert net.stat().st_mtime > 3_000_000.0 and not is_stale(net, sources)
        os.utime(s, (1_000_000.0, 1_000_000.0))
        os.utime(net, (2_000_000.0, 2_000_000.0))
    assert not is_stale(net, sources)
    load_scenario(scenario, force=True)  # forced: rebuilt though up to date
    assert net.stat().st_mtime > 3_000_000.0
    net.unlink()
    assert is_stale(net, sources)


def _lane_samples(road, lane, step: float = 1.0) -> np.ndarray:
    pts = np.asarray(lane.getShape())
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    si = np.linspace(0.0, s[-1], max(2, int(s[-1] / step) + 1))
    return np.stack([np.interp(si, s, pts[:, 0]), np.interp(si, s, pts[:, 1])], axis=1)


def test_frenet_round_trip_every_lane(road):
    """xy -> (s, d) -> xy within 1 cm on every lane near the loop, internal (junction) lanes included;
    loop lanes land in their own lane."""
    checked = 0
    for edge in road.net.getEdges(withInternal=True):
        for lane in edge.getLanes():
            xy = _lane_samples(road, lane)
            s, d = road.to_frenet(xy[:, 0], xy[:, 1])
            near = np.abs(d) < 8.0  # ramps far from the loop are outside the route frame's reach
            x2, y2 = road.to_xy(s, d)
            err = np.hypot(x2 - xy[:, 0], y2 - xy[:, 1])[near]
            assert err.size == 0 or err.max() < 0.01, f"{lane.getID()}: round trip error {err.max():.4f} m"
            checked += int(near.sum())
            on_loop = edge.getID() in LOOP_EDGES or any(
                edge.getID().startswith(f":{n}_") for n in ("S1", "S2")
            )
            if on_loop:
                assert np.all(road.lane_of_d(d) == lane.getIndex()), lane.getID()
    assert checked > 6000


def test_route_distance_equals_sumolib(road):
    rng = np.random.default_rng(0)
    edges = list(LOOP_EDGES)
    for _ in range(60):
        a, b = rng.choice(edges, 2)
        la, lb = road.net.getEdge(a).getLength(), road.net.getEdge(b).getLength()
        pa, pb = rng.uniform(0, la), rng.uniform(0, lb)
        _, cost = road.net.getShortestPath(road.net.getEdge(a), road.net.getEdge(b), fromPos=pa, toPos=pb)
        if a == b and pb < pa:  # once round: sumolib leaves out the first junction (see the next test)
            e = road.net.getEdge(a)
            vias = [road.net.getInternalPath(c)[1] for n, c in e.getOutgoing().items() if n.getID() in edges]
            cost += min(vias)
        assert road.route_distance(a, pa, b, pb) == pytest.approx(cost, abs=1e-6)


def test_route_distance_once_round_the_loop(road):
    """sumolib's looping search leaves out the first junction's internal lane (junction B after X1_B);
    route_distance counts it, so going round equals a lap of edges and junction lanes less 200 m."""
    e = road.net.getEdge("X1_B")
    _, cost = road.net.getShortestPath(e, e, fromPos=300.0, toPos=100.0)
    d = road.route_distance("X1_B", 300.0, "X1_B", 100.0)
    via = road.net.getInternalPath(e.getOutgoing()[road.net.getEdge("B_S2")])[1]
    assert via == pytest.approx(18.6, abs=0.5)  # the internal lane of junction B
    assert d == pytest.approx(cost + via, abs=1e-6)
    lap_sumo = road.route_distance("X1_B", 100.0, "X1_B", 99.999) + 0.001
    assert d == pytest.approx(lap_sumo - 200.0, abs=1e-6)
    assert lap_sumo == pytest.approx(road.lap_length, abs=1.5)


def test_exit_unreachable_target(road):
    assert road.route_distance("exit1", 10.0, "A_S1", 10.0) == np.inf
