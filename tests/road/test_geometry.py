"""Route-frame geometry: projection against a brute-force search, lane centrelines, route distances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from irlsim.road import LANE_WIDTH, LaneCentreline
from irlsim.road.geometry import RASTER_REACH
from irlsim.road.scenario import load_scenario

#: the oval's route, as its scenario file (sumo_net/oval/scenario.toml) writes it
LOOP_EDGES = load_scenario("oval", build=False).edges


def _brute_force_frenet(road, qx: np.ndarray, qy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest of ALL reference segments (clipped foot), then the library's exact refinement."""
    a = road.ref_xy  # [M, 2]
    u = np.roll(a, -1, axis=0) - a
    ln = np.linalg.norm(u, axis=1)
    u = u / ln[:, None]
    seg = np.empty(len(qx), dtype=np.int64)
    t = np.empty(len(qx))
    for i in range(0, len(qx), 200):
        q = np.stack([qx[i : i + 200], qy[i : i + 200]], axis=1)[:, None, :]  # [C, 1, 2]
        tc = np.clip(((q - a) * u).sum(-1), 0.0, ln)  # [C, M]
        dist = np.linalg.norm(q - (a + u * tc[..., None]), axis=-1)
        j = np.argmin(dist, axis=1)
        seg[i : i + 200], t[i : i + 200] = j, tc[np.arange(len(j)), j]
    return road._project_smooth(qx, qy, seg, t)


def _query_points(road, rng) -> tuple[np.ndarray, np.ndarray]:
    lap = road.lap_length
    parts = []
    # on and beside the loop, all lanes and the shoulders, straights and curves alike
    s = rng.uniform(0.0, lap, 2000)
    parts.append(road.to_xy(s, rng.uniform(-12.0, 12.0, s.shape)))
    # the half circles (x beyond the straights' ends), out to the raster's reach and beyond
    xy = np.stack(road.to_xy(s, rng.uniform(-70.0, 70.0, s.shape)), axis=1)
    xy = xy[(xy[:, 0] < 0.0) | (xy[:, 0] > 700.0)][:600]
    parts.append((xy[:, 0], xy[:, 1]))
    # the ramps (their lanes as SUMO draws them, within 3 m)
    for eid in ("exit1", "exit2", "entry1", "entry2"):
        shape = np.asarray(road.net.getEdge(eid).getLane(0).getShape())
        k = rng.integers(0, len(shape) - 1, 150)
        f = rng.uniform(0.0, 1.0, 150)[:, None]
        p = shape[k] * (1 - f) + shape[k + 1] * f + rng.uniform(-3.0, 3.0, (150, 2))
        parts.append((p[:, 0], p[:, 1]))
    # anywhere around the course, inside the oval included (the full search far from the road)
    parts.append((rng.uniform(-300.0, 1000.0, 400), rng.uniform(-150.0, 450.0, 400)))
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def test_to_frenet_equals_brute_force(road):
    """The raster-windowed search finds the same nearest segment as a search over all of them, so
    (s, d) agree within 1e-9 m everywhere: on the lanes, on the ramps, in the curves, far away."""
    qx, qy = _query_points(road, np.random.default_rng(0))
    s, d = road.to_frenet(qx, qy)
    s_ref, d_ref = _brute_force_frenet(road, qx, qy)
    ds = (s - s_ref + road.lap_length / 2) % road.lap_length - road.lap_length / 2
    assert np.abs(ds).max() < 1e-9 and np.abs(d - d_ref).max() < 1e-9
    assert (np.abs(d) > RASTER_REACH).sum() > 50, "the sample must also cover points beyond the raster"
    # the same answers one point at a time and in any shape
    s2, d2 = road.to_frenet(qx[:200].reshape(10, 20), qy[:200].reshape(10, 20))
    np.testing.assert_array_equal(s2.ravel(), s[:200])
    np.testing.assert_array_equal(d2.ravel(), d[:200])
    s1, d1 = road.to_frenet(qx[7], qy[7])
    assert s1.shape == () and (float(s1), float(d1)) == (s[7], d[7])


def _half_circle_bounds(road) -> list[tuple[float, float]]:
    """Route-frame (start, end) of each half circle with 50 m of straight on both sides."""
    s, _ = road.to_frenet(np.array([650.0, 650.0, 50.0, 50.0]), np.array([0.0, 300.0, 300.0, 0.0]))
    return [(s[0], s[1]), (s[2], s[3])]


def _lane_arc(c: LaneCentreline, a: float, b: float) -> float:
    return float((c.arc_length(b) - c.arc_length(a)) % c.length)


def test_lane_centrelines_differ_by_pi_lane_width_per_half_circle(road):
    """Offset curves: a lane 3.2 m further out is longer by 3.2 m x the angle turned, pi per half circle,
    and exactly as long on the straights. Tolerance 1e-4 m: moving a polyline's vertices along their
    bisector normals by d shortens the offset turn at each vertex by d (phi - 2 sin(phi / 2)) ~ d phi^3 / 24,
    ~5e-6 m over a half circle of 0.5 m segments (phi = 0.5 / 150)."""
    lanes = [road.lane_centreline(k) for k in range(3)]
    for a, b in _half_circle_bounds(road):
        arc = [_lane_arc(c, a, b) for c in lanes]
        assert arc[0] - arc[1] == pytest.approx(math.pi * LANE_WIDTH, abs=1e-4)
        assert arc[1] - arc[2] == pytest.approx(math.pi * LANE_WIDTH, abs=1e-4)
    (_, b0), (a1, b1) = _half_circle_bounds(road)
    for a, b in ((b0, a1), (b1, _half_circle_bounds(road)[0][0])):  # the two straights between
        arc = [_lane_arc(c, a, b) for c in lanes]
        assert arc[0] == pytest.approx(arc[1], abs=1e-4) and arc[2] == pytest.approx(arc[1], abs=1e-4)
    assert lanes[0].length - lanes[1].length == pytest.approx(2 * math.pi * LANE_WIDTH, abs=2e-4)
    assert lanes[1].length == pytest.approx(road.lap_length, abs=1e-9)  # lane 1 runs on the reference


def test_lane_centreline_points_lie_on_their_lane(road):
    for k in range(3):
        c = road.lane_centreline(k)
        assert c.lane == k and c.x.shape == c.y.shape == c.s.shape == road.ref_s.shape
        assert c.s[0] == 0.0 and np.all(np.diff(c.s) > 0) and c.length > c.s[-1]
        s, d = road.to_frenet(c.x, c.y)
        ds = (s - c.ref_s + road.lap_length / 2) % road.lap_length - road.lap_length / 2
        assert np.abs(ds).max() < 1e-6 and np.abs(d - (k - 1) * LANE_WIDTH).max() < 1e-6
        assert c.arc_length(c.ref_s[5]) == pytest.approx(c.s[5], abs=1e-9)
        assert c.arc_length(c.ref_s[5] + 3 * road.lap_length) == pytest.approx(c.s[5], abs=1e-6)
    with pytest.raises(ValueError, match="lane"):
        road.lane_centreline(3)


def _mid_lane_pos(road, edge_id: str, x: float, y: float) -> float:
    """SUMO edge position [m] of a point: its offset along the edge's middle lane (edge-length units)."""
    from sumolib.geomhelper import polygonOffsetWithMinimumDistanceToPoint, polyLength

    edge = road.net.getEdge(edge_id)
    mid = edge.getLane(1).getShape()
    return polygonOffsetWithMinimumDistanceToPoint((x, y), mid) * edge.getLength() / polyLength(mid)


def test_closed_form_route_distance_matches_dijkstra(road):
    """``remaining_distance`` ((s_target - s) mod lap) against sumolib's Dijkstra (``route_distance``) for
    points on all three lanes of every loop edge, once-round-the-loop pairs included.

    Points are drawn at SUMO lane positions (scaled along each lane's own shape, as SUMO does) and
    measured on the SUMO side along the middle lane, which is what edge lengths count. Tolerance: the
    route frame's reference is SUMO's middle lane smoothed over +-8 m, which cuts the junctions' shape
    kinks and makes a lap ``lap_sumo - lap_length`` (~1.1 m) shorter; plus 0.4 m for projecting a point
    onto the smoothed line instead of the raw one near a kink.
    """
    from sumolib.geomhelper import polyLength, positionAtShapeOffset

    net = road.net
    lap_sumo = sum(net.getEdge(e).getLength() for e in LOOP_EDGES) + sum(
        net.getInternalPath(conns)[1]
        for e in LOOP_EDGES
        for nxt, conns in net.getEdge(e).getOutgoing().items()
        if nxt.getID() in LOOP_EDGES
    )
    tol = abs(lap_sumo - road.lap_length) + 0.4
    assert tol < 2.0
    rng = np.random.default_rng(1)
    pts = []
    for eid in LOOP_EDGES:
        edge = net.getEdge(eid)
        for k in range(3):
            lane = edge.getLane(k)
            shape = lane.getShape()
            for pos in rng.uniform(0.0, edge.getLength(), 4):
                x, y = positionAtShapeOffset(shape, pos * polyLength(shape) / lane.getLength())
                pts.append((eid, _mid_lane_pos(road, eid, x, y), x, y))
    xy = np.array([(p[2], p[3]) for p in pts])
    s, d = road.to_frenet(xy[:, 0], xy[:, 1])
    assert set(road.lane_of_d(d).tolist()) == {0, 1, 2}
    once_round = 0
    for i in range(len(pts)):
        for j in rng.choice(len(pts), 12, replace=False):
            (ea, pa, _, _), (eb, pb, _, _) = pts[i], pts[j]
            closed = float(road.remaining_distance(s[i], s[j]))
            dijkstra = road.route_distance(ea, pa, eb, pb)
            assert closed == pytest.approx(dijkstra, abs=tol), (ea, pa, eb, pb)
            once_round += ea == eb and pb < pa
    assert once_round > 5
