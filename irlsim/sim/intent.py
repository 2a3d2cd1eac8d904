"""Where a vehicle inside a junction goes, read from SUMO's lanes: a vehicle on a junction's internal lane
follows it, and the internal lanes after it, into one lane of an edge; where that edge is on the ego's
route, the vehicle's way ahead is that lane's centre line (:class:`JunctionPaths`). The planner predicts
such a vehicle along it where it is turned against the route (turning into the road from a side street,
:func:`irlsim.planner.planner.route_frame_boxes`): at its present place across the road it would not be
seen coming into a lane until it is in it. A vehicle crossing the route, or turning off it, goes to an
edge off the route and keeps the prediction of every other vehicle.

What SUMO says is where the vehicle *is* going (its route), not a guess; a recording's replayed vehicle
has no route, and SUMO's lane for it is the lane it lies on, so its way is that lane's."""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.road.geometry import Road
from irlsim.sim.types import PATH_STEP

#: points of a path: 80 m from the vehicle's front, more than a planning horizon's travel at a city's speeds
PATH_POINTS = 81
#: internal lanes followed at most (a junction's lane, and an internal junction's after it)
MAX_INTERNAL = 4


class JunctionPaths:
    """Each vehicle's way ahead while it is inside a junction and bound for the ego's route; the lanes'
    chains are static and read from SUMO once per lane."""

    def __init__(self, road: Road) -> None:
        self.route_edges = frozenset(edge for edge, _, _ in road.edge_bounds)
        # internal lane -> (xy [K, 2] from its start into the route lane it leads to, its SUMO length /
        # its shape's length), or None where it leads off the route
        self._chains: dict[str, tuple[np.ndarray, float] | None] = {}
        self._internal: dict[str, list[str]] | None = None  # junction -> its internal lanes

    def chain(self, api: Any, lane: str) -> tuple[np.ndarray, float] | None:
        """The centre line from the start of internal ``lane`` through the internal lanes after it into
        the first lane of an edge, and the ratio of ``lane``'s SUMO length to its shape's; None where that
        edge is not on the route (or the chain does not end within :data:`MAX_INTERNAL` lanes)."""
        if lane in self._chains:
            return self._chains[lane]
        points: list[np.ndarray] = []
        here, found = lane, None
        for _ in range(MAX_INTERNAL + 1):
            points.append(np.asarray(api.lane.getShape(here), dtype=np.float64))
            if not here.startswith(":"):
                found = here
                break
            links = api.lane.getLinks(here)
            if not links:
                break
            here = self._via(api, here, points[-1][-1], links[0][0])
        chain = None
        if found is not None and api.lane.getEdgeID(found) in self.route_edges:
            xy = np.concatenate(points)
            geometric = float(np.hypot(*np.diff(points[0], axis=0).T).sum())  # ``lane``'s own shape
            chain = (xy, float(api.lane.getLength(lane)) / geometric if geometric > 0 else 1.0)
        self._chains[lane] = chain
        return chain

    def _via(self, api: Any, lane: str, end: np.ndarray, to: str) -> str:
        """The lane after internal ``lane`` (ending at ``end``) on its way to ``to``: SUMO's link names
        the lane it leads to, not an internal junction's lane between (a left turn waiting inside the
        junction), so that lane is the junction's internal lane that starts where ``lane`` ends and
        leads to ``to``; else ``to``."""
        if np.hypot(*(np.asarray(api.lane.getShape(to)[0]) - end)) < 0.5:
            return to
        if self._internal is None:
            self._internal = {}
            for other in api.lane.getIDList():
                if other.startswith(":"):
                    self._internal.setdefault(other[1:].rsplit("_", 2)[0], []).append(other)
        for other in self._internal.get(lane[1:].rsplit("_", 2)[0], []):
            if other != lane and np.hypot(*(np.asarray(api.lane.getShape(other)[0]) - end)) < 0.1:
                if any(link[0] == to for link in api.lane.getLinks(other)):
                    return str(other)
        return to

    def paths(self, api: Any, ids: tuple[str, ...]) -> np.ndarray | None:
        """[M, PATH_POINTS, 2] xy of each vehicle's way ahead from its lane position, every
        :data:`PATH_STEP` metres (straight on beyond the chain's end), NaN for a vehicle not inside a
        junction or bound off the route; None where no vehicle has one."""
        out: np.ndarray | None = None
        for i, vid in enumerate(ids):
            lane = api.vehicle.getLaneID(vid)
            if not lane.startswith(":"):
                continue
            chain = self.chain(api, lane)
            if chain is None:
                continue
            xy, scale = chain
            if out is None:
                out = np.full((len(ids), PATH_POINTS, 2), np.nan)
            out[i] = along(xy, api.vehicle.getLanePosition(vid) / scale + np.arange(PATH_POINTS) * PATH_STEP)
        return out


def along(xy: np.ndarray, at: np.ndarray) -> np.ndarray:
    """[N, 2] points of the polyline ``xy`` [K, 2] at the arc lengths ``at`` [N] [m] from its first
    point; beyond its last point straight on along its last segment."""
    seg = np.hypot(*np.diff(xy, axis=0).T)
    keep = np.concatenate([[True], seg > 1e-9])  # repeated points would divide by 0
    xy = xy[keep]
    arc = np.concatenate([[0.0], np.cumsum(seg[seg > 1e-9])])
    if len(xy) < 2:
        return np.repeat(xy[:1], len(at), axis=0)
    x = np.interp(at, arc, xy[:, 0])
    y = np.interp(at, arc, xy[:, 1])
    beyond = at > arc[-1]
    if beyond.any():
        u = (xy[-1] - xy[-2]) / np.hypot(*(xy[-1] - xy[-2]))
        x[beyond] = xy[-1, 0] + u[0] * (at[beyond] - arc[-1])
        y[beyond] = xy[-1, 1] + u[1] * (at[beyond] - arc[-1])
    return np.stack([x, y], axis=1)
