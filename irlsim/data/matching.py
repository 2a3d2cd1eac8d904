"""Map matching: the route of a recorded vehicle from its positions alone (a recording without lanes).

Every point is projected onto the nearest lane of the network whose direction there lies within
``MAX_ANGLE`` of the point's heading: the lanes sampled every metre or closer and bucketed in a grid of
cells, all points of a recording at once (no loop over rows). A point nearest a junction's internal lane,
or farther than ``bound`` from every lane in its direction, gives no edge. Per vehicle, the edges of its
points in the order driven (consecutive repeats merged; a brief visit A X A, less than ``FOLD_M``
driven on X, folded into A) become a connected route: each edge followed by the next directly, or
by the shortest path between them when that path is no longer than the distance driven from one to the
other (the recorded speed over time, plus ``SLACK_M``); otherwise the vehicle's positions match no
connected route, said in a phrase.

A recording with lanes (SUMO's FCD) gives each point its recorded lane's edge instead, and the same
joining makes its route connected: SUMO records one lane a step, so a vehicle crosses an edge shorter than
a step's travel (OpenStreetMap networks have edges of a few decimetres) without a record on it. Routes are
a passenger car's (the ego's class, and the class of the vehicles SUMO drives in a reactive replay):
gaps are filled over edges a car may use (not over a walking area), and a vehicle most of whose points
lie on lanes a car may not use (a bicycle on its lane, a tram) has no route, said in a phrase.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from irlsim.road.angles import atan2
from irlsim.road.route import CAR_CLASS

#: [rad] a lane matches a point when its direction there is within this of the point's heading
MAX_ANGLE = math.radians(60.0)
#: [m] a shortest path filling a gap between two matched edges may be this much longer than the distance
#: driven from the last point on one to the first point on the other
SLACK_M = 20.0
#: [m] a visit to another edge between two stretches of one edge is folded into it when the vehicle
#: drove less than this there (a point nearer a neighbouring edge, not a route)
FOLD_M = 10.0
#: points matched per block (bounds the candidates' memory)
BLOCK = 4096
#: a vehicle with more than this share of its points on lanes a car may not use is no car
NOT_CAR_SHARE = 0.5


@dataclass(frozen=True)
class LaneSamples:
    """Points every metre or closer along every lane of a network (internal lanes included): sample ``i``
    lies on lane ``lane[i]`` (an index into ``ids``), whose direction there is ``angle[i]`` [rad, ENU]."""

    xy: np.ndarray  # [P, 2] [m]
    angle: np.ndarray  # [P] [rad]
    lane: np.ndarray  # [P] int
    ids: tuple[str, ...]  # [L] SUMO lane ids
    edge: tuple[str, ...]  # [L] the lane's edge; '' for a junction's internal lane
    car: tuple[bool, ...] = ()  # [L] a passenger car may use the lane (a junction's: True)


def lane_samples(net: Any) -> LaneSamples:
    """The samples of every lane of ``net`` (a sumolib network read with its internal edges)."""
    xy: list[np.ndarray] = []
    angle: list[np.ndarray] = []
    lane: list[np.ndarray] = []
    ids: list[str] = []
    edge: list[str] = []
    car: list[bool] = []
    for e in net.getEdges(withInternal=True):
        internal = e.getFunction() == "internal" or e.getID().startswith(":")
        for ln in e.getLanes():
            sh = np.asarray(ln.getShape(), dtype=np.float64)[:, :2]
            seg = np.diff(sh, axis=0)
            n = np.maximum(np.ceil(np.hypot(seg[:, 0], seg[:, 1])).astype(int), 1)
            f = np.concatenate([np.arange(k) / k for k in n])  # fractions along each segment
            heading = atan2(seg[:, 1], seg[:, 0])
            xy += [np.repeat(sh[:-1], n, axis=0) + np.repeat(seg, n, axis=0) * f[:, None], sh[-1:]]
            angle += [np.repeat(heading, n), heading[-1:]]
            lane.append(np.full(int(n.sum()) + 1, len(ids)))
            ids.append(ln.getID())
            edge.append("" if internal else e.getID())
            car.append(internal or bool(ln.allows(CAR_CLASS)))
    return LaneSamples(
        np.concatenate(xy), np.concatenate(angle), np.concatenate(lane), tuple(ids), tuple(edge), tuple(car)
    )


def nearest_lanes(
    samples: LaneSamples, x: np.ndarray, y: np.ndarray, heading: np.ndarray, bound: float
) -> np.ndarray:
    """[N] for each point, the index of the nearest lane within ``bound`` whose direction there is within
    ``MAX_ANGLE`` of its heading (-1: none); the nearest sample decides."""
    cell = bound
    lo = samples.xy.min(axis=0) - cell
    cs = np.floor((samples.xy - lo) / cell).astype(np.int64)
    ny = int(cs[:, 1].max()) + 3
    key = cs[:, 0] * ny + cs[:, 1]
    order = np.argsort(key, kind="stable")
    skey = key[order]
    off = np.array([dx * ny + dy for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    out = np.full(len(x), -1, dtype=np.int64)
    cos_max = math.cos(MAX_ANGLE)
    for a in range(0, len(x), BLOCK):  # over blocks of points, not rows
        q = np.stack([x[a : a + BLOCK], y[a : a + BLOCK]], axis=1)
        cq = np.floor((q - lo) / cell).astype(np.int64)
        inside = (cq[:, 0] >= 1) & (cq[:, 1] >= 1) & (cq[:, 1] < ny - 1)
        keys = (cq[:, 0] * ny + cq[:, 1])[:, None] + off[None, :]  # [Q, 9] the cells around each point
        first = np.searchsorted(skey, keys, side="left")
        count = np.where(inside[:, None], np.searchsorted(skey, keys, side="right") - first, 0).ravel()
        qid = np.repeat(np.arange(len(q)), 9)
        qrep = np.repeat(qid, count)  # sorted: each point's candidates together
        within = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
        sidx = order[np.repeat(first.ravel(), count) + within]
        d2 = ((samples.xy[sidx] - q[qrep]) ** 2).sum(axis=1)
        aligned = np.cos(samples.angle[sidx] - heading[a : a + BLOCK][qrep]) >= cos_max
        d2 = np.where(aligned & (d2 <= bound * bound), d2, np.inf)
        best = np.lexsort((d2, qrep))  # per point, its candidates nearest first
        head = best[np.r_[True, qrep[best][1:] != qrep[best][:-1]]] if len(best) else best
        hit = np.isfinite(d2[head])
        out[a + qrep[head][hit]] = samples.lane[sidx[head][hit]]
    return out


def _runs(edges: list[str], dist: np.ndarray) -> tuple[list[str], list[float], list[float]]:
    """Consecutive repeats merged, A X A folded into A: the edges with the distance driven at their first
    and last point."""
    names: list[str] = []
    first: list[float] = []
    last: list[float] = []
    for e, s in zip(edges, dist.tolist(), strict=True):  # over one vehicle's matched points
        if names and names[-1] == e:
            last[-1] = s
        elif len(names) >= 2 and names[-2] == e and last[-1] - first[-1] < FOLD_M:  # a brief visit: folded
            del names[-1], first[-1], last[-1]
            last[-1] = s
        else:
            names.append(e)
            first.append(s)
            last.append(s)
    return names, first, last


def connect(net: Any, edges: list[str], dist: np.ndarray) -> tuple[str, ...] | str:
    """The connected route of one vehicle whose matched points lie on ``edges`` (in the order driven,
    '' for none) after ``dist`` [m] driven; or, where there is none, why (a phrase)."""
    keep = [i for i, e in enumerate(edges) if e]
    if not keep:
        return "none of its positions lies on an edge in its direction"
    names, first, last = _runs([edges[i] for i in keep], dist[keep])
    route = [names[0]]
    for k in range(1, len(names)):  # over the vehicle's edges, not its points
        prev, nxt = net.getEdge(route[-1]), net.getEdge(names[k])
        if nxt in prev.getAllowedOutgoing(CAR_CLASS):
            route.append(names[k])
            continue
        path, _ = net.getShortestPath(prev, nxt, vClass=CAR_CLASS)
        driven = first[k] - last[k - 1]
        if not path:
            return f"edge {route[-1]} does not lead to edge {names[k]}"
        between = sum(e.getLength() for e in path[1:-1])
        if between > driven + SLACK_M:
            return (
                f"edge {route[-1]} leads to edge {names[k]} only over {between:.0f} m, the vehicle drove "
                f"{driven:.0f} m between them"
            )
        route += [e.getID() for e in path[1:]]
    return tuple(route)


def match_routes(
    net: Any,
    cols: dict[str, np.ndarray],
    bounds: np.ndarray,
    bound: float,
    samples: LaneSamples | None = None,
) -> list[tuple[str, ...] | str]:
    """Per vehicle (its points ``bounds[k]:bounds[k + 1]`` of ``cols``: ``t``, ``x``, ``y``, ``v``,
    ``heading``, in time order), its connected route of edges, or why its positions match none (a phrase).
    The distance driven is the recorded speed integrated over time (a jump in position drives nothing).
    ``samples``: ``net``'s lane samples where the caller has them (None: sampled here)."""
    samples = lane_samples(net) if samples is None else samples
    lane = nearest_lanes(samples, cols["x"], cols["y"], cols["heading"], bound)
    edge_of = np.array([*samples.edge, ""], dtype=object)  # -1: no lane
    car = np.array([*samples.car, True])
    names = np.array([*samples.ids, ""], dtype=object)
    return _routes(net, edge_of[lane], car[lane], names[lane], cols["t"], cols["v"], bounds)


def lane_routes(
    net: Any, lanes: np.ndarray, cols: dict[str, np.ndarray], bounds: np.ndarray
) -> list[tuple[str, ...] | str]:
    """Per vehicle, as :func:`match_routes`, from its recorded ``lanes`` (SUMO lane ids, '' for none;
    every one a lane of ``net``) instead of its positions."""
    table = {ln.getID(): ln for e in net.getEdges(withInternal=True) for ln in e.getLanes()}
    uniq, inv = np.unique(lanes.astype(str), return_inverse=True)
    edge = np.array(
        ["" if not u or u.startswith(":") else table[u].getEdge().getID() for u in uniq], dtype=object
    )
    car = np.array([not u or u.startswith(":") or bool(table[u].allows(CAR_CLASS)) for u in uniq])
    return _routes(net, edge[inv], car[inv], uniq.astype(object)[inv], cols["t"], cols["v"], bounds)


def _routes(
    net: Any,
    edges: np.ndarray,
    car: np.ndarray,
    lanes: np.ndarray,
    t: np.ndarray,
    v: np.ndarray,
    bounds: np.ndarray,
) -> list[tuple[str, ...] | str]:
    """Per vehicle, the connected route of its points' ``edges`` ('' for none) or why there is none; a
    point on a lane a car may not use (``car`` False) gives no edge, and a vehicle with more than
    ``NOT_CAR_SHARE`` of its points on such lanes has no route."""
    step = np.r_[0.0, 0.5 * (v[1:] + v[:-1]) * np.diff(t)]  # trapezoids; a vehicle's first is dropped below
    out: list[tuple[str, ...] | str] = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):  # per vehicle
        off = ~car[a:b]
        if off.mean() > NOT_CAR_SHARE:
            lane = lanes[a + int(np.argmax(off))]
            out.append(f"it drove on lane {lane}, which a passenger car may not use")
            continue
        dist = np.cumsum(np.r_[0.0, step[a + 1 : b]])
        out.append(connect(net, np.where(off, "", edges[a:b]).tolist(), dist))
    return out
