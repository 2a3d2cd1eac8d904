"""What a route on a SUMO network says: its edges, whether it is a loop, its lanes, the lane shapes along
it (junction lanes included), its all-way stops, the exits that leave it and the lanes it goes on from.

Pure functions over a ``sumolib`` network, for :class:`irlsim.road.Road`. Errors are one line naming the
edge at fault and the fix (``IrlsimError``), raised before any simulation starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from irlsim.errors import IrlsimError


def resolve_route(net: object, edges: tuple[str, ...], from_edge: str, to_edge: str) -> tuple[str, ...]:
    """The route's edges: ``edges`` checked against the network, or the shortest path from/to."""
    if not edges:
        for e in (from_edge, to_edge):
            if not net.hasEdge(e):  # type: ignore[attr-defined]
                raise IrlsimError(f"route: edge '{e}' is not in the network: check [route] from / to")
        path, _ = net.getShortestPath(net.getEdge(from_edge), net.getEdge(to_edge))  # type: ignore[attr-defined]
        if path is None:
            raise IrlsimError(
                f"route: no path from '{from_edge}' to '{to_edge}' on the network: choose edges that connect"
            )
        return tuple(e.getID() for e in path)
    missing = [e for e in edges if not net.hasEdge(e)]  # type: ignore[attr-defined]
    if missing:
        raise IrlsimError(f"route: edge '{missing[0]}' is not in the network: check [route] edges")
    for a, b in zip(edges, edges[1:], strict=False):
        if not _connects(net, a, b):
            raise IrlsimError(
                f"route: edge '{a}' does not lead into '{b}' (no connection): fix [route] edges"
            )
    return tuple(edges)


def _connects(net: object, a: str, b: str) -> bool:
    return any(n.getID() == b for n in net.getEdge(a).getOutgoing())  # type: ignore[attr-defined]


def is_closed(net: object, edges: tuple[str, ...]) -> bool:
    """True when the route's last edge leads into its first: a loop, driven in laps."""
    return len(edges) > 1 and _connects(net, edges[-1], edges[0])


#: the vehicle class whose lanes are the route's lanes (the ego's and the background traffic's)
CAR_CLASS = "passenger"


def car_lanes(edge: object) -> tuple[int, ...]:
    """SUMO indices of the lanes of ``edge`` that admit passenger cars, rightmost first (a sidewalk, a
    bike, bus or tram lane is left out: it bounds the road but is no lane of the route)."""
    return tuple(ln.getIndex() for ln in edge.getLanes() if ln.allows(CAR_CLASS))  # type: ignore[attr-defined]


@dataclass(frozen=True)
class LaneLayout:
    """The lanes along a route on one numbering: lane ``g`` (0 = the rightmost car lane anywhere on the
    route) is the car lane ``g - first[i]`` of route edge ``i`` (counted from the right among the lanes
    that admit cars: SUMO lane ``lanes[i][g - first[i]]``), where it exists. Lanes that go straight on
    across a junction keep their number; a lane added on the right (an on-ramp) or dropped there shifts
    ``first`` by one."""

    first: tuple[int, ...]  # per route edge: the route lane of its rightmost car lane
    count: tuple[int, ...]  # per route edge: its number of car lanes
    n_lanes: int  # lanes on the route's numbering
    width: float  # [m] the lane width of the route frame (see :func:`route_width`)
    #: per route edge, the SUMO indices of its car lanes, rightmost first; () = SUMO lanes 0..count-1
    lanes: tuple[tuple[int, ...], ...] = ()
    #: per route edge, its car lanes' real widths [m], rightmost first, where some differ from ``width``;
    #: () = every lane is ``width`` wide
    widths: tuple[tuple[float, ...], ...] = ()

    @property
    def varies(self) -> bool:
        """True when some edge lacks some of the route's lanes (lanes added, dropped, merging)."""
        return any(c != self.n_lanes for c in self.count)

    def edge_lane(self, i: int, lane: int) -> int:
        """SUMO lane index on route edge ``i`` of route lane ``lane``; -1 where that edge lacks it."""
        k = lane - self.first[i]
        if not 0 <= k < self.count[i]:
            return -1
        return self.lanes[i][k] if self.lanes else k

    def route_lane(self, i: int, sumo_lane: int) -> int:
        """Route lane of SUMO lane ``sumo_lane`` of route edge ``i``; -1 for a lane that admits no cars."""
        if not self.lanes:
            return self.first[i] + sumo_lane
        idx = self.lanes[i]
        return self.first[i] + idx.index(sumo_lane) if sumo_lane in idx else -1


def lane_layout(net: object, edges: tuple[str, ...], closed: bool) -> LaneLayout:
    """The route's lane numbering (:class:`LaneLayout`) over the lanes that admit passenger cars, from
    SUMO's lane connections: across each junction the most common shift between a connection's from- and
    to-lane (the lanes that go straight on). Refuses an edge without a car lane."""
    n = len(edges)
    lanes = []
    for eid in edges:
        idx = car_lanes(net.getEdge(eid))  # type: ignore[attr-defined]
        if not idx:
            raise IrlsimError(
                f"route: edge '{eid}' has no lane for passenger cars (only sidewalks, bike, bus or tram "
                "lanes): choose a route of roads for cars"
            )
        lanes.append(idx)
    rank = [{k: j for j, k in enumerate(idx)} for idx in lanes]
    rel = [0]
    for i in range(n - 1 if not closed else n):
        j = (i + 1) % n
        a, b = net.getEdge(edges[i]), edges[j]  # type: ignore[attr-defined]
        shifts = [
            rank[i][k] - rank[j][c.getToLane().getIndex()]
            for k in lanes[i]
            for c in a.getLane(k).getOutgoing()
            if c.getTo().getID() == b and c.getToLane().getIndex() in rank[j]
        ]
        if not shifts:
            raise IrlsimError(f"route: no car lane of '{edges[i]}' leads into '{b}': fix [route] edges")
        shift = min(set(shifts), key=lambda v: (-shifts.count(v), abs(v), v))
        if i < n - 1:
            rel.append(rel[-1] + shift)
        elif rel[-1] + shift != rel[0]:
            raise IrlsimError(
                f"route: the loop's lanes do not join up at '{edges[0]}' (a lane added or dropped for good "
                "on a loop): choose a loop with the same lanes all round"
            )
    lo = min(rel)
    first = tuple(r - lo for r in rel)
    count = tuple(len(idx) for idx in lanes)
    n_lanes = max(f + c for f, c in zip(first, count, strict=True))
    contiguous = all(idx == tuple(range(len(idx))) for idx in lanes)
    widths = tuple(
        tuple(float(net.getEdge(eid).getLane(k).getWidth()) for k in idx)  # type: ignore[attr-defined]
        for eid, idx in zip(edges, lanes, strict=True)
    )
    width = route_width(widths, [float(net.getEdge(e).getLength()) for e in edges])  # type: ignore[attr-defined]
    uniform = all(w == width for ws in widths for w in ws)
    return LaneLayout(
        first, count, n_lanes, width, () if contiguous else tuple(lanes), () if uniform else widths
    )


def route_width(widths: tuple[tuple[float, ...], ...], lengths: list[float]) -> float:
    """[m] The one lane width of the route frame from every route edge's car lane widths: the common one
    where they agree (within 0.05 m), else their median weighted by edge length.

    The approximation where widths differ: the reference line follows the real middle of each edge's car
    lanes (see :func:`reference_lanes`), and lane ``g``'s centre is taken at ``(g - (n_lanes - 1) / 2) *
    width`` from it, so a lane of another width is placed and judged (the lane of an offset, the road's
    edges, off-road) up to half the width difference per lane from the middle away from where SUMO draws
    it (0.3 m for 3.6 m lanes on a 3.0 m frame, two lanes)."""
    ws = np.asarray([w for e in widths for w in e])
    ls = np.asarray([ln for e, ln in zip(widths, lengths, strict=True) for _ in e])
    if np.abs(ws - ws[0]).max() <= 0.05:
        return float(ws[0])
    order = np.argsort(ws, kind="stable")
    cum = np.cumsum(ls[order])
    return float(ws[order][int(np.searchsorted(cum, cum[-1] / 2))])


def reference_lanes(layout: LaneLayout) -> list[tuple[int, float]]:
    """Per route edge, (the SUMO index of its car lane nearest the middle of the route's lanes, the lateral
    offset [m] from that lane's centre to the middle, positive to the left): the pieces of the reference
    line. Where lane widths differ the middle is that of the edge's real car lanes, lanes the edge lacks
    counted at the route's width."""
    c = (layout.n_lanes - 1) / 2
    out = []
    for i, (first, count) in enumerate(zip(layout.first, layout.count, strict=True)):
        k = min(range(count), key=lambda j: (abs(first + j - c), j))
        if not layout.widths:
            delta = (c - (first + k)) * layout.width
        else:
            wi, w = layout.widths[i], layout.width
            right = -wi[k] / 2 - sum(wi[:k]) - first * w  # the route's right edge from this lane's centre
            left = wi[k] / 2 + sum(wi[k + 1 :]) + (layout.n_lanes - first - count) * w
            delta = (right + left) / 2
        out.append((layout.edge_lane(i, first + k), delta))
    return out


@dataclass(frozen=True)
class ReferenceShape:
    """A route's reference line before resampling: its points and where each route edge lies along it."""

    points: np.ndarray  # [P, 2]; a loop's first point is not repeated at the end
    #: [E, 2] arc length [m] along ``points`` where each route edge's piece starts and ends (a point of
    #: an edge is near that stretch of the line: the hint of its projection, see ``Road.to_frenet``)
    edge_arcs: np.ndarray
    #: [K] arc length [m] where each piece of the line starts (an edge's lane, a junction lane), in order
    piece_arcs: np.ndarray
    #: per piece, the junctions it touches (an edge: its two end nodes; a junction lane: its node)
    piece_nodes: tuple[frozenset[str], ...]


def reference_shape(net: object, edges: tuple[str, ...], layout: LaneLayout, closed: bool) -> ReferenceShape:
    """The middle of the route's lanes along it: each edge's lane nearest the middle (and the junction
    lane from it into the same route lane of the next edge), moved sideways onto the middle where it is
    not there. Where that lane does not go on into the next edge (a turn at a junction made from other
    lanes only), the junction lane of the nearest lane that does, moved over by the lanes between: the
    reference follows the turn. The line may come back near itself (:func:`self_crossing`)."""
    pieces = reference_lanes(layout)
    n = len(edges)
    pts: list[np.ndarray] = []
    kinds: list[tuple[int, frozenset[str]]] = []  # per piece: (route edge index or -1, its junctions)
    for i, eid in enumerate(edges):
        k, delta = pieces[i]
        lane = net.getEdge(eid).getLane(k)  # type: ignore[attr-defined]
        pts.append(_offset(np.asarray(lane.getShape(), dtype=np.float64), delta))
        edge = net.getEdge(eid)  # type: ignore[attr-defined]
        kinds.append((i, frozenset((edge.getFromNode().getID(), edge.getToNode().getID()))))
        if i < n - 1 or closed:
            j = (i + 1) % n
            want = layout.edge_lane(j, layout.route_lane(i, k))
            cons = [c for c in lane.getOutgoing() if c.getTo().getID() == edges[j]]
            via = [c for c in cons if c.getToLane().getIndex() == want] or cons
            via_id, shift = (via[0].getViaLaneID() if via else ""), delta
            if not cons:
                via_id, shift = _turn_from_other_lane(net, edges, layout, i, k, delta)
            if via_id:
                via_lane = net.getLane(via_id)  # type: ignore[attr-defined]
                pts.append(_offset(np.asarray(via_lane.getShape(), dtype=np.float64), shift))
                kinds.append((-1, frozenset((edge.getToNode().getID(),))))
    allpts = np.concatenate(pts)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(allpts, axis=0), axis=1))])
    first = np.cumsum([0] + [len(p) for p in pts])  # index of each piece's first and (next) last point
    span = [(float(arc[first[j]]), float(arc[first[j + 1] - 1])) for j in range(len(pts))]
    edge_arcs = np.array([span[j] for j, (i, _) in enumerate(kinds) if i >= 0])
    starts = np.array([a for a, _ in span])
    return ReferenceShape(_clean_polyline(allpts, closed), edge_arcs, starts, tuple(n for _, n in kinds))


def _offset(pts: np.ndarray, delta: float) -> np.ndarray:
    return pts if delta == 0.0 else offset_polyline(pts, delta)


def _turn_from_other_lane(
    net: object, edges: tuple[str, ...], layout: LaneLayout, i: int, k: int, delta: float
) -> tuple[str, float]:
    """(junction lane id, its lateral offset [m]) of the way into route edge i + 1 from the car lane of
    edge i nearest SUMO lane ``k`` (which has none), moved by the lanes between onto the middle."""
    j = (i + 1) % len(edges)
    here = layout.route_lane(i, k)
    ways = [
        (abs(g - here), g, c.getViaLaneID())
        for ln in net.getEdge(edges[i]).getLanes()  # type: ignore[attr-defined]
        if (g := layout.route_lane(i, ln.getIndex())) >= 0
        for c in ln.getOutgoing()
        if c.getTo().getID() == edges[j] and c.getViaLaneID()
    ]
    if not ways:
        return "", delta
    _, g, via_id = min(ways)
    return via_id, delta + (here - g) * layout.width


def edge_table(
    ref_s: np.ndarray, bounds: list[tuple[str, float, float]], values: list[float], closed: bool
) -> np.ndarray:
    """A value per route edge spread over the reference vertices [M]: each edge's over its stretch,
    inside a junction the lower of the two edges' (the filling of :func:`lane_table`)."""
    order = sorted(set(values))
    rank = tuple(order.index(v) for v in values)
    ranks = LaneLayout(rank, (1,) * len(values), len(order), 0.0)  # a value's rank as a 'lane'
    lo, _ = lane_table(ref_s, bounds, ranks, closed)
    return np.asarray(order, dtype=np.float64)[lo]


def lane_table(
    ref_s: np.ndarray, bounds: list[tuple[str, float, float]], layout: LaneLayout, closed: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(lowest, highest) route lane at each reference vertex [M] (int64): each edge's lanes over its
    stretch ``bounds`` (edge id, s at its start, s at its end); inside a junction the lanes of the edges
    on both sides; beyond an open route's ends, those of its first and last edge."""
    m = len(ref_s)
    lap = float(ref_s[-1]) + 1.0  # any s past the last vertex belongs to nothing
    lo = np.full(m, -1, dtype=np.int64)
    hi = np.full(m, -1, dtype=np.int64)
    for i, (_, a, b) in enumerate(bounds):
        span = (b - a) % lap if closed else b - a
        sel = ((ref_s - a) % lap <= span) if closed else ((ref_s >= a) & (ref_s <= b))
        lo[sel] = layout.first[i]
        hi[sel] = layout.first[i] + layout.count[i] - 1
    if (lo >= 0).all() or not (lo >= 0).any():
        return np.maximum(lo, 0), np.where(hi < 0, layout.n_lanes - 1, hi)
    idx = np.arange(m)
    known = lo >= 0
    if closed:  # fill around the loop: three copies, take the middle
        k3 = np.tile(known, 3)
        i3 = np.arange(3 * m)
        prev = np.maximum.accumulate(np.where(k3, i3, -1))[m : 2 * m] % m
        nxt = np.minimum.accumulate(np.where(k3, i3, 3 * m)[::-1])[::-1][m : 2 * m] % m
    else:
        prev = np.maximum.accumulate(np.where(known, idx, -1))
        nxt = np.minimum.accumulate(np.where(known, idx, m)[::-1])[::-1]
        prev = np.where(prev < 0, nxt, prev)
        nxt = np.where(nxt >= m, prev, nxt)
    lo = np.where(known, lo, np.minimum(lo[prev], lo[nxt]))
    hi = np.where(known, hi, np.maximum(hi[prev], hi[nxt]))
    return lo, hi


def offset_polyline(pts: np.ndarray, delta: float) -> np.ndarray:
    """The polyline moved ``delta`` metres to its left (vertex normals: the mean of the adjacent
    segments' normals)."""
    if len(pts) < 2:
        return pts
    seg = np.diff(pts, axis=0)
    seg = seg / np.maximum(np.linalg.norm(seg, axis=1), 1e-12)[:, None]
    nrm = np.stack([-seg[:, 1], seg[:, 0]], axis=1)
    vn = np.vstack([nrm[:1], nrm[:-1] + nrm[1:], nrm[-1:]])
    vn = vn / np.maximum(np.linalg.norm(vn, axis=1), 1e-12)[:, None]
    return pts + delta * vn


def lane_shape(net: object, edges: tuple[str, ...], layout: LaneLayout, g: int, closed: bool) -> np.ndarray:
    """Centreline of route lane ``g`` along a route whose every edge has it, the junction (internal) lanes
    from it into the same route lane of the next edge included where that connection exists: [P, 2]; for
    a loop the first point is not repeated at the end."""
    pts: list[tuple[float, float]] = []
    n = len(edges)
    for i, eid in enumerate(edges):
        lane = net.getEdge(eid).getLane(layout.edge_lane(i, g))  # type: ignore[attr-defined]
        pts.extend(lane.getShape())
        if i == n - 1 and not closed:
            break
        j = (i + 1) % n
        nxt, k = edges[j], layout.edge_lane(j, g)
        via = [c for c in lane.getOutgoing() if c.getTo().getID() == nxt and c.getToLane().getIndex() == k]
        # a lane that does not go on into route lane g (it turns off, or only other lanes continue) is joined
        # to the next edge's lane by a straight segment across the junction
        via_id = via[0].getViaLaneID() if via else ""
        if via_id:
            pts.extend(net.getLane(via_id).getShape())  # type: ignore[attr-defined]
    return _clean_polyline(np.asarray(pts, dtype=np.float64), closed)


def exit_shapes(net: object, edges: tuple[str, ...], closed: bool) -> list[tuple[str, np.ndarray, int]]:
    """Every road for cars the route's rightmost car lane can turn into other than the route's next edge:
    (edge id, the junction lane into it and its rightmost car lane [P, 2], the index of the route edge
    it leaves from). Leaving the route there is the exit failure."""
    out = []
    n = len(edges)
    on_route = set(edges)
    for i, eid in enumerate(edges):
        if i == n - 1 and not closed:
            break
        nxt = edges[(i + 1) % n]
        edge = net.getEdge(eid)  # type: ignore[attr-defined]
        for c in edge.getLane(car_lanes(edge)[0]).getOutgoing():
            to = c.getTo()
            to_cars = car_lanes(to)
            if to.getID() == nxt or to.getID() in on_route or not to_cars:
                continue
            pts: list[tuple[float, float]] = []
            via = c.getViaLaneID()
            if via:
                pts.extend(net.getLane(via).getShape())  # type: ignore[attr-defined]
            pts.extend(to.getLane(to_cars[0]).getShape())
            out.append((to.getID(), np.asarray(pts, dtype=np.float64), i))
    return out


def mission_points(
    net: object, edges: tuple[str, ...], closed: bool, layout: LaneLayout
) -> list[tuple[float, float, int, tuple[int, ...], int]]:
    """Where the route goes on from some of its lanes only: (x, y) of the end of that edge's lane nearest
    the middle, the continuing lane nearest the middle, every continuing lane (the mission lanes:
    passing in any of them keeps the mission) and the edge's index, one per such edge. For an open route
    also its end, where any lane will do (lane -1, no lanes listed)."""
    out: list[tuple[float, float, int, tuple[int, ...], int]] = []
    n = len(edges)
    c = (layout.n_lanes - 1) / 2
    pieces = reference_lanes(layout)
    for i, eid in enumerate(edges):
        edge = net.getEdge(eid)  # type: ignore[attr-defined]
        x, y = edge.getLane(pieces[i][0]).getShape()[-1]
        if i == n - 1 and not closed:
            out.append((float(x), float(y), -1, (), i))
            break
        nxt = edges[(i + 1) % n]
        going = sorted(
            {
                layout.route_lane(i, lane.getIndex())
                for lane in edge.getLanes()
                for con in lane.getOutgoing()
                if con.getTo().getID() == nxt and con.getToLane().allows(CAR_CLASS)
            }
            - {-1}
        )
        if len(going) < layout.count[i]:
            req = min(going, key=lambda g: (abs(g - c), g))
            out.append((float(x), float(y), int(req), tuple(int(g) for g in going), i))
    return out


def _clean_polyline(arr: np.ndarray, closed: bool) -> np.ndarray:
    """The polyline without repeated points (where a lane meets its junction lane); a loop's last point,
    when it is its first, dropped."""
    keep = np.ones(len(arr), bool)
    keep[1:] = np.linalg.norm(np.diff(arr, axis=0), axis=1) > 1e-6
    arr = arr[keep]
    if closed and np.linalg.norm(arr[0] - arr[-1]) < 1e-6:
        arr = arr[:-1]
    return arr
