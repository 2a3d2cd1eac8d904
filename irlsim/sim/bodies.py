"""Vehicle bodies for the ego's collision check in the simulation: another car is one box along its heading
(SUMO's, from its rear to its front); a long vehicle (a bus, a truck with its trailer, longer than
:data:`LONG_VEHICLE`) and the ego, of any length, are boxes along the path their front drove, as a body
follows that path.

A rigid box along the front's heading is not a 16 m truck's body: where its front turns through a bend
or a lane's shift, a rigid box puts its rear to the side of the front (16.25 m at 14 degrees: 3.9 m)
where the truck's body, still on the lane before the shift, is not, and into vehicles it never reaches.
SUMO's recorded truck-trailers at its game crossing "collided" so with the oncoming traffic in 4 of 20 of
their own recorded drives (docs/results/styles.md). Nor is it the ego's in a junction's tight turn: on a
6 m radius a 4.5 m box along the front's heading swings its rear 1.5 m outwards, into the car turning in
the next lane (on a SUMO user's signalised grid, 4 of the expert's 20 drives). The chain takes the trail
of the vehicle's front positions (kept while it is driven), cuts its last ``length`` metres into equal
parts of at most :data:`PART` and puts a box on each chord; where the trail is shorter than the vehicle
(it has just appeared), it goes on straight back along the trail's oldest stretch (the front's heading
without a trail): a rigid box on a straight path.
"""

from __future__ import annotations

import math

import numpy as np

from irlsim.sim.collision import obb_collide
from irlsim.sim.types import EgoState, VehicleStates

#: [m] a vehicle longer than this is a chain of boxes along its path (SUMO's default truck, 7.1 m, is not)
LONG_VEHICLE = 7.5
#: [m] the longest part of a chain
PART = 5.0
#: [m] a trail point is kept where the front has moved at least this far from the last one
TRAIL_STEP = 0.25
#: [rad] a front that moved more than this off its heading jumped sideways (SUMO's instantaneous lane
#: change moves a vehicle 3.2 m sideways in one step): its trail starts again from the new point
TRAIL_JUMP = math.pi / 4


def chain(
    trail: list[tuple[float, float]],
    x: float,
    y: float,
    yaw: float,
    length: float,
    width: float,
    along: bool = False,
) -> tuple[np.ndarray, ...]:
    """The boxes of a body (front-bumper centre x, y, yaw, length, width; each an array of the parts):
    one box along ``yaw`` up to :data:`LONG_VEHICLE` (unless ``along``), else equal parts along the path
    through the front (``x``, ``y``) and ``trail`` (its earlier front positions, the newest last)."""
    if length <= LONG_VEHICLE and not along:
        return tuple(np.array([v], dtype=np.float64) for v in (x, y, yaw, length, width))
    pts = np.array([(x, y), *reversed(trail)], dtype=np.float64)
    keep = np.concatenate([[True], np.hypot(*np.diff(pts, axis=0).T) > 1e-9])
    pts = pts[keep]
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] < length:  # straight on back along the oldest stretch (the heading without one)
        back = pts[-1] - pts[-2] if len(pts) > 1 else -np.array([math.cos(yaw), math.sin(yaw)])
        back = back / np.hypot(*back)
        pts = np.vstack([pts, pts[-1] + (length - cum[-1]) * back])
        cum = np.append(cum, length)
    n = math.ceil(length / PART)
    at = np.linspace(0.0, length, n + 1)
    px, py = np.interp(at, cum, pts[:, 0]), np.interp(at, cum, pts[:, 1])
    yaws = np.arctan2(py[:-1] - py[1:], px[:-1] - px[1:])
    return px[:-1], py[:-1], yaws, np.full(n, length / n), np.full(n, width)


class Bodies:
    """The trails of the long vehicles and of the ego through an episode, and the ego's check."""

    def __init__(self, ego_along_path: bool = True) -> None:
        """``ego_along_path`` False: a car ego is one box along its heading, as other cars are (a recorded
        ego replayed as recorded: SUMO changed its lane in one step, the recording's rows a second apart
        draw that across both lanes, and its recorded heading stays along the lane)."""
        self.trails: dict[str, list[tuple[float, float]]] = {}
        self.ego_trail: list[tuple[float, float]] = []
        self.ego_along_path = ego_along_path

    @staticmethod
    def _follow(trail: list[tuple[float, float]], x: float, y: float, yaw: float, length: float) -> None:
        """Add the front (``x``, ``y``, heading ``yaw``) to ``trail`` where it moved, keeping a vehicle's
        length and a part; where it moved more than TRAIL_JUMP off its heading (sideways: a lane change
        SUMO made in one step, or a recording's rows a second apart interpolated across it) the trail
        starts again there (the body then lies straight back along the heading, as a rigid box)."""
        if not trail or math.hypot(x - trail[-1][0], y - trail[-1][1]) >= TRAIL_STEP:
            if trail:
                dx, dy = x - trail[-1][0], y - trail[-1][1]
                off = math.atan2(dy, dx) - yaw
                if abs(math.atan2(math.sin(off), math.cos(off))) > TRAIL_JUMP:
                    trail.clear()
            trail.append((x, y))
            while len(trail) > 2 and _arc(trail[1:]) > length + PART:
                trail.pop(0)

    def hits(
        self, ego: EgoState, length: float, width: float, veh: VehicleStates, near: np.ndarray
    ) -> np.ndarray:
        """Whether the ego's body overlaps each of the vehicles ``near`` (indices into ``veh``); the long
        vehicles' trails are advanced first (every step, near or not)."""
        long = np.flatnonzero(veh.length > LONG_VEHICLE)
        ids = {veh.ids[i] for i in long}
        for vid in [v for v in self.trails if v not in ids]:
            del self.trails[vid]
        for i in long:
            trail = self.trails.setdefault(veh.ids[i], [])
            self._follow(trail, float(veh.x[i]), float(veh.y[i]), float(veh.yaw[i]), float(veh.length[i]))
        self._follow(self.ego_trail, ego.x, ego.y, ego.yaw, length)  # the ego's body: any length
        if not len(near):
            return np.zeros(0, dtype=bool)
        along = self.ego_along_path
        ex, ey, eyaw, elen, ewid = chain(self.ego_trail, ego.x, ego.y, ego.yaw, length, width, along=along)
        if len(ex) == 1 and not np.any(veh.length[near] > LONG_VEHICLE):
            return obb_collide(
                ex[0], ey[0], eyaw[0], length, width,
                veh.x[near], veh.y[near], veh.yaw[near], veh.length[near], veh.width[near],
            )  # fmt: skip
        trails = [self.trails.get(veh.ids[i], []) for i in near]
        parts = [
            chain(t, veh.x[i], veh.y[i], veh.yaw[i], veh.length[i], veh.width[i])
            for t, i in zip(trails, near, strict=True)
        ]
        owner = np.repeat(np.arange(len(near)), [len(p[0]) for p in parts])
        ox, oy, oyaw, olen, owid = (np.concatenate([p[k] for p in parts]) for k in range(5))
        hit = obb_collide(
            ex[:, None], ey[:, None], eyaw[:, None], elen[:, None], ewid[:, None], ox, oy, oyaw, olen, owid
        ).any(axis=0)
        out = np.zeros(len(near), dtype=bool)
        np.logical_or.at(out, owner, hit)
        return out


def _arc(points: list[tuple[float, float]]) -> float:
    """[m] the length of a polyline."""
    p = np.asarray(points, dtype=np.float64)
    return float(np.hypot(*np.diff(p, axis=0).T).sum()) if len(p) > 1 else 0.0
