"""Right of way at the route's minor links (yield and priority junctions, :attr:`Road.yield_points`),
from SUMO's junction model.

Every step on a road with yield points, libsumo's ``vehicle.getJunctionFoes(ego, YIELD_LOOKAHEAD)`` lists
the vehicles approaching or inside a conflict area of the junctions ahead of the ego (within that many
metres of its route) with, per foe, the ego's and the foe's distance to the start and the end of their
conflict area and which of the two must respond to the other (SUMO's link priorities: ``egoResponse`` is
True where the foe has priority). Only the foes the ego must respond to, at a yield point's junction,
count. irlsim judges their timing with SUMO's gap acceptance for a minor link (``jmTimegapMinor``, SUMO's
default 1 s: the time a vehicle leaves between itself and a prioritised one when passing ahead of it):

- the yield point **binds** (its line holds the ego like a red light's) while a foe with priority is
  inside the conflict area or would reach it before the ego, going now, has cleared it plus
  ``YIELD_GAP`` (the ego's time to clear: its distance to the area's end plus its length, from its
  speed accelerating at ``YIELD_ACCEL`` up to the road's limit);
- entering the conflict area while it binds (a foe with priority inside it, or due before the ego
  clears it plus the gap: the foe would have to brake for the ego) is a **yield violation** (counted
  once per yield point and passage, like crossing on red).

The foes' times to the area are their distance over their speed (a foe standing outside the area never
arrives: SUMO's queued vehicles do not hold the ego).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.road import Road
from irlsim.sim.config import EpisodeConfig

#: [m] how far ahead along its route the ego asks SUMO for junction foes (beyond the planner's stop
#: reach of a yield line at city speeds)
YIELD_LOOKAHEAD = 60.0
#: [m] how far past a yield line (through its junction) SUMO is still asked, and how far beyond the line
#: it looks: the conflict areas of generated junctions end within it. SUMO is asked only from
#: YIELD_LOOKAHEAD before a yield line to YIELD_PAST beyond it, and no further ahead than YIELD_PAST past
#: the line: libsumo 1.28's getJunctionFoes crashed the process (SIGSEGV) when the ego reached some
#: junctions where a lane widens into two (netgenerate's spider networks), none of them a yield point
YIELD_PAST = 30.0
#: [s] SUMO's jmTimegapMinor default: the gap a minor-road vehicle keeps ahead of a prioritised one
YIELD_GAP = 1.0
#: [m/s^2] the ego's acceleration from where it is when judging whether it would clear in time (below
#: the planner's largest, which it reaches only after its acceleration ramp)
YIELD_ACCEL = 1.5
#: [m/s] below this a foe outside the conflict area counts as standing (it never arrives)
STANDING = 0.1


def junction_of(internal_lane: str) -> str:
    """The node id of a junction's internal lane ``:<node>_<link>_<lane>`` (node ids may hold '_')."""
    return internal_lane[1:].rsplit("_", 2)[0] if internal_lane.startswith(":") else ""


def clear_time(dist: np.ndarray, v: float, accel: float, v_max: float) -> np.ndarray:
    """[s] time to cover ``dist`` [m] (>= 0) from speed ``v`` [m/s], accelerating at ``accel`` up to
    ``v_max`` and on at it (vectorised over ``dist``)."""
    dist = np.maximum(np.asarray(dist, dtype=np.float64), 0.0)
    v = min(max(v, 0.0), v_max)
    t_ramp = (v_max - v) / accel
    d_ramp = v * t_ramp + 0.5 * accel * t_ramp**2
    in_ramp = (np.sqrt(v * v + 2.0 * accel * dist) - v) / accel
    return np.where(dist <= d_ramp, in_ramp, t_ramp + (dist - d_ramp) / max(v_max, 1e-9))


def foe_arrival(foe_dist: np.ndarray, foe_exit: np.ndarray, foe_v: np.ndarray) -> np.ndarray:
    """[s] when each foe reaches its conflict area: 0 inside it, inf once past it or while standing."""
    inside = (foe_dist <= 0.0) & (foe_exit > 0.0)
    moving = (foe_dist > 0.0) & (foe_v >= STANDING)
    return np.where(inside, 0.0, np.where(moving, foe_dist / np.maximum(foe_v, STANDING), np.inf))


class YieldWatch:
    """The ego's right of way at a road's yield points, read from SUMO each step (:meth:`read`):
    ``binding`` per yield point, and the violations of the last step."""

    def __init__(self, road: Road, cfg: EpisodeConfig):
        self.nodes = tuple(p.node for p in road.yield_points)
        self.ways: dict[str, set[str]] = {}  # node -> the internal lanes of the route's way(s) through it
        for p in road.yield_points:
            self.ways.setdefault(p.node, set()).update(p.lanes)
        self.s = np.array([p.s for p in road.yield_points], dtype=np.float64)  # [m] their route positions
        self.lap = float(road.lap_length)
        self.ego_length = float(cfg.ego_length)
        self.v_max = min(float(cfg.ego_target_speed), road.max_speed_limit)  # [m/s] the ego's top speed
        self.binding = np.zeros(len(self.nodes), dtype=bool)
        self._ego_dist: dict[tuple[str, str], float] = {}  # (node, foe) -> ego's distance last step
        self._violated: set[str] = set()  # nodes violated in the current passage

    def reach(self, ego_s: float) -> float:
        """[m] how far ahead of the ego (route position ``ego_s``) SUMO is asked for junction foes: up to
        YIELD_PAST beyond the nearest yield line within reach (YIELD_LOOKAHEAD before it to YIELD_PAST
        past it), at most YIELD_LOOKAHEAD; 0 where none is (SUMO is not asked)."""
        ahead = (self.s - ego_s + self.lap / 2) % self.lap - self.lap / 2  # [m] wrapped on a loop
        live = ahead[(ahead <= YIELD_LOOKAHEAD) & (ahead >= -YIELD_PAST)]
        return float(min(YIELD_LOOKAHEAD, live.min() + YIELD_PAST)) if len(live) else 0.0

    def on_way(self, lane: str) -> bool:
        """Whether SUMO's foe answer for the ego's internal lane ``lane`` is one of the route's way through
        a yield point's junction: where two links' internal lanes run together (a turn's end where another
        approach's joins it), SUMO may place the moved ego on the other link's lane and answer with that
        link's foes and priorities, which are not the ego's. A point without internal lanes known takes
        every lane of its junction."""
        node = junction_of(lane)
        way = self.ways.get(node)
        return way is not None and (not way or lane in way)

    def read(self, api: Any, ego: str, ego_v: float, ego_s: float) -> int:
        """Ask SUMO for the ego's junction foes near a yield point; set ``binding``; return the new
        violations this step. On a road without yield points, and away from them, SUMO is not asked
        (those episodes keep their bytes)."""
        if not self.nodes:
            return 0
        foes: Any = ()
        if (reach := self.reach(ego_s)) > 0.0:
            try:
                foes = api.vehicle.getJunctionFoes(ego, reach)
            except Exception:  # the ego has left the simulation (SUMO's driver at its route's end)
                foes = ()
        mine = [f for f in foes if f[7] and self.on_way(f[5])]
        self.binding = np.zeros(len(self.nodes), dtype=bool)
        if not mine:
            self._ego_dist, self._violated = {}, set()
            return 0
        node = np.array([self.nodes.index(junction_of(f[5])) for f in mine])
        ego_d, foe_d, ego_x, foe_x = (np.array([f[k] for f in mine], dtype=np.float64) for k in range(1, 5))
        foe_v = np.array([api.vehicle.getSpeed(f[0]) for f in mine], dtype=np.float64)
        arrive = foe_arrival(foe_d, foe_x, foe_v)
        to_clear = ego_x + self.ego_length
        go_now = clear_time(to_clear, ego_v, YIELD_ACCEL, self.v_max)
        too_soon = arrive < go_now + YIELD_GAP
        np.logical_or.at(self.binding, node, too_soon)
        before = np.array(
            [self._ego_dist.get((self.nodes[k], f[0]), np.inf) for k, f in zip(node, mine, strict=True)]
        )
        # entering the conflict area while a foe SUMO already listed the step before was due: a foe SUMO
        # lists first when the ego is already inside (it just changed into, or was inserted on, its lane)
        # is none the ego could have yielded to
        entering = (ego_d <= 0.0) & np.isfinite(before) & (before > 0.0) & (ego_x > -self.ego_length)
        bad = entering & too_soon
        live = {self.nodes[k] for k in node}
        self._violated &= live
        new = {self.nodes[k] for k in node[bad]} - self._violated
        self._violated |= new
        self._ego_dist = {(self.nodes[k], f[0]): float(d) for k, f, d in zip(node, mine, ego_d, strict=True)}
        return len(new)
