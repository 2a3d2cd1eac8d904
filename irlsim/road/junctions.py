"""The junctions a route crosses and what their SUMO link states ask of it: stop signs and all-way stops,
traffic lights, and minor links (yield and priority junctions).

Pure functions over a ``sumolib`` network, for :class:`irlsim.road.Road`, the traffic and the ego's
start.
"""

from __future__ import annotations

from typing import Any

#: SUMO link states at which a vehicle comes to a full stop: a stop sign, an all-way stop
STOP_STATES = ("s", "w")


def junction_controls(
    net: object, edges: tuple[str, ...], closed: bool, lanes: dict[str, int]
) -> tuple[list[tuple[str, float, float, int]], list[tuple[Any, ...]]]:
    """The junctions the route crosses that make it stop: (stops, signals). A stop is a stop sign or an
    all-way stop on the route's way through (SUMO link state 's' or 'w'): (node id, x, y, i) at the end
    of the middle lane of route edge i, the incoming one. A signal is a traffic light on it: (node id, x,
    y, traffic light id, link index of the route's connection, i, ((lane index, link index) of every lane
    of edge i that leads into the route's next edge through that light, ...)): lanes of one approach may
    show different signals (a green arrow for one, red for the next)."""
    stops, signals = [], []
    for node, x, y, cons, i in _ways_through(net, edges, closed, lanes):
        if cons and cons[0].getTLSID():
            tls, nxt = cons[0].getTLSID(), edges[(i + 1) % len(edges)]
            by_lane = {}
            for ln in net.getEdge(edges[i]).getLanes():  # type: ignore[attr-defined]
                into = [c for c in ln.getOutgoing() if c.getTo().getID() == nxt and c.getTLSID() == tls]
                if into:
                    by_lane[int(ln.getIndex())] = int(into[0].getTLLinkIndex())
            lane_links = tuple(sorted(by_lane.items()))
            signals.append((node, x, y, tls, int(cons[0].getTLLinkIndex()), i, lane_links))
        elif cons and cons[0].getState() in STOP_STATES:
            stops.append((node, x, y, i))
    return stops, signals


def _ways_through(
    net: object, edges: tuple[str, ...], closed: bool, lanes: dict[str, int]
) -> list[tuple[str, float, float, list[Any], int]]:
    """Per junction the route crosses: (node id, x, y of the end of the incoming edge's middle lane, the
    connections of the route's way through: the middle lane's into the next route edge, else any lane's,
    the index i of the incoming route edge)."""
    out = []
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
        out.append((edge.getToNode().getID(), float(x), float(y), cons, i))
    return out


def yield_points(
    net: object, edges: tuple[str, ...], closed: bool, lanes: dict[str, int]
) -> list[tuple[str, float, float, int, tuple[str, ...]]]:
    """The junctions where the route's way through is a minor link without a traffic light (SUMO link
    state 'm', '=' or 'Z': a minor road, equal rank, a zipper merge): (node id, x, y, i, internal lanes)
    at the end of the middle lane of route edge i, the incoming one, where the ego waits for the foes with
    priority (like a stop line); the internal lanes are those of the route's way through
    (:func:`way_lanes`)."""
    return [
        (node, x, y, i, way_lanes(net, edges[i], edges[(i + 1) % len(edges)]))
        for node, x, y, cons, i in _ways_through(net, edges, closed, lanes)
        if cons and not cons[0].getTLSID() and cons[0].getState() in YIELD_STATES
    ]


def way_lanes(net: object, edge: str, nxt: str) -> tuple[str, ...]:
    """The internal lanes of every connection from a lane of ``edge`` into ``nxt``, each connection's
    chain through its junction (the lane it starts on, then an internal junction's lane after it), sorted;
    () on a network built without internal lanes."""
    out: set[str] = set()
    for ln in net.getEdge(edge).getLanes():  # type: ignore[attr-defined]
        for con in ln.getOutgoing():
            via = con.getViaLaneID() if con.getTo().getID() == nxt else ""
            while via and via not in out:  # an internal lane leads on to the next one of its chain
                out.add(via)
                onward = [c.getViaLaneID() for c in net.getLane(via).getOutgoing()]  # type: ignore[attr-defined]
                via = onward[0] if onward else ""
    return tuple(sorted(out))


#: SUMO link states at which a vehicle yields without a sign (a minor road, equal rank, a zipper merge)
YIELD_STATES = ("m", "=", "Z")


def yield_ends(net: object, edges: tuple[str, ...], closed: bool) -> tuple[int, ...]:
    """Indices of the route edges whose way into the route's next edge yields (a merge, a minor road:
    SUMO link state 'm', '=' or 'Z'); SUMO refuses a departure too close before such a junction to brake."""
    n = len(edges)
    out = []
    for i, eid in enumerate(edges):
        if i == n - 1 and not closed:
            break
        nxt = edges[(i + 1) % n]
        states = {
            c.getState()
            for ln in net.getEdge(eid).getLanes()  # type: ignore[attr-defined]
            for c in ln.getOutgoing()
            if c.getTo().getID() == nxt
        }
        if states & set(YIELD_STATES):
            out.append(i)
    return tuple(out)
