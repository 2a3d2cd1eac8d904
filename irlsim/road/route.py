"""What a route on a SUMO network says: its edges, whether it is a loop, its lanes, the lane shapes along
it (junction lanes included), its all-way stops, the exits that leave it and the lanes it goes on from.

Pure functions over a ``sumolib`` network, for :class:`irlsim.road.Road`. Errors are one line naming the
edge at fault and the fix (``IrlsimError``), raised before any simulation starts.
"""

from __future__ import annotations

import numpy as np

from irlsim.errors import IrlsimError

#: SUMO junction types at which every vehicle comes to a full stop
STOP_TYPES = ("allway_stop",)


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


def route_lanes(net: object, edges: tuple[str, ...]) -> tuple[int, float]:
    """(number of lanes, lane width [m]) along the route, which must be the same on every edge and every
    lane a passenger car may use."""
    first = net.getEdge(edges[0])  # type: ignore[attr-defined]
    n, width = first.getLaneNumber(), float(first.getLane(0).getWidth())
    for eid in edges:
        edge = net.getEdge(eid)  # type: ignore[attr-defined]
        if edge.getLaneNumber() != n:
            raise IrlsimError(
                f"route: edge '{eid}' has {edge.getLaneNumber()} lanes where the route began with {n}: "
                "routes whose number of lanes changes are not supported yet; choose a route with the same "
                "number of lanes on every edge"
            )
        for lane in edge.getLanes():
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
    return n, width


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
    arr = np.asarray(pts, dtype=np.float64)
    keep = np.ones(len(arr), bool)
    keep[1:] = np.linalg.norm(np.diff(arr, axis=0), axis=1) > 1e-6
    arr = arr[keep]
    if closed and np.linalg.norm(arr[0] - arr[-1]) < 1e-6:
        arr = arr[:-1]
    return arr


def stop_points(net: object, edges: tuple[str, ...], ref_lane: int) -> list[tuple[str, float, float]]:
    """(node id, x, y) of each all-way stop the route enters: the end of its reference lane there."""
    out = []
    on_route = set(edges)
    for node in net.getNodes():  # type: ignore[attr-defined]
        if node.getType() not in STOP_TYPES:
            continue
        inc = [e for e in node.getIncoming() if e.getID() in on_route]
        if not inc:
            continue
        x, y = inc[0].getLane(ref_lane).getShape()[-1]
        out.append((node.getID(), float(x), float(y)))
    return out


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
    net: object, edges: tuple[str, ...], closed: bool, n_lanes: int
) -> list[tuple[float, float, int]]:
    """Where the route goes on from some of its lanes only: (x, y) of the end of that edge's middle lane
    and the lane required there (the continuing lane nearest the middle), one per such edge. For an open
    route also its end, where any lane will do (lane -1)."""
    out = []
    n = len(edges)
    mid = (n_lanes - 1) // 2
    for i, eid in enumerate(edges):
        edge = net.getEdge(eid)  # type: ignore[attr-defined]
        if i == n - 1 and not closed:
            x, y = edge.getLane(mid).getShape()[-1]
            out.append((float(x), float(y), -1))
            break
        nxt = edges[(i + 1) % n]
        going = sorted(
            {
                lane.getIndex()
                for lane in edge.getLanes()
                for c in lane.getOutgoing()
                if c.getTo().getID() == nxt
            }
        )
        if len(going) < n_lanes:
            x, y = edge.getLane(mid).getShape()[-1]
            req = min(going, key=lambda k: (abs(k - mid), k))
            out.append((float(x), float(y), int(req)))
    return out
