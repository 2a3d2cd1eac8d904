"""Background traffic around the ego: spawning, recycling, pending insertions, stop-line monitoring.

Works through the SUMO API module it is handed (``libsumo`` or ``traci``, same functions). Vehicles
drive a route that repeats the loop many times (one route per start edge), at a constant speed set with
``setMaxSpeed`` (vehicle type ``bg``: sigma 0, no lane changes); SUMO's car following and the
``allway_stop`` junctions make them slow down and stop. Route-frame distances are wrapped to
[-lap/2, lap/2) around the ego.

Spread, not walls: vehicles enter about ``spawn_distance`` ahead of the ego, never within
``insert_spacing`` of another vehicle in any lane, and are recycled only ``recycle_behind`` (600 m)
behind it, so 15 vehicles are ~55 m apart along the road. Entering beside each other at near-equal
speeds, three of them would form a 'wall' across the road that nothing passes for tens of seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from irlsim.road import Road, junctions
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.types import VehicleStates

BG_TYPE = "bg"
#: [m] per lane change it needs, no vehicle enters a lane that does not go on along the route closer than
#: this to where it stops going on (SUMO refuses a departure that cannot leave the lane in time: 'junction
#: too close', 'too many lane changes required')
LANE_END_CLEARANCE = 150.0
#: [m] how far along the route a lane is followed to find where it stops going on
RUNWAY_HORIZON = 1000.0
#: [m/s^2] the background vehicles' deceleration (vehicle type 'bg' in sumo_net/vtypes.add.xml) and [m] the
#: room beyond their braking distance they keep from a junction where they yield when they enter
BG_DECEL = 4.5
YIELD_MARGIN = 10.0


@dataclass
class _Tracked:
    s: float  # unwrapped route position of the front bumper [m]
    stopped: list[bool]  # per stop line: stood still in its zone since last passing it
    stand_since: float  # [s] time it began standing outside a stop-line queue; NaN while not


@dataclass
class LoopEdges:
    """Route-frame extent of each route edge (middle lane) to map s -> (edge, lane position)."""

    ids: tuple[str, ...]
    s0: np.ndarray  # [E] [m]
    s1: np.ndarray  # [E] [m]
    length: np.ndarray  # [E] SUMO edge length [m]

    @staticmethod
    def from_road(road: Road) -> LoopEdges:
        s0, s1, ln = [], [], []
        for eid, a, b in road.edge_bounds:  # each edge's ends projected near its own stretch of the route
            s0.append(a)
            s1.append(b if b > a else b + road.lap_length)
            ln.append(float(road.net.getEdge(eid).getLength()))
        return LoopEdges(road.edges, np.array(s0), np.array(s1), np.array(ln))

    def locate(self, s: float, lap: float, margin: float = 1.0) -> tuple[str, float] | None:
        """(edge id, lane position [m]) of wrapped route position s; None inside a junction (or within
        ``margin`` of an edge end, where insertion is fragile)."""
        s = s % lap
        for eid, a, b, ln in zip(self.ids, self.s0, self.s1, self.length, strict=False):
            for ss in (s, s + lap):
                if a + margin <= ss <= b - margin:
                    return eid, (ss - a) / (b - a) * ln
        return None


@dataclass
class BackgroundTraffic:
    """Keeps ``cfg.n_vehicles`` background vehicles around the ego; see the module docstring."""

    api: Any
    road: Road
    cfg: EpisodeConfig
    rng: np.random.Generator
    route_laps: int
    edges: LoopEdges
    counter: int = 0
    pending: set[str] = field(default_factory=set)
    tracked: dict[str, _Tracked] = field(default_factory=dict)
    sizes: dict[str, tuple[float, float]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    off_loop: set[str] = field(default_factory=set)
    stuck: set[str] = field(default_factory=set)
    failures: list[dict[str, Any]] = field(default_factory=list)
    #: route position [m] where each vehicle irlsim inserted entered, until it is tracked
    placed: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for k in ("recycled", "resampled", "stop_lines_passed", "stop_lines_compliant", "collisions"):
            self.counts.setdefault(k, 0)
        # (route edge, SUMO lane) -> (metres it goes on along the route beyond its edge's end, lane changes
        # needed where it stops): the lanes that turn off or end within RUNWAY_HORIZON (none on the oval)
        self._runway = lane_runways(self.road)
        # the route edges whose way on yields (a merge): SUMO refuses a departure too close to brake there
        self._yields = set(junctions.yield_ends(self.road.net, self.road.edges, self.road.closed))

    # ------------------------------------------------------------------ routes and insertion
    def add_routes(self) -> None:
        """One route per route edge: on a loop, the loop from that edge repeated ``route_laps`` times; on
        an open route, the rest of the route (vehicles leave at its end and others enter ahead)."""
        route = self.road.edges
        n = len(route)
        for i, eid in enumerate(route):
            if self.road.closed:
                edges = [route[(i + k) % n] for k in range(n * self.route_laps)]
            else:
                edges = list(route[i:])
            self.api.route.add(f"loop@{eid}", edges)

    def _spot_free(
        self, s: float, lane: int, ego_s: float, occupied: list[tuple[float, int]], spacing: bool = True
    ) -> bool:
        """No insertion near the ego, just before a stop line, within ``insert_gap`` of a vehicle in the
        same lane or (``spacing``) within ``insert_spacing`` of a vehicle in any lane."""
        lap = self.road.lap_length
        if abs(wrap_route(s - ego_s, lap)) < self.cfg.spawn_clearance:
            return False
        for sl in self.road.stop_lines:  # a vehicle must have room to stop at the line
            if -2.0 <= (sl.s - s) % lap <= self.cfg.stop_line_keep_out or (s - sl.s) % lap < 2.0:
                return False
        gap_any = self.cfg.insert_spacing if spacing else 0.0
        for so, ln in occupied:
            ds = abs(wrap_route(s - so, lap))
            if ds < gap_any or (ln == lane and ds < self.cfg.insert_gap):
                return False
        return True

    def _insert(self, s: float, lane: int, speed: float) -> str | None:
        loc = self.edges.locate(s, self.road.lap_length)
        if loc is None:
            return None
        eid, pos = loc
        i = self.road.edges.index(eid)
        k = self.road.layout.edge_lane(i, lane)  # the route lane on this edge
        if k < 0:
            return None
        beyond, changes = self._runway.get((i, k), (0.0, 0))
        if changes > 1 or self.edges.length[i] - pos + beyond < LANE_END_CLEARANCE * changes:
            # it could not change out of a lane that does not go on before the lane ends; SUMO refuses a
            # departure that needs two lane changes or more beside other vehicles ('too many lane changes')
            return None
        if i in self._yields and self.edges.length[i] - pos < speed**2 / (2 * BG_DECEL) + YIELD_MARGIN:
            return None  # 'unpriorised junction too close'
        vid = f"bg{self.counter}"
        self.counter += 1
        # SUMO refuses a departure faster than the lane's limit (the type's speedFactor is 1): a street
        # slower than the traffic's speeds (a 20 km/h zone) sees them enter at its limit
        limit = float(self.road.net.getEdge(eid).getLane(k).getSpeed())
        self.api.vehicle.add(
            vid,
            f"loop@{eid}",
            typeID=BG_TYPE,
            departLane=str(k),
            departPos=f"{pos:.3f}",
            departSpeed=f"{min(speed, limit):.3f}",
        )
        self.api.vehicle.setMaxSpeed(vid, speed)
        self.pending.add(vid)
        self.placed[vid] = s
        return vid

    def hints(self, ids: tuple[str, ...], ego_s: float) -> np.ndarray:
        """[N] route position [m] each vehicle ``ids`` is known to be near (``Road.to_frenet``'s ``near``):
        where it was tracked a step before, else where it was inserted, else the ego's ``ego_s``."""
        lap = self.road.lap_length
        out = [self.tracked[v].s % lap if v in self.tracked else self.placed.get(v, ego_s) for v in ids]
        return np.array(out, dtype=np.float64)

    def spawn(self, ego_s: float, vehicles: VehicleStates, initial: bool) -> None:
        """Insert vehicles until ``n_vehicles`` are running or pending.

        Later (``initial=False``) every vehicle enters ``spawn_distance`` +- ``spawn_jitter`` ahead of the
        ego, at a spot at least ``insert_spacing`` from every vehicle in any lane (20 tries per step; a
        vehicle that finds no spot enters at a later step). At reset (``initial=True``) the traffic is
        laid out as that spawn / recycle cycle leaves it: the span from ``recycle_behind`` behind the ego
        to spawn_distance + spawn_jitter ahead is cut into one slot per vehicle and each vehicle is drawn
        inside its slot (so they are evenly spread, most of them behind the ego); a slot without a free
        spot hands its vehicle to a draw over the whole span with the same-lane gap only."""
        missing = self.cfg.n_vehicles - (vehicles.count + len(self.pending))
        if missing <= 0 or self.road.demand:  # a scenario's own demand brings its vehicles itself
            return
        occupied = [
            (float(s), int(ln)) for s, ln in zip(vehicles.s, self.road.lane_of_d(vehicles.d), strict=False)
        ]
        c = self.cfg
        lap = self.road.lap_length
        hi = c.spawn_distance + c.spawn_jitter
        lo = -min(c.recycle_behind, lap / 2 - hi - 1.0)
        if initial:
            edges = np.linspace(lo, hi, missing + 1)
            # slots in a random order, so which ones give way near the stop lines is random too
            plan: list[tuple[float, float, bool]] = [
                (float(edges[k]), float(edges[k + 1]), True) for k in self.rng.permutation(missing)
            ]
        else:
            plan = [(c.spawn_distance - c.spawn_jitter, hi, True)] * missing
        left = 0
        for a, b, spacing in plan:
            if not self._draw(ego_s, a, b, occupied, spacing):
                left += 1
        if initial:
            for _ in range(left):
                self._draw(ego_s, lo, hi, occupied, spacing=False)

    def _draw(
        self, ego_s: float, a: float, b: float, occupied: list[tuple[float, int]], spacing: bool
    ) -> bool:
        """Insert one vehicle at a random spot ds in [a, b] ahead of the ego (20 tries)."""
        c = self.cfg
        for _try in range(20):
            ds = self.rng.uniform(a, b)
            s = (ego_s + ds) % self.road.lap_length
            lane = int(self.rng.integers(0, self.road.n_lanes))
            speed = float(self.rng.uniform(c.bg_speed_min, c.bg_speed_max))
            if self._spot_free(s, lane, ego_s, occupied, spacing) and self._insert(s, lane, speed):
                occupied.append((s, lane))
                return True
        return False

    # ------------------------------------------------------------------ per step
    def after_step(self, t: float, ego_s: float, vehicles: VehicleStates) -> None:
        """Drop insertions SUMO left pending (re-drawn later), recycle vehicles far behind the ego, track
        stop lines and the loop, then top the traffic up again."""
        api = self.api
        if self.pending:
            still = set(api.simulation.getPendingVehicles()) & self.pending
            for vid in still:
                api.vehicle.remove(vid)
                self.counts["resampled"] += 1
            self.pending = set()
        lap = self.road.lap_length
        ids = vehicles.ids
        rel = wrap_route(vehicles.s - ego_s, lap)
        recycle = (rel < -self.cfg.recycle_behind) & (not self.road.demand)
        for i in np.flatnonzero(recycle):
            api.vehicle.remove(ids[i])
            self.counts["recycled"] += 1
        keep = ~recycle
        kept = vehicles.subset(keep)
        self._track(t, kept)
        self.spawn(ego_s, kept, initial=False)

    def _track(self, t: float, veh: VehicleStates) -> None:
        """Per vehicle: unwrapped progress, stops in each stop line's zone, lines passed, off-loop, and
        standing still outside a stop-line queue for longer than ``bg_stuck_time`` (stuck)."""
        lap = self.road.lap_length
        old = self.tracked
        self.tracked = {}
        self.placed = {v: s for v, s in self.placed.items() if v in self.pending}  # not seen yet
        if veh.count == 0:
            return
        n_lines = len(self.road.stop_lines)
        prev = np.array([old[v].s if v in old else s for v, s in zip(veh.ids, veh.s, strict=False)])
        since = np.array([old[v].stand_since if v in old else np.nan for v in veh.ids])
        stopped = np.array([old[v].stopped if v in old else [False] * n_lines for v in veh.ids], dtype=bool)
        s_new = prev + wrap_route(veh.s - prev, lap)
        lines = np.array([sl.s for sl in self.road.stop_lines])  # [L]
        passed = np.ceil((s_new[:, None] - lines) / lap) - np.ceil((prev[:, None] - lines) / lap)  # [M, L]
        if passed.any():
            for i, k in zip(*np.nonzero(passed > 0), strict=False):
                self.counts["stop_lines_passed"] += 1
                self.counts["stop_lines_compliant"] += int(stopped[i, k])
                if not stopped[i, k]:
                    self.failures.append({"t": t, "vehicle": veh.ids[i], "stop_line": int(k)})
            stopped &= ~(passed > 0)
        to_line = (lines - s_new[:, None]) % lap  # [M, L] distance ahead to each stop line
        standing = veh.v < self.cfg.stop_speed
        stopped |= standing[:, None] & (to_line <= self.cfg.stop_zone)
        # standing in a queue before a stop line or a traffic light is normal; anywhere else a vehicle
        # should not stand for long
        queue = to_line <= self.cfg.bg_stuck_queue
        if self.road.signals:
            sig = np.array([g.s for g in self.road.signals])
            queue = np.concatenate([queue, (sig - s_new[:, None]) % lap <= self.cfg.bg_stuck_queue], axis=1)
        waiting = standing & ~queue.any(axis=1) & (np.abs(veh.d) <= self.road.half_road + 0.3)  # on the route
        since = np.where(waiting, np.where(np.isnan(since), t, since), np.nan)
        over = waiting & (t - since > self.cfg.bg_stuck_time)
        if over.any():
            self.stuck.update(veh.ids[i] for i in np.flatnonzero(over))
        for i, vid in enumerate(veh.ids):
            self.tracked[vid] = _Tracked(float(s_new[i]), stopped[i].tolist(), float(since[i]))
        off = np.abs(veh.d) > self.road.half_road + 0.3
        if off.any():
            self.off_loop.update(veh.ids[i] for i in np.flatnonzero(off))

    def stats(self) -> dict[str, int]:
        c = self.counts
        return {
            "sim/bg_stop_lines_passed": c["stop_lines_passed"],
            "sim/bg_stop_lines_compliant": c["stop_lines_compliant"],
            "sim/bg_off_loop": len(self.off_loop),
            # vehicles that stood still (v < stop_speed) longer than bg_stuck_time anywhere but within
            # bg_stuck_queue before a stop line: blocked traffic, the failure a teleport would hide (SUMO
            # never teleports here, --time-to-teleport -1)
            "sim/bg_stuck": len(self.stuck),
            "sim/bg_collisions": c["collisions"],
            "sim/bg_recycled": c["recycled"],
            "sim/bg_resampled": c["resampled"],
        }


def lane_runways(road: Road) -> dict[tuple[int, int], tuple[float, int]]:
    """For every car lane of every route edge that stops going on along the route within RUNWAY_HORIZON
    (it turns off into another road, or ends): (route edge index, SUMO lane) -> (metres it is followed
    beyond its edge's end, the lane changes needed where it stops: to the nearest lane that goes on)."""
    edges, n, lay = road.edges, len(road.edges), road.layout
    out: dict[tuple[int, int], tuple[float, int]] = {}
    for i in range(n):
        for g in range(lay.first[i], lay.first[i] + lay.count[i]):
            j, lane, dist = i, lay.edge_lane(i, g), 0.0
            while dist < RUNWAY_HORIZON and (road.closed or j < n - 1):
                nxt = (j + 1) % n
                cons = [
                    c
                    for c in road.net.getEdge(edges[j]).getLane(lane).getOutgoing()
                    if c.getTo().getID() == edges[nxt] and lay.route_lane(nxt, c.getToLane().getIndex()) >= 0
                ]
                if not cons:
                    here = lay.route_lane(j, lane)
                    going = [
                        lay.route_lane(j, ln.getIndex())
                        for ln in road.net.getEdge(edges[j]).getLanes()
                        if any(c.getTo().getID() == edges[nxt] for c in ln.getOutgoing())
                    ]
                    out[(i, lay.edge_lane(i, g))] = (dist, min(abs(here - h) for h in going if h >= 0))
                    break
                j, lane = nxt, cons[0].getToLane().getIndex()
                dist += float(road.net.getEdge(edges[j]).getLength())
                if j == i and road.closed:
                    break  # round the loop and back: it goes on for ever
    return out


def wrap_route(ds: Any, lap: float) -> Any:
    """Route distance wrapped into [-lap/2, lap/2)."""
    return (np.asarray(ds) + lap / 2) % lap - lap / 2
