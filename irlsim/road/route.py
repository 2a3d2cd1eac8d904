"""What a route on a SUMO network says: its edges, whether it is a loop, its lanes, the lane shapes along
it (junction lanes included), its all-way stops, the exits that leave it and the lanes it goes on from.

Pure functions over a ``sumolib`` network, for :class:`irlsim.road.Road`. Errors are one line naming the
edge at fault and the fix (``IrlsimError``), raised before any simulation starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from irlsim.errors import IrlsimError

#: SUMO link states at which a vehicle comes to a full stop: a stop sign, an all-way stop
STOP_STATES = ("s", "w")


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


@dataclass(frozen=True)
class LaneLayout:
    """The lanes along a route on one numbering: lane ``g`` (0 = the rightmost lane anywhere on the route)
    is SUMO lane ``g - first[i]`` of route edge ``i``, where it exists. Lanes that go straight on across
    a junction keep their number; a lane added on the right (an on-ramp) or dropped there shifts
    ``first`` by one."""

    first: tuple[int, ...]  # per route edge: the route lane of its SUMO lane 0
    count: tuple[int, ...]  # per route edge: its number of lanes
    n_lanes: int  # lanes on the route's numbering
    width: float  # [m] every lane's width

    @property
    def varies(self) -> bool:
        """True when some edge lacks some of the route's lanes (lanes added, dropped, merging)."""
        return any(c != self.n_lanes for c in self.count)

    def edge_lane(self, i: int, lane: int) -> int:
        """SUMO lane index on route edge ``i`` of route lane ``lane``; -1 where that edge lacks it."""
        k = lane - self.first[i]
        return k if 0 <= k < self.count[i] else -1


def lane_layout(net: object, edges: tuple[str, ...], closed: bool) -> LaneLayout:
    """The route's lane numbering (:class:`LaneLayout`) from SUMO's lane connections: across each
    junction the most common shift between a connection's from- and to-lane index (the lanes that go
    straight on); checks one lane width and lanes for passenger cars."""
    n = len(edges)
    rel = [0]
    for i in range(n - 1 if not closed else n):
        a, b = net.getEdge(edges[i]), edges[(i + 1) % n]  # type: ignore[attr-defined]
        shifts = [
            lane.getIndex() - c.getToLane().getIndex()
            for lane in a.getLanes()
            for c in lane.getOutgoing()
            if c.getTo().getID() == b
        ]
        if not shifts:
            raise IrlsimError(f"route: no lane of '{edges[i]}' leads into '{b}': fix [route] edges")
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
    count = tuple(net.getEdge(e).getLaneNumber() for e in edges)  # type: ignore[attr-defined]
    width = float(net.getEdge(edges[0]).getLane(0).getWidth())  # type: ignore[attr-defined]
    for eid in edges:
        for lane in net.getEdge(eid).getLanes():  # type: ignore[attr-defined]
            if abs(float(lane.getWidth()) - width) > 0.05:
                raise IrlsimError(
                    f"route: lane '{lane.getID()}' is {lane.getWidth():.2f} m wide where the route's lanes "
                    f"are {width:.2f} m: choose a route whose lanes have one width"
                )
            if not lane.allows("passenger"):
                raise IrlsimError(
                    f"route: lane '{lane.getID()}' does not admit passenger cars: choose a route of roads "
                    "for cars"
                )
    n_lanes = max(f + c for f, c in zip(first, count, strict=True))
    return LaneLayout(first, count, n_lanes, width)


def reference_lanes(layout: LaneLayout) -> list[tuple[int, float]]:
    """Per route edge, (its SUMO lane nearest the middle of the route's lanes, the lateral offset [m] from
    that lane's centre to the middle, positive to the left): the pieces of the reference line."""
    c = (layout.n_lanes - 1) / 2
    out = []
    for first, count in zip(layout.first, layout.count, strict=True):
        k = min(range(count), key=lambda j: (abs(first + j - c), j))
        out.append((k, (c - (first + k)) * layout.width))
    return out


def reference_shape(net: object, edges: tuple[str, ...], layout: LaneLayout, closed: bool) -> np.ndarray:
    """The middle of the route's lanes along it: each edge's lane nearest the middle (and the junction
    lane from it into the same route lane of the next edge), moved sideways onto the middle where it is
    not there: [P, 2]; for a loop the first point is not repeated at the end."""
    pieces = reference_lanes(layout)
    n = len(edges)
    pts: list[np.ndarray] = []
    for i, eid in enumerate(edges):
        k, delta = pieces[i]
        lane = net.getEdge(eid).getLane(k)  # type: ignore[attr-defined]
        part = [np.asarray(lane.getShape(), dtype=np.float64)]
        if i < n - 1 or closed:
            j = (i + 1) % n
            want = layout.edge_lane(j, layout.first[i] + k)
            cons = [c for c in lane.getOutgoing() if c.getTo().getID() == edges[j]]
            via = [c for c in cons if c.getToLane().getIndex() == want] or cons
            via_id = via[0].getViaLaneID() if via else ""
            if via_id:
                part.append(np.asarray(net.getLane(via_id).getShape(), dtype=np.float64))  # type: ignore[attr-defined]
        for p in part:
            pts.append(p if delta == 0.0 else offset_polyline(p, delta))
    return _clean_polyline(np.concatenate(pts), closed)


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


def lane_shape(net: object, edges: tuple[str, ...], k: int, closed: bool) -> np.ndarray:
    """Centreline of lane ``k`` along the route, the junction (internal) lanes from lane k to lane k of the
    next edge included where that connection exists: [P, 2]; for a loop the first point is not repeated
    at the end."""
    pts: list[tuple[float, float]] = []
    n = len(edges)
    for i, eid in enumerate(edges):
        lane = net.getEdge(eid).getLane(k)  # type: ignore[attr-defined]
        pts.extend(lane.getShape())
        if i == n - 1 and not closed:
            break
        nxt = edges[(i + 1) % n]
        via = [c for c in lane.getOutgoing() if c.getTo().getID() == nxt and c.getToLane().getIndex() == k]
        # a lane that does not go on into lane k (it turns off, or only other lanes continue) is joined to
        # the next edge's lane k by a straight segment across the junction
        via_id = via[0].getViaLaneID() if via else ""
        if via_id:
            pts.extend(net.getLane(via_id).getShape())  # type: ignore[attr-defined]
    return _clean_polyline(np.asarray(pts, dtype=np.float64), closed)


def junction_controls(
    net: object, edges: tuple[str, ...], closed: bool, lanes: dict[str, int]
) -> tuple[list[tuple[str, float, float]], list[tuple[str, float, float, str, int]]]:
    """The junctions the route crosses that make it stop: (stops, signals). A stop is a stop sign or an
    all-way stop on the route's way through (SUMO link state 's' or 'w'): (node id, x, y) at the end of
    the incoming edge's middle lane. A signal is a traffic light on it: (node id, x, y, traffic light id,
    link index of the route's connection)."""
    stops, signals = [], []
    n = len(edges)
    for i, eid in enumerate(edges):
        if i == n - 1 and not closed:
            break
        edge = net.getEdge(eid)  # type: ignore[attr-defined]
        lane = edge.getLane(lanes[eid])
        cons = [c for c in lane.getOutgoing() if c.getTo().getID() == edges[(i + 1) % n]]
        if not cons:  # the middle lane turns elsewhere: any lane's connection into the route
            cons = [
                c
                for ln in edge.getLanes()
                for c in ln.getOutgoing()
                if c.getTo().getID() == edges[(i + 1) % n]
            ]
        x, y = lane.getShape()[-1]
        node = edge.getToNode().getID()
        if cons and cons[0].getTLSID():
            signals.append((node, float(x), float(y), cons[0].getTLSID(), int(cons[0].getTLLinkIndex())))
        elif cons and cons[0].getState() in STOP_STATES:
            stops.append((node, float(x), float(y)))
    return stops, signals


def exit_shapes(net: object, edges: tuple[str, ...], closed: bool) -> list[tuple[str, np.ndarray]]:
    """Every edge the route's rightmost lane can turn into other than the route's next edge: (edge id, the
    junction lane into it and its rightmost lane [P, 2]). Leaving the route there is the exit failure."""
    out = []
    n = len(edges)
    on_route = set(edges)
    for i, eid in enumerate(edges):
        if i == n - 1 and not closed:
            break
        nxt = edges[(i + 1) % n]
        for c in net.getEdge(eid).getLane(0).getOutgoing():  # type: ignore[attr-defined]
            to = c.getTo()
            if to.getID() == nxt or to.getID() in on_route:
                continue
            pts: list[tuple[float, float]] = []
            via = c.getViaLaneID()
            if via:
                pts.extend(net.getLane(via).getShape())  # type: ignore[attr-defined]
            pts.extend(to.getLane(0).getShape())
            out.append((to.getID(), np.asarray(pts, dtype=np.float64)))
    return out


def mission_points(
    net: object, edges: tuple[str, ...], closed: bool, layout: LaneLayout
) -> list[tuple[float, float, int, tuple[int, ...]]]:
    """Where the route goes on from some of its lanes only: (x, y) of the end of that edge's lane nearest
    the middle, the continuing lane nearest the middle, and every continuing lane (the mission lanes:
    passing in any of them keeps the mission), one per such edge. For an open route also its end, where
    any lane will do (lane -1, no lanes listed)."""
    out: list[tuple[float, float, int, tuple[int, ...]]] = []
    n = len(edges)
    c = (layout.n_lanes - 1) / 2
    pieces = reference_lanes(layout)
    for i, eid in enumerate(edges):
        edge = net.getEdge(eid)  # type: ignore[attr-defined]
        x, y = edge.getLane(pieces[i][0]).getShape()[-1]
        if i == n - 1 and not closed:
            out.append((float(x), float(y), -1, ()))
            break
        nxt = edges[(i + 1) % n]
        going = sorted(
            {
                layout.first[i] + lane.getIndex()
                for lane in edge.getLanes()
                for con in lane.getOutgoing()
                if con.getTo().getID() == nxt
            }
        )
        if len(going) < layout.count[i]:
            req = min(going, key=lambda g: (abs(g - c), g))
            out.append((float(x), float(y), int(req), tuple(int(g) for g in going)))
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
