"""Road geometry of the oval in the route frame, read from the SUMO network with sumolib.

The route frame: ``s`` is arc length [m] along the reference line (the centreline of the middle loop
lane, which is the drawn line of the one-way 3-lane loop), ``d`` the signed lateral offset [m],
positive to the left (towards the inner lane). Lane ``k`` has its centre at ``d = (k - 1) * LANE_WIDTH`` on
the oval; any other route: see :class:`Road`.
Yaw is ENU: radians, 0 = east, counter-clockwise. SUMO angles are degrees, 0 = north, clockwise.

The reference line is the concatenation of the middle lane's shapes, internal (junction) lanes included,
resampled every ``REF_STEP`` metres. Projection xy -> (s, d) is onto that polyline; (s, d) -> xy uses the
normal interpolated between vertex normals, and the projection inverts exactly that, so a round trip is
exact (float precision).
"""

# size-ok: one class, Road, whose reference line, projection raster and route-frame maps share private
# arrays; what is not Road here (the small records and resampling helpers) is a tenth of the file
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.road import crossing, junctions, route
from irlsim.road.angles import atan2

if TYPE_CHECKING:
    from irlsim.road.scenario import Scenario

LANE_WIDTH = 3.2  # [m]
N_LANES = 3
HALF_ROAD = N_LANES * LANE_WIDTH / 2  # [m] |d| of the loop's road edges
REF_STEP = 0.5  # [m] reference line resampling
#: [m] how far a scenario's checkpoint may lie beyond the edges of the lanes that exist where it is (and
#: beyond an open route's ends) and still count as on the road
CHECKPOINT_MARGIN = 1.0
SMOOTH_HALF_WINDOW = 8.0  # [m] the reference is smoothed over +-8 m: SUMO's 6-degree shape kinks vanish
#: [m] in a tight turn the window narrows so that the smoothing moves the line inwards by about this much
#: (a moving average over +-h on radius R moves it by about h^2 / (6 R); R read over +-8 m, which makes a
#: junction's turn look wider than it is): +-8 m cut a netgenerate grid's right turns by 1.0-1.7 m, the
#: ego's lane into the next lane's turn, now 0.3-0.5 m; every shipped route keeps +-8 m (its tightest
#: bend, 153 m on the oval, allows 9.6 m)
SMOOTH_SHIFT = 0.1
RAMP_RANGE = 160.0  # [m] of an exit ramp kept in the route frame, from where it leaves lane 0
OPEN_EXTENSION = 300.0  # [m] an open route's reference runs on straight this far beyond both ends
#: [m] the shortest open route: its reference runs on OPEN_EXTENSION beyond both ends, so the planner's
#: look-ahead (200 m) needs no route of its own; what an episode needs is a start (irlsim.sim.start: at
#: least 37.5 m of route ahead of it at its smallest scale, 5 m to draw it from, off the junctions)
MIN_OPEN_LENGTH = 50.0
#: a turn (at a junction, a tight bend: the reference's radius below TURN_RADIUS [m]) is driven at most as
#: fast as gives TURN_LAT_ACC [m/s^2] of lateral acceleration on the reference's curvature, as a driver
#: takes it; wider bends (every one of the oval's, a motorway's) only by the planner's a_lat_max
TURN_RADIUS = 60.0
TURN_LAT_ACC = 2.5
#: projection index (Road._build_raster): cell size [m]; how far from the reference it answers [m] (points
#: further away search all segments: exact, ~20 us each); search windows [segments], the narrow one for
#: nearly every cell near the road, the wide one where normals converge (inside curves); extra segment
#: before a cell's range
RASTER_CELL = 1.0
RASTER_REACH = 50.0
RASTER_TIERS = (8, 16, 48)
RASTER_PAD = 1
#: projection by progress on a route that comes back near itself (``Road.flat`` False): a point given the
#: route position ``near`` it is known to be close to is projected onto the reference within NEAR_WINDOW
#: [m] of ``near`` either way. The hints are a vehicle's own position one step before (it moves < 4 m in a
#: 0.1 s step at 140 km/h) and, when the road is built, the position of the route edge a point belongs to
#: (off by the smoothing of the line, a few metres); the window is under half of CROSSING_MIN_APART (the
#: least distance along the route between two passes that self_crossing compares), so it never holds
#: the other pass. A point further than the road's half width + NEAR_SLACK [m] from the reference in its
#: window (a vehicle that left the route, a teleport, no fitting hint) is projected onto the nearest
#: segment of the whole route instead, as on a flat route.
NEAR_WINDOW = 25.0
NEAR_SLACK = 5.0


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap angles [rad] into [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def yaw_to_sumo_angle(yaw: float) -> float:
    """ENU yaw [rad] -> SUMO angle [deg, 0 = north, clockwise]."""
    return (90.0 - math.degrees(yaw)) % 360.0


@dataclass(frozen=True)
class Checkpoint:
    index: int
    s: float  # [m] route frame
    x: float  # [m]
    y: float  # [m]
    lane: int  # required lane (-1: any lane)
    #: every lane that meets it, where several do (the lanes the route goes on from); () = just ``lane``
    lanes: tuple[int, ...] = ()

    def meets(self, lane: int) -> bool:
        """True when passing it in ``lane`` keeps the mission."""
        if self.lanes:
            return lane in self.lanes
        return lane == self.lane or (self.lane < 0 <= lane)


@dataclass(frozen=True)
class StopLine:
    node: str  # the allway_stop node
    s: float  # [m] route frame position of the line (end of the incoming lanes)
    x: float  # [m] world position of the line on the middle lane
    y: float


@dataclass(frozen=True)
class Signal:
    """A traffic light on the route: its stop line binds while the route's link shows red or yellow."""

    node: str  # the junction
    s: float  # [m] route frame position of the line (end of the incoming lanes)
    x: float  # [m] world position of the line on the middle lane
    y: float
    tls: str  # SUMO traffic light id
    link: int  # index of the route's connection in the traffic light's state string (its middle lane's)
    edge: str = ""  # the incoming route edge
    #: (SUMO lane index of ``edge``, its link into the route's next edge), for every lane that has one: the
    #: ego on ``edge`` is held by its own lane's signal (``link`` elsewhere)
    lane_links: tuple[tuple[int, int], ...] = ()

    def link_of(self, lane: int) -> int:
        """The link whose state binds a vehicle on lane ``lane`` of the incoming edge: that lane's into the
        route where it has one, else the middle lane's (-1: a lane not known)."""
        return next((link for index, link in self.lane_links if index == lane), self.link)


@dataclass(frozen=True)
class YieldPoint:
    """A minor link on the route (a yield or priority junction): its line binds while a foe with
    priority would reach the conflict area too soon (see :mod:`irlsim.sim.yielding`)."""

    node: str  # the junction
    s: float  # [m] route frame position of the line (end of the incoming lanes)
    x: float  # [m] world position of the line on the middle lane
    y: float
    #: SUMO's internal lanes of the route's way through the junction (every lane's connection into the
    #: next route edge, each through its chain); () on a network without internal lanes
    lanes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Exit:
    """An off-ramp: a trap. ``ramp_s``/``ramp_d`` sample its centreline in the route frame.

    ``s_start`` is where its lane leaves lane 0 (the start of the junction's internal lane); beyond
    ``ramp_s[-1]`` the ramp is far away from the loop.
    """

    edge: str
    s_start: float  # [m]
    ramp_s: np.ndarray  # [M] increasing, [m]
    ramp_d: np.ndarray  # [M] [m]

    def d_at(self, s: np.ndarray) -> np.ndarray:
        """Ramp centre offset [m] at route position(s) ``s`` (NaN outside the ramp's range)."""
        s = np.asarray(s, dtype=np.float64)
        out = np.interp(s, self.ramp_s, self.ramp_d)
        return np.where((s >= self.ramp_s[0]) & (s <= self.ramp_s[-1]), out, np.nan)


@dataclass(frozen=True)
class LaneCentreline:
    """Closed centreline of loop lane ``lane`` in the route frame: the reference's vertices moved to the
    lane centre (d = ``Road.lane_center(lane)``, through ``Road.to_xy``), with arc length along the lane
    itself. Arrays are [M] (one point per reference vertex; the last point joins the first)."""

    lane: int
    x: np.ndarray  # [M] [m]
    y: np.ndarray  # [M] [m]
    s: np.ndarray  # [M] [m] arc length along this lane from its first point (s[0] = 0)
    ref_s: np.ndarray  # [M] [m] route-frame s of each point (= Road.ref_s)
    length: float  # [m] one lap of this lane
    lap_length: float  # [m] one lap of the route frame

    def arc_length(self, s: np.ndarray | float) -> np.ndarray:
        """Arc length [m] along this lane, in [0, length), at route-frame position(s) ``s`` (wrapped);
        linear between the points."""
        sw = np.asarray(s, dtype=np.float64) % self.lap_length
        xp = np.concatenate([self.ref_s, [self.lap_length]])
        fp = np.concatenate([self.s, [self.length]])
        return np.interp(sw, xp, fp) % self.length


class Road:
    """Geometry and topology of a route on a SUMO network, from a ``.net.xml``. Build with
    :func:`load_road` (a scenario name or path: its file names the route and the checkpoints) or
    directly from a network, a route and checkpoints (None: derived from the route).

    The reference line (d = 0) is the centre of the road: the middle lane's centreline for an odd number
    of lanes, midway between the two middle lanes for an even one. Lane ``k`` (0 = rightmost) has its
    centre at ``d = (k - (n_lanes - 1) / 2) * lane_width``. A loop route (its last edge leads into its
    first) is closed and driven in laps; an open route's reference line runs on straight for
    ``OPEN_EXTENSION`` metres beyond both of its ends, and the episode ends at ``route_end_s``.
    """

    def __init__(
        self,
        net_file: str | Path,
        edges: tuple[str, ...],
        checkpoints: tuple[tuple[float, float, int], ...] | None = None,
        *,
        from_edge: str = "",
        to_edge: str = "",
        name: str = "",
        scenario_file: str | Path | None = None,
        demand: tuple[Path, ...] = (),
        warmup: float = 0.0,
        additional: tuple[Path, ...] = (),
    ):
        net_file = Path(net_file)
        self.net = _read_net(net_file, Path(scenario_file) if scenario_file is not None else None)
        #: the scenario's own SUMO route files (empty: irlsim's spawner) and its warm-up [s]
        self.demand: tuple[Path, ...] = tuple(demand)
        self.warmup = float(warmup)
        #: SUMO additional files the network runs with (the scenario's signal programs)
        self.additional: tuple[Path, ...] = tuple(additional)
        self.net_file = net_file
        self.name = name or net_file.name.split(".")[0]
        #: the scenario file that names the route and the checkpoints (None: given directly)
        self.scenario_file = Path(scenario_file) if scenario_file is not None else None
        self._check_route_edges(tuple(edges), from_edge, to_edge)
        self.edges = route.resolve_route(self.net, tuple(edges), from_edge, to_edge)
        self.closed = route.is_closed(self.net, self.edges)
        self.layout = route.lane_layout(self.net, self.edges, self.closed)
        self.n_lanes, self.lane_width = self.layout.n_lanes, self.layout.width
        self.half_road = self.n_lanes * self.lane_width / 2  # [m] |d| of the road's outer edges
        #: per route edge, the SUMO lane nearest the middle of the road (locates edges and stop lines)
        self.middle_lane = {
            e: k for e, (k, _) in zip(self.edges, route.reference_lanes(self.layout), strict=True)
        }
        self.lane_shapes = (
            []
            if self.layout.varies
            else [
                route.lane_shape(self.net, self.edges, self.layout, k, self.closed)
                for k in range(self.n_lanes)
            ]
        )
        self.flat: bool = True  # set by _build_reference: False where the route comes back near itself
        centre = self._build_reference()
        if self.closed:
            self.lane_lengths = tuple(float(_closed_length(sh)) for sh in self.lane_shapes)
            self.route_begin_s, self.route_end_s = 0.0, math.inf
        else:
            self.lane_lengths = tuple(
                float(np.linalg.norm(np.diff(sh, axis=0), axis=1).sum()) for sh in self.lane_shapes
            )
            self.route_begin_s, self.route_end_s = self._open_ends(centre)
        if self.route_end_s - self.route_begin_s < MIN_OPEN_LENGTH:
            raise IrlsimError(
                f"route is {self.route_end_s - self.route_begin_s:.0f} m long, shorter than the "
                f"{MIN_OPEN_LENGTH:.0f} m an episode needs to start and drive: choose a longer route"
            )
        (self.stop_lines, self.signals), self.yield_points = self._stop_lines(), self._yield_points()
        self.exits = self._exits()
        self.checkpoints = self._checkpoints(checkpoints)
        if not self.checkpoints:
            raise IrlsimError("route has no checkpoint: give [[checkpoints]] in the scenario file")
        self._edge_cost = functools.lru_cache(maxsize=None)(self._edge_cost_uncached)
        # SUMO edge of each route-frame position of the middle lane, for Dijkstra queries
        self._edge_bounds = self._loop_edge_bounds()
        # the lowest and highest route lane at each reference vertex (all lanes on a constant road)
        self._lane_lo, self._lane_hi = route.lane_table(
            self.ref_s, self._edge_bounds, self.layout, self.closed
        )
        if checkpoints is not None:
            self.check_checkpoints(checkpoints)
        # the speed limit [m/s] at each reference vertex: its edge's (inside a junction, the lower of both)
        speeds = [float(self.net.getEdge(e).getSpeed()) for e in self.edges]
        self._vmax = route.edge_table(self.ref_s, self._edge_bounds, speeds, self.closed)
        self._vmax_min, self._vmax_max = float(self._vmax.min()), float(self._vmax.max())
        inner = (self.layout.n_lanes - 1) / 2 * self.layout.width  # [m] the innermost lane's offset
        self._vturn = turn_speeds(self._kappa, inner)  # [m/s] per reference vertex, inf where no turn
        self._turns = bool(np.isfinite(self._vturn).any())
        self._centrelines: dict[int, LaneCentreline] = {}

    # ------------------------------------------------------------------ construction
    def _where(self) -> str:
        """What names the route in a refusal: its scenario file, else its network."""
        return f"scenario {self.scenario_file}" if self.scenario_file else f"route on network {self.net_file}"

    def _check_route_edges(self, edges: tuple[str, ...], from_edge: str, to_edge: str) -> None:
        """One line, before any geometry, for a route edge the network lacks."""
        missing = [e for e in (*edges, from_edge, to_edge) if e and not self.net.hasEdge(e)]
        if missing:
            raise IrlsimError(
                f"{self._where()}: route edge '{missing[0]}' is not in the network {self.net_file}: fix "
                "[route] or give the network the route was written for"
            )

    def check_checkpoints(self, given: tuple[tuple[float, float, int], ...]) -> None:
        """Checkpoints (x, y, lane) as a scenario file gives them: each lane is -1 (any) or >= 0, each
        point lies on the road (within CHECKPOINT_MARGIN of the edges of the lanes that exist there, and
        of an open route's ends) and its lane exists there; else one line naming the first that does not,
        its scenario file and the fix. The road checks its own when it is built."""
        if not given:
            return
        xyl = np.array(given, dtype=np.float64).reshape(-1, 3)
        s, d = self.to_frenet(xyl[:, 0], xyl[:, 1])
        right, left = self.road_edges(s)
        lo, hi = self.lane_bounds(s)
        beyond = np.maximum(right - d, d - left)  # [m] > 0 outside the lanes
        outside = np.maximum(self.route_begin_s - s, s - self.route_end_s)  # [m] > 0 off an open route
        margin = f"more than {CHECKPOINT_MARGIN:g} m"
        for i, (x, y, lane) in enumerate(given):
            head = f"{self._where()}: checkpoint {i} (x={x:g}, y={y:g})"
            if not (math.isfinite(x) and math.isfinite(y)):
                raise IrlsimError(f"{head} is not a point: give finite x and y [m] on the route")
            if lane < -1:
                raise IrlsimError(f"{head} has lane {lane}: give a lane >= 0 (0: the rightmost) or -1 (any)")
            if outside[i] > CHECKPOINT_MARGIN:
                side = "before the route's start" if s[i] < self.route_begin_s else "beyond the route's end"
                raise IrlsimError(f"{head} lies {outside[i]:.1f} m {side} ({margin}): move it onto the route")
            if beyond[i] > CHECKPOINT_MARGIN:
                raise IrlsimError(
                    f"{head} lies {beyond[i]:.1f} m beyond the road's edge ({margin}, at s={s[i]:.1f} m "
                    "of the route): move it onto the route's lanes"
                )
            if lane >= 0 and not lo[i] <= lane <= hi[i]:
                raise IrlsimError(
                    f"{head} requires lane {lane}, but the route has lanes {lo[i]}..{hi[i]} there: give "
                    "one of them or -1 (any lane)"
                )

    def _open_ends(self, centre: np.ndarray) -> tuple[float, float]:
        """Route positions [m] of an open route's first and last point. A route that ends on its start's
        straight run-on (round a block and back towards its first edge) is not flat: globally each end
        lies on the other's run-on, which a projection cannot tell apart; its points are then projected by
        their progress."""
        ends = self._arc_to_s(np.array([0.0, _open_length(centre)]), centre)
        s_ends, _ = self.to_frenet(centre[[0, -1], 0], centre[[0, -1], 1], near=ends)
        if self.flat and (np.abs(s_ends - ends) > NEAR_WINDOW).any():
            self.flat = False
            s_ends, _ = self.to_frenet(centre[[0, -1], 0], centre[[0, -1], 1], near=ends)
        return float(s_ends[0]), float(s_ends[1])

    def _build_reference(self) -> np.ndarray:
        """The reference line, whether the route comes back near itself, and where each edge lies on it;
        returns the unsmoothed line it was built from."""
        shape = route.reference_shape(self.net, self.edges, self.layout, self.closed)
        centre = shape.points
        #: False where the route crosses itself or runs back near itself (alongside on the other
        #: carriageway, round a block and back): then a point is projected by progress (``to_frenet``'s
        #: ``near``). True on the oval and every shipped scenario: their projection is global, as always.
        gap = self.layout.n_lanes * self.layout.width + 0.5  # [m] the whole lane frame's width
        self.flat = crossing.self_crossing(centre, self.closed, gap) is None
        if not self.flat:
            crossing.check_same_level(shape, self.closed)
        if self.closed:
            ref = _smooth_closed(_resample_closed(centre, REF_STEP), SMOOTH_HALF_WINDOW)
        else:
            ref = _open_reference(centre)
        self._set_reference(ref)
        #: [E, 2] route position [m] where each route edge's piece of the reference starts and ends: the
        #: hints of the projections of points that belong to an edge
        self.edge_s = self._arc_to_s(shape.edge_arcs, centre)
        return centre

    def _checkpoints(self, given: tuple[tuple[float, float, int], ...] | None) -> tuple[Checkpoint, ...]:
        """The given checkpoints (x, y, lane), or those derived from the route (the mission points)."""
        points = route.mission_points(self.net, self.edges, self.closed, self.layout) if given is None else []
        if given is None and not points:  # a loop without a mission: one checkpoint where any lane will do
            x, y = self.net.getEdge(self.edges[0]).getLane(self.middle_lane[self.edges[0]]).getShape()[-1]
            points = [(float(x), float(y), -1, (), 0)]
        xyl = tuple((x, y, lane) for x, y, lane, _, _ in points) if given is None else given
        # a derived point lies at the end of its route edge; a given one may lie anywhere (no hint)
        hints = [float(self.edge_s[p[4], 1]) for p in points] if given is None else [math.nan] * len(xyl)
        out = []
        for i, (x, y, lane) in enumerate(xyl):
            s = float(self.to_frenet(np.array([x]), np.array([y]), near=hints[i])[0][0])
            out.append(Checkpoint(i, s, x, y, lane, points[i][3] if given is None else ()))  # type: ignore[index]
        return tuple(out)

    def _set_reference(self, ref: np.ndarray) -> None:
        self.ref_xy = ref  # [M, 2], closed (segment M-1 joins the last point to the first)
        seg = np.roll(ref, -1, axis=0) - ref
        self._seg_len = np.linalg.norm(seg, axis=1)  # [M]
        self._seg_dir = seg / self._seg_len[:, None]
        self._seg_normal = np.stack([-self._seg_dir[:, 1], self._seg_dir[:, 0]], axis=1)  # left normal
        # vertex normals (mean of the adjacent segments'); to_xy interpolates them, so the frame is
        # continuous and to_frenet can invert it exactly
        vn = self._seg_normal + np.roll(self._seg_normal, 1, axis=0)
        if not self.closed:  # an open route's two end vertices take their real segment's normal alone
            vn[0], vn[-1] = self._seg_normal[0], self._seg_normal[-2]
        self._vtx_normal = vn / np.linalg.norm(vn, axis=1)[:, None]
        self.ref_s = np.concatenate([[0.0], np.cumsum(self._seg_len)[:-1]])  # [M] s of each vertex
        self.lap_length = float(np.sum(self._seg_len))  # [m]
        self._seg_heading = atan2(self._seg_dir[:, 1], self._seg_dir[:, 0])  # the same on every CPU
        # curvature at vertices from heading change over the neighbouring half segments
        dh = wrap_angle(self._seg_heading - np.roll(self._seg_heading, 1))
        kappa_v = dh / (0.5 * (self._seg_len + np.roll(self._seg_len, 1)))
        # smooth over +-2.5 m (the reference itself is already smooth)
        w = max(1, int(round(2.5 / REF_STEP)))
        kern = np.ones(2 * w + 1) / (2 * w + 1)
        padded = np.concatenate([kappa_v[-w:], kappa_v, kappa_v[:w]])
        self._kappa = np.convolve(padded, kern, mode="valid")  # [M]
        # fast lookups for to_xy / heading (same values as the [M, 2] tables, one contiguous array per
        # component). The vertices are spaced ~REF_STEP apart, so a vertex index is a division plus a
        # few corrections (exactly what searchsorted would give), not a binary search.
        m = len(ref)
        # an open route's closing chord is one long segment: the spacing of the others makes the guess
        self._h = self.lap_length / m if self.closed else float(self.ref_s[-1]) / (m - 1)
        self._inv_h = 1.0 / self._h
        dev = np.abs(self.ref_s - np.arange(m) * self._h).max()
        self._n_fix = int(math.ceil(dev / self._h)) + 1  # correction passes each way
        self._ref_s_ext = np.concatenate([self.ref_s, [np.inf]])  # sentinel: never step past M - 1
        self._rx, self._ry = np.ascontiguousarray(ref[:, 0]), np.ascontiguousarray(ref[:, 1])
        self._ux = np.ascontiguousarray(self._seg_dir[:, 0])
        self._uy = np.ascontiguousarray(self._seg_dir[:, 1])
        nxt = np.roll(self._vtx_normal, -1, axis=0)
        self._n0x = np.ascontiguousarray(self._vtx_normal[:, 0])
        self._n0y = np.ascontiguousarray(self._vtx_normal[:, 1])
        self._n1x, self._n1y = np.ascontiguousarray(nxt[:, 0]), np.ascontiguousarray(nxt[:, 1])
        sh = self._seg_heading
        self._h_prev = wrap_angle(sh - np.roll(sh, 1))  # heading change from the previous segment
        self._h_next = wrap_angle(np.roll(sh, -1) - sh)  # heading change to the next segment
        # per-segment terms of the projection's quadratic (_project_smooth), and the segment tables
        # extended by the widest search window, so a window starting at any segment is a plain slice
        self._kx = (self._n1x - self._n0x) / self._seg_len  # d(normal)/dt along the segment [1/m]
        self._ky = (self._n1y - self._n0y) / self._seg_len
        u_x_n0 = self._ux * self._n0y - self._uy * self._n0x  # cross(u, n0)
        u_x_k = self._ux * self._ky - self._uy * self._kx  # cross(u, k)
        # one row per segment, so a projection gathers once: [M, 14]
        self._proj_tab = np.stack(
            [self._rx, self._ry, self._ux, self._uy, self._n0x, self._n0y, self._n1x, self._n1y]
            + [self._kx, self._ky, u_x_n0, u_x_k, self._seg_len, self.ref_s],
            axis=1,
        )
        wide = RASTER_TIERS[-1]
        self._win = {
            name: np.lib.stride_tricks.sliding_window_view(np.concatenate([a, a[:wide]]), wide)
            for name, a in (
                ("ax", self._rx),
                ("ay", self._ry),
                ("ux", self._ux),
                ("uy", self._uy),
                ("len", self._seg_len),
            )
        }
        self._build_raster()

    def _build_raster(self) -> None:
        """Grid of RASTER_CELL square cells around the reference: per cell, a window of segments (first
        segment, width) that holds the segment nearest to any point of the cell within RASTER_REACH.

        Built by splatting: each vertex's normal line is sampled every RASTER_CELL / 2 out to
        RASTER_REACH (+ one sample) on both sides, and every cell records the lowest and highest vertex
        index landing in it; then each cell takes the index range of the cells within ``r`` of it. A
        point q whose nearest segment j (from vertex j to j + 1) lies within RASTER_REACH is less than
        ``bound`` from a splat of vertex j: bound = the longest segment (where along j the foot is) +
        RASTER_REACH x |segment normal - vertex normal| (the splat runs along the vertex normal) + half a
        sample. With ``r = ceil(bound / cell)`` q's cell window holds j, so the window search finds the
        global nearest segment whenever the distance it finds is <= RASTER_REACH (_nearest_segment).
        """
        cell, reach = RASTER_CELL, RASTER_REACH
        m = len(self.ref_xy)
        step = cell / 2
        offs = np.arange(-reach - step, reach + 1.5 * step, step)  # [D]
        lo = self.ref_xy.min(axis=0) - reach - 2 * cell  # [2] grid origin
        nx, ny = (int(v) for v in np.ceil((self.ref_xy.max(axis=0) + reach + 2 * cell - lo) / cell))
        ix = np.floor((self._rx[:, None] + offs * self._n0x[:, None] - lo[0]) / cell).astype(np.int64)
        iy = np.floor((self._ry[:, None] + offs * self._n0y[:, None] - lo[1]) / cell).astype(np.int64)
        cid = (iy * nx + ix).ravel()  # [M * D]
        vid = np.repeat(np.arange(m), len(offs))
        cos_t = np.minimum(
            (self._seg_normal * self._vtx_normal).sum(-1),
            (np.roll(self._seg_normal, 1, axis=0) * self._vtx_normal).sum(-1),
        )
        if not self.closed:  # the chord's normals at an open route's two far ends bound nothing
            cos_t[[0, -1]] = 1.0
        max_angle = float(np.arccos(np.clip(cos_t, -1.0, 1.0)).max())
        longest = float(self._seg_len.max() if self.closed else self._seg_len[:-1].max())  # open: no chord
        bound = longest + reach * 2.0 * math.sin(max_angle / 2.0) + step / 2
        r = int(math.ceil(bound / cell))  # [cells] dilation radius
        # index ranges in two numberings: a cell near s = 0 sees vertices near 0 and near M - 1, which
        # are contiguous only when counted from half a lap on
        half = m // 2
        big = 4 * m
        ranges = []
        for v in (vid, (vid + half) % m):
            vmin = np.full(nx * ny, big)
            vmax = np.full(nx * ny, -big)
            np.minimum.at(vmin, cid, v)
            np.maximum.at(vmax, cid, v)
            vmin = _dilate(vmin.reshape(ny, nx), r, np.minimum, big).ravel()
            vmax = _dilate(vmax.reshape(ny, nx), r, np.maximum, -big).ravel()
            ranges.append((vmin, vmax))
        (a0, b0), (a1, b1) = ranges
        shifted = (b1 - a1) < (b0 - a0)
        first = np.where(shifted, (a1 - half) % m, a0)
        # the window: the segment before the first vertex (a foot exactly at a vertex ties the two
        # segments that meet there), then the segments starting at the vertices of the range
        width = np.where(shifted, b1 - a1, b0 - a0) + 1 + RASTER_PAD
        empty = (b0 < a0) | (width > RASTER_TIERS[-1])  # nothing within reach, or too wide: full search
        self._g_lo, self._g_nx, self._g_ny = lo, nx, ny
        self._g_first = np.where(empty, 0, (first - RASTER_PAD) % m).astype(np.int64)
        self._g_width = np.where(empty, 0, width).astype(np.int64)

    def _stop_lines(self) -> tuple[tuple[StopLine, ...], tuple[Signal, ...]]:
        stops, signals = junctions.junction_controls(self.net, self.edges, self.closed, self.middle_lane)
        lines = []
        for node, x, y, i in stops:  # at the end of route edge i
            s = float(self.to_frenet(np.array([x]), np.array([y]), near=self.edge_s[i, 1])[0][0])
            lines.append(StopLine(node, s, x, y))
        sig = []
        for node, x, y, tls, link, i, lane_links in signals:
            s = float(self.to_frenet(np.array([x]), np.array([y]), near=self.edge_s[i, 1])[0][0])
            sig.append(Signal(node, s, x, y, tls, link, self.edges[i], lane_links))
        return tuple(sorted(lines, key=lambda sl: sl.s)), tuple(sorted(sig, key=lambda g: g.s))

    def _yield_points(self) -> tuple[YieldPoint, ...]:
        """The minor links on the route's way through (yield and priority junctions), by s."""
        points = junctions.yield_points(self.net, self.edges, self.closed, self.middle_lane)
        out = []
        for n, x, y, i, lanes in points:  # at the end of route edge i
            s = float(self.to_frenet(np.array([x]), np.array([y]), near=self.edge_s[i, 1])[0][0])
            out.append(YieldPoint(n, s, x, y, lanes))
        return tuple(sorted(out, key=lambda p: p.s))

    def _exits(self) -> tuple[Exit, ...]:
        out = []
        for eid, pts, i in route.exit_shapes(self.net, self.edges, self.closed):
            xy = _resample_open(pts, 1.0)
            # the ramp leaves at the end of route edge i and runs on alongside the route at first
            along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
            s, d = self.to_frenet(xy[:, 0], xy[:, 1], near=self.edge_s[i, 1] + along)
            s0 = s[0]
            s_rel = (s - s0) % self.lap_length
            keep = s_rel <= RAMP_RANGE
            # keep the monotone part only (the ramp bends away; projection stays monotone near the loop)
            s_keep, d_keep = s_rel[keep], d[keep]
            mono = np.concatenate([[True], np.diff(s_keep) > 1e-6])
            mono = np.cumprod(mono).astype(bool)
            if d_keep[mono][-1] > d_keep[0]:  # a turn to the left: the lateral planner has no way there
                continue
            out.append(Exit(eid, float(s0), s0 + s_keep[mono], d_keep[mono]))
        return tuple(sorted(out, key=lambda e: e.s_start))

    def _loop_edge_bounds(self) -> list[tuple[str, float, float]]:
        """(edge id, s at its start, s at its end) of each loop edge on the middle lane."""
        out = []
        for i, eid in enumerate(self.edges):
            shape = np.asarray(self.net.getEdge(eid).getLane(self.middle_lane[eid]).getShape())
            s, _ = self.to_frenet(shape[[0, -1], 0], shape[[0, -1], 1], near=self.edge_s[i])
            out.append((eid, float(s[0]), float(s[1])))
        return out

    @property
    def edge_bounds(self) -> list[tuple[str, float, float]]:
        """(edge id, s at its start, s at its end) of each route edge on its middle lane."""
        return list(self._edge_bounds)

    def _arc_to_s(self, arc: np.ndarray, centre: np.ndarray) -> np.ndarray:
        """Route position [m] of arc length(s) ``arc`` along the unsmoothed line ``centre`` the reference
        was built from: the reference vertex resampled from that arc (its resampling is by arc length,
        the smoothing keeps vertex indices), so off only by the smoothing's local shift."""
        m = len(self.ref_s)
        if self.closed:
            length = _closed_length(centre)
            idx = np.asarray(arc) / (length / round(length / REF_STEP))
            return np.interp(idx, np.arange(m + 1), np.concatenate([self.ref_s, [self.lap_length]]))
        length = _open_length(centre)
        h = length / (max(2, int(math.ceil(length / REF_STEP)) + 1) - 1)  # as _resample_open spaces it
        idx = np.asarray(arc) / h + math.ceil(OPEN_EXTENSION / h)  # the run-on before it (_open_reference)
        return np.interp(idx, np.arange(m), self.ref_s)

    # ------------------------------------------------------------------ frame conversions
    def to_frenet(
        self, x: np.ndarray, y: np.ndarray, near: np.ndarray | float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """World xy [m] -> route frame (s in [0, lap_length), d) [m]; any shape, vectorised.

        Projects onto the reference segment nearest to the point (found in a small window of segments
        from a raster lookup, see :meth:`_build_raster`; points further than RASTER_REACH from the
        reference search all segments), then solves exactly for the foot whose interpolated normal
        passes through the point (:meth:`_project_smooth`), so ``to_xy`` inverts it.

        ``near`` (a route position [m], scalar or one per point, NaN = none) is where each point is known
        to lie along the route. On a route that comes back near itself (``flat`` False) where one xy lies
        on two passes, a point is projected onto the nearest segment within NEAR_WINDOW of ``near``
        (:meth:`_nearest_near`): the same xy gets each pass's own s. On a flat route it changes nothing.
        """
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        shape = x.shape
        qx, qy = x.ravel(), y.ravel()
        if near is None or self.flat:
            seg, t = self._nearest_segment(qx, qy)
        else:
            seg, t = self._nearest_near(qx, qy, np.broadcast_to(np.asarray(near, np.float64), shape).ravel())
        s, d = self._project_smooth(qx, qy, seg, t)
        return s.reshape(shape), d.reshape(shape)

    def project_near(self, x: np.ndarray, y: np.ndarray, near: float) -> tuple[np.ndarray, np.ndarray]:
        """World xy [m] [Q] -> route frame (s, d) projected onto the reference within NEAR_WINDOW of the
        route position ``near`` [m], on any route (``to_frenet``'s ``near`` applies only where ``flat`` is
        False); a point further than the road's half width + NEAR_SLACK from there is projected globally."""
        qx, qy = np.asarray(x, np.float64).ravel(), np.asarray(y, np.float64).ravel()
        seg, t = self._nearest_near(qx, qy, np.full(len(qx), float(near)))
        return self._project_smooth(qx, qy, seg, t)

    def _nearest_near(
        self, qx: np.ndarray, qy: np.ndarray, near: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The nearest reference segment to each point [Q] among those within NEAR_WINDOW of ``near`` [Q]
        (a [Q, W] search), and its clipped foot t [m]; the global nearest (:meth:`_nearest_segment`) for a
        point without a hint (NaN) or further than half_road + NEAR_SLACK from the window's segments."""
        m = len(self.ref_xy)
        half = int(math.ceil(NEAR_WINDOW / self._h))
        w = 2 * half + 1
        hinted = np.isfinite(near)
        sw = np.where(hinted, near, 0.0) % self.lap_length
        centre = self._segment_of_wrapped(np.where(sw >= self.lap_length, 0.0, sw))
        if self.closed:
            first = (centre - half) % m
        else:  # segments 0 .. M - 2 (the closing chord M - 1 is no road)
            first = np.clip(centre - half, 0, max(m - 1 - w, 0))
            w = min(w, m - 1)
        cols = (first[:, None] + np.arange(w)) % m  # [Q, W]
        seg, t, dist2 = self._nearest_of(
            qx, qy, self._rx[cols], self._ry[cols], self._ux[cols], self._uy[cols], self._seg_len[cols], first
        )
        reach = self.half_road + NEAR_SLACK
        rest = np.flatnonzero(~hinted | (dist2 > reach * reach))
        if len(rest):
            seg[rest], t[rest] = self._nearest_segment(qx[rest], qy[rest])
        return seg, t

    def _nearest_segment(self, qx: np.ndarray, qy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The reference segment nearest to each point [Q] and the clipped foot parameter t [m] on it:
        the same answer as a search over all segments (up to exact ties)."""
        n = len(qx)
        lo, nx, ny = self._g_lo, self._g_nx, self._g_ny
        fx = np.floor((qx - lo[0]) * (1.0 / RASTER_CELL))
        fy = np.floor((qy - lo[1]) * (1.0 / RASTER_CELL))
        inside = (fx >= 0) & (fx < nx) & (fy >= 0) & (fy < ny)  # False for NaN: the full search
        cid = np.where(inside, fy * nx + fx, 0).astype(np.int64)
        width = np.where(inside, self._g_width[cid], 0)
        first = self._g_first[cid]
        if n and width.min() > 0 and (width.max() <= RASTER_TIERS[0] or n <= 256):
            # the usual case (all near the road), or so few points that one window for all is cheapest
            seg, t, dist2 = self._search_window(qx, qy, first, max(int(width.max()), RASTER_TIERS[0]))
            todo = dist2 > RASTER_REACH * RASTER_REACH
        else:
            seg, t = np.zeros(n, dtype=np.int64), np.zeros(n)
            todo = np.ones(n, dtype=bool)
            narrower = 0
            for w in RASTER_TIERS:
                sel = np.flatnonzero((width > narrower) & (width <= w))
                narrower = w
                if len(sel):
                    j, tt, dist2 = self._search_window(qx[sel], qy[sel], first[sel], w)
                    seg[sel], t[sel] = j, tt
                    todo[sel] = dist2 > RASTER_REACH * RASTER_REACH
        # exact only when the nearest segment found is within the raster's reach (see _build_raster)
        rest = np.flatnonzero(todo)
        chunk = max(1, 2_000_000 // len(self.ref_xy))  # bounded memory: [chunk, M] arrays
        for i in range(0, len(rest), chunk):
            r = rest[i : i + chunk]
            seg[r], t[r] = self._search_all(qx[r], qy[r])
        return seg, t

    def _search_window(
        self, qx: np.ndarray, qy: np.ndarray, first: np.ndarray, w: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest of the w segments from ``first`` on (wrapped) per point: (segment, t, distance^2)."""
        win = self._win
        ax, ay = win["ax"][first, :w], win["ay"][first, :w]  # [Q, w]
        ux, uy, ln = win["ux"][first, :w], win["uy"][first, :w], win["len"][first, :w]
        return self._nearest_of(qx, qy, ax, ay, ux, uy, ln, first)

    def _search_all(self, qx: np.ndarray, qy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest of all segments per point (for points far from the reference): (segment, t)."""
        seg, t, _ = self._nearest_of(
            qx, qy, self._rx, self._ry, self._ux, self._uy, self._seg_len, np.zeros(len(qx), np.int64)
        )
        return seg, t

    def _nearest_of(
        self,
        qx: np.ndarray,
        qy: np.ndarray,
        ax: np.ndarray,
        ay: np.ndarray,
        ux: np.ndarray,
        uy: np.ndarray,
        ln: np.ndarray,
        first: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Argmin over candidate segments [Q, W] (or [W] for all points) of the distance from the points
        [Q] to the clipped foot a + u t: (segment = first + column, t, squared distance)."""
        relx, rely = qx[:, None] - ax, qy[:, None] - ay
        tt = np.minimum(np.maximum(relx * ux + rely * uy, 0.0), ln)
        dx = qx[:, None] - (ax + ux * tt)
        dy = qy[:, None] - (ay + uy * tt)
        dist2 = dx * dx + dy * dy
        if not self.closed:  # an open route's closing segment (last vertex -> first) is no road
            m = len(self.ref_xy)
            cols = first[:, None] + np.arange(dist2.shape[1])
            dist2 = np.where(cols % m == m - 1, np.inf, dist2)
        j = np.argmin(dist2, axis=1)
        rows = np.arange(len(qx))
        return (first + j) % len(self.ref_xy), tt[rows, j], dist2[rows, j]

    def _project_smooth(
        self, qx: np.ndarray, qy: np.ndarray, seg: np.ndarray, t_clip: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Exact inverse of :meth:`to_xy` near segment ``seg``: the foot t where q - P(t) is parallel to
        the interpolated normal N(t) (a quadratic in t), tried on seg, then its neighbours.

        With piecewise-constant normals, points in the wedge outside a vertex have no exact (s, d) and the
        round trip misses by |d| x (turn angle per vertex), ~1.5 cm on the outer lane's curves.
        """
        m = len(self.ref_xy)
        best_t = np.full(len(qx), np.nan)
        best_seg = seg.copy()
        rows = np.arange(len(qx))
        for off in (0, -1, 1):
            if off:  # the neighbours only where seg itself holds no root (rare: at vertices)
                rows = rows[np.isnan(best_t[rows])]
                if not len(rows):
                    break
            jj = (seg[rows] + off) % m
            tab = self._proj_tab[jj]
            rx, ry = qx[rows] - tab[:, 0], qy[rows] - tab[:, 1]
            n0x, n0y = tab[:, 4], tab[:, 5]
            c0 = rx * n0y - ry * n0x  # cross(r, n0)
            c1 = (rx * tab[:, 9] - ry * tab[:, 8]) - tab[:, 10]  # cross(r, k) - cross(u, n0)
            c2 = -tab[:, 11]
            # the root near -c0/c1 (numerically stable form; the other root is ~1/c2 away)
            sq = np.sqrt(np.maximum(c1 * c1 - 4.0 * c2 * c0, 0.0))
            with np.errstate(divide="ignore", invalid="ignore"):
                tt = -2.0 * c0 / (c1 + np.where(c1 >= 0, 1.0, -1.0) * sq)
            ok = (tt >= -1e-9) & (tt <= tab[:, 12] + 1e-9)
            best_t[rows[ok]] = tt[ok]
            best_seg[rows[ok]] = jj[ok]
        tab = self._proj_tab[best_seg]
        ln = tab[:, 12]
        best_t = np.where(np.isnan(best_t), t_clip, np.minimum(np.maximum(best_t, 0.0), ln))
        footx = tab[:, 0] + tab[:, 2] * best_t
        footy = tab[:, 1] + tab[:, 3] * best_t
        # the normal interpolated between vertex normals, as in to_xy
        f = best_t / ln
        g = 1.0 - f
        nx = tab[:, 4] * g + tab[:, 6] * f
        ny = tab[:, 5] * g + tab[:, 7] * f
        norm = np.sqrt(nx * nx + ny * ny)
        s = (tab[:, 13] + best_t) % self.lap_length
        return s, (qx - footx) * (nx / norm) + (qy - footy) * (ny / norm)

    def _segment_of_wrapped(self, sw: np.ndarray) -> np.ndarray:
        """``clip(searchsorted(ref_s, sw, 'right') - 1, 0, M - 1)`` for sw in [0, lap_length], by index
        arithmetic: a guess from the mean vertex spacing, then ``_n_fix`` exact corrections each way."""
        m = len(self.ref_s)
        sw = np.asarray(sw)
        i = np.minimum((sw * self._inv_h).astype(np.int64), m - 1)  # sw >= 0: truncation is floor
        ext = self._ref_s_ext
        for _ in range(self._n_fix):
            i = i - (ext[i] > sw)
        i = np.maximum(i, 0)
        for _ in range(self._n_fix):
            i = i + (ext[i + 1] <= sw)
        return i

    def to_xy(self, s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Route frame (s, d) [m] -> world xy [m]; s may be unwrapped (any real); vectorised."""
        s = np.asarray(s, dtype=np.float64)
        d = np.asarray(d, dtype=np.float64)
        shape = np.broadcast_shapes(s.shape, d.shape)
        if s.ndim == 0 or d.ndim == 0:  # array arithmetic throughout (0-d arrays out, as before)
            s, d = (np.broadcast_to(a, shape).reshape(-1) for a in (s, d))
        sw = s % self.lap_length
        # a tiny negative s wraps to exactly lap_length in floating point: that is s = 0 (found by the
        # property test of the round trip; t = lap_length on segment 0 put the point 2 km away)
        sw = np.where(sw >= self.lap_length, 0.0, sw)
        seg = self._segment_of_wrapped(sw)
        t = sw - self.ref_s[seg]
        # the unit left normal interpolated linearly between the vertex normals (per component)
        f = t / self._seg_len[seg]
        g = 1.0 - f
        nx = self._n0x[seg] * g + self._n1x[seg] * f
        ny = self._n0y[seg] * g + self._n1y[seg] * f
        norm = np.sqrt(nx * nx + ny * ny)
        x = (self._rx[seg] + self._ux[seg] * t) + nx / norm * d
        y = (self._ry[seg] + self._uy[seg] * t) + ny / norm * d
        return x.reshape(shape), y.reshape(shape)

    def heading(self, s: np.ndarray) -> np.ndarray:
        """Reference heading [rad, ENU] at s, interpolated between segment headings (smooth in s)."""
        s = np.asarray(s, dtype=np.float64)
        shape = s.shape
        sw = s.reshape(-1) % self.lap_length  # array arithmetic throughout (0-d array out, as before)
        sw = np.where(sw >= self.lap_length, 0.0, sw)  # a tiny negative s wraps to lap_length (see to_xy)
        seg = self._segment_of_wrapped(sw)
        frac = (sw - self.ref_s[seg]) / self._seg_len[seg]
        # blend around the segment's mid point so the heading is continuous: towards the previous
        # segment's heading before it, towards the next one's after it
        first = frac < 0.5
        slope = np.where(first, self._h_prev[seg], self._h_next[seg])
        out = wrap_angle(self._seg_heading[seg] + slope * (frac - 0.5))
        return out.reshape(shape) if shape else out[0]  # a numpy scalar for a scalar s, as before

    def curvature(self, s: np.ndarray) -> np.ndarray:
        """Signed curvature of the reference [1/m] (positive = left turn), smoothed over 5 m."""
        sw = np.asarray(s, dtype=np.float64) % self.lap_length
        pos = sw / REF_STEP
        m = len(self._kappa)
        i0 = np.floor(pos).astype(np.int64) % m
        f = pos - np.floor(pos)
        return self._kappa[i0] * (1 - f) + self._kappa[(i0 + 1) % m] * f

    # ------------------------------------------------------------------ lanes
    def lane_center(self, lane: np.ndarray | int) -> np.ndarray:
        """Lateral offset [m] of lane centre(s)."""
        return (np.asarray(lane, dtype=np.float64) - (self.n_lanes - 1) / 2) * self.lane_width

    @property
    def lane_centres(self) -> np.ndarray:
        """[n_lanes] lateral offsets [m] of every lane's centre, rightmost first."""
        return (np.arange(self.n_lanes) - (self.n_lanes - 1) / 2) * self.lane_width

    def lane_of_d(self, d: np.ndarray) -> np.ndarray:
        """Lane index (int8) of lateral offset(s) d; -1 beyond the road's edges."""
        d = np.asarray(d, dtype=np.float64)
        lane = np.clip(np.floor(d / self.lane_width + self.n_lanes / 2), 0, self.n_lanes - 1).astype(np.int8)
        return np.where(np.abs(d) <= self.half_road, lane, -1).astype(np.int8)

    @property
    def lanes_vary(self) -> bool:
        """True when lanes are added or dropped along the route (see :meth:`lane_bounds`)."""
        return self.layout.varies

    def lane_bounds(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lowest, highest) lane that exists at route position(s) ``s`` (wrapped), int arrays."""
        sw = np.asarray(s, dtype=np.float64).reshape(-1) % self.lap_length
        seg = self._segment_of_wrapped(np.where(sw >= self.lap_length, 0.0, sw))
        shape = np.shape(s)
        return self._lane_lo[seg].reshape(shape), self._lane_hi[seg].reshape(shape)

    def road_edges(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(right, left) edge [m] of the lanes that exist at route position(s) ``s``."""
        lo, hi = self.lane_bounds(s)
        half_w = self.lane_width / 2
        return self.lane_center(lo) - half_w, self.lane_center(hi) + half_w

    def lane_geometry(
        self, d: np.ndarray, lanes: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | float]:
        """For lateral offsets ``d`` [J, T]: (distance [m] to the nearest lane centre, the road's right
        edge [J, T], its left edge) over every lane, or with ``lanes`` ((lowest, highest) lane [T] at each
        step) over the lanes that exist at each step."""
        centres = self.lane_centres
        if lanes is None:
            dev = np.abs(d - centres[0])
            for c in centres[1:]:  # a handful of lanes
                dev = np.minimum(dev, np.abs(d - c))
            return dev, np.full(d.shape, -self.half_road), self.half_road
        lo, hi = lanes
        dev = np.full(d.shape, np.inf)
        for k, c in enumerate(centres):
            dev = np.minimum(dev, np.where((lo <= k) & (k <= hi), np.abs(d - c), np.inf))
        right = np.broadcast_to(self.lane_center(lo) - self.lane_width / 2, d.shape).copy()
        return dev, right, self.lane_center(hi) + self.lane_width / 2

    @property
    def max_speed_limit(self) -> float:
        """[m/s] the highest speed limit on the route (the oval: 27.78, 100 km/h)."""
        return self._vmax_max

    def speed_limit_over(self, s0: float, s1: float) -> float:
        """The lowest speed limit [m/s] of the route from ``s0`` to ``s1`` (unwrapped, s1 >= s0)."""
        if self._vmax_min >= self._vmax_max:  # one limit all along (the oval): no look-up
            return self._vmax_min
        m = len(self.ref_s)
        a = int(self._segment_of_wrapped(np.array([s0 % self.lap_length]))[0])
        n = int(min(np.ceil((s1 - s0) / self._h) + 2, m))
        return float(self._vmax[(a + np.arange(n)) % m].min())

    def turn_speed_over(self, s0: float, s1: float) -> float:
        """The lowest turn speed [m/s] of the route from ``s0`` to ``s1`` (unwrapped, s1 >= s0): a turn
        at a junction taken at TURN_LAT_ACC; inf where there is none (the oval, a motorway)."""
        if not self._turns:
            return math.inf
        m = len(self.ref_s)
        a = int(self._segment_of_wrapped(np.array([s0 % self.lap_length]))[0])
        n = int(min(np.ceil((s1 - s0) / self._h) + 2, m))
        return float(self._vturn[(a + np.arange(n)) % m].min())

    def required_lane(self, checkpoint: int, d: float) -> int:
        """The lane checkpoint ``checkpoint`` requires of an ego at offset ``d``: its lane; where several
        lanes meet it, the one of them nearest ``d``; for an any-lane checkpoint (lane -1, an open route's
        end) the lane at ``d``, so staying in one's lane meets it."""
        cp = self.checkpoints[checkpoint]
        here = max(int(self.lane_of_d(np.array(d))), 0)
        if cp.lanes:
            return int(min(cp.lanes, key=lambda k: (abs(k - here), k)))
        return int(cp.lane) if cp.lane >= 0 else here

    def lane_centreline(self, lane: int) -> LaneCentreline:
        """The closed centreline of loop lane ``lane`` (0 outer .. 2 inner) with its own arc length.

        Built from the route frame, so its points have (s, d) = (ref_s, lane_center(lane)) exactly; on
        the half circles the outer lane is longer than the middle one, and the middle one longer than the
        inner one, by pi x LANE_WIDTH each. (``lane_lengths`` are SUMO's own lane shapes instead.)
        """
        if lane not in range(self.n_lanes):
            raise ValueError(f"lane must be 0..{self.n_lanes - 1}, got {lane}")
        if lane not in self._centrelines:
            x, y = self.to_xy(self.ref_s, np.full(len(self.ref_s), float(self.lane_center(lane))))
            seg = np.hypot(np.roll(x, -1) - x, np.roll(y, -1) - y)  # [M] closed
            s = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
            self._centrelines[lane] = LaneCentreline(
                lane, x, y, s, self.ref_s.copy(), float(seg.sum()), self.lap_length
            )
        return self._centrelines[lane]

    # ------------------------------------------------------------------ route distance (Dijkstra)
    def _edge_cost_uncached(self, from_edge: str, to_edge: str) -> float:
        path, cost = self.net.getShortestPath(self.net.getEdge(from_edge), self.net.getEdge(to_edge))
        return math.inf if path is None else float(cost)

    def route_distance(self, from_edge: str, from_pos: float, to_edge: str, to_pos: float) -> float:
        """Road distance [m] from (edge, pos) to (edge, pos) by Dijkstra on the SUMO network, cached.

        Equals ``sumolib`` ``net.getShortestPath(..., fromPos, toPos)`` (edge lengths plus the shortest
        internal lane of each junction crossed) and goes once round the loop when the target lies behind
        the start on the same edge. There sumolib 1.28 leaves out the internal lane of the first
        junction (its looping search starts on the next edge without it); this method counts it.
        ``inf`` when the target is unreachable (from an exit ramp). Edge-to-edge costs are cached;
        positions are applied in closed form.
        """
        if from_edge == to_edge and to_pos >= from_pos:
            return float(to_pos - from_pos)
        if from_edge == to_edge:
            # once round: leave this edge, come back to it
            edge = self.net.getEdge(from_edge)
            best = min(
                (
                    self._edge_cost(n.getID(), to_edge) + self.net.getInternalPath(conns)[1]
                    for n, conns in edge.getOutgoing().items()
                    if n.getID() in self.edges
                ),
                default=math.inf,
            )
            return float(edge.getLength() - from_pos + best - self.net.getEdge(to_edge).getLength() + to_pos)
        cost = self._edge_cost(from_edge, to_edge)
        if math.isinf(cost):
            return math.inf
        # sumolib's cost counts both end edges whole; cut to the positions
        return float(cost - from_pos - (self.net.getEdge(to_edge).getLength() - to_pos))

    def remaining_distance(self, s: np.ndarray, s_target: float) -> np.ndarray:
        """Route distance [m] from loop position(s) s to the route target at s_target, along the loop.

        The loop offers a single path, so Dijkstra reduces to ``(s_target - s) mod lap_length`` in the
        route frame. tests/road/test_geometry.py checks it against :meth:`route_distance` (sumolib's
        Dijkstra) for points on all three lanes: they agree within the ~1.1 m per lap by which the
        smoothed reference is shorter than SUMO's middle lane (edges + junction lanes), plus 0.4 m.
        Vectorised, for the planner.
        """
        return (s_target - np.asarray(s, dtype=np.float64)) % self.lap_length

    # ------------------------------------------------------------------ summaries
    def drivable_right_edge(self, s: np.ndarray) -> np.ndarray:
        """Lowest drivable d [m] at s: the loop's right edge, or the far edge of an exit ramp beside it."""
        s = np.asarray(s, dtype=np.float64)
        edge = self.road_edges(s)[0] if self.lanes_vary else np.full(s.shape, -self.half_road)
        for ex in self.exits:
            ds = (s - ex.s_start) % self.lap_length + ex.s_start
            rd = ex.d_at(ds)
            edge = np.where(np.isfinite(rd), np.minimum(edge, rd - self.lane_width / 2), edge)
        return edge

    def describe(self) -> dict[str, object]:
        return {
            "route": f"{len(self.edges)} edges, {'a loop' if self.closed else 'open'}",
            "lanes": f"{self.n_lanes} x {self.lane_width:.2f} m",
            "lap_length_m": round(self.lap_length, 2),
            "lane_lengths_m": [round(v, 2) for v in self.lane_lengths],
            "stop_lines_s_m": [round(sl.s, 2) for sl in self.stop_lines],
            "signals_s_m": [round(g.s, 2) for g in self.signals],
            **({"yield_points_s_m": [round(p.s, 2) for p in self.yield_points]} if self.yield_points else {}),
            "exits_s_m": [round(e.s_start, 2) for e in self.exits],
            "checkpoints": [(round(c.s, 2), list(c.lanes) if c.lanes else c.lane) for c in self.checkpoints],
        }


def turn_speeds(kappa: np.ndarray, inner: float = 0.0) -> np.ndarray:
    """[M] [m/s] the speed of a turn at each reference vertex from its curvature ``kappa`` [M] [1/m] on the
    lane ``inner`` metres inside the reference (the innermost: the reference follows a junction's own
    lanes, whose inner one turns tighter): TURN_LAT_ACC of lateral acceleration where that lane's radius
    is below TURN_RADIUS, inf elsewhere."""
    k = np.abs(kappa)
    k = k / np.maximum(1.0 - k * inner, 0.2)  # the inner lane's curvature
    return np.where(k > 1.0 / TURN_RADIUS, np.sqrt(TURN_LAT_ACC / np.maximum(k, 1e-9)), np.inf)


def _dilate(a: np.ndarray, r: int, op: np.ufunc, fill: int) -> np.ndarray:
    """``op`` (np.minimum or np.maximum) of a 2-D array over the (2r + 1) x (2r + 1) cells around each
    cell (separable: rows, then columns); cells outside the array count as ``fill``."""
    for axis in (0, 1):
        b = np.moveaxis(a, axis, 0)
        padded = np.full((b.shape[0] + 2 * r,) + b.shape[1:], fill, dtype=a.dtype)
        padded[r : r + b.shape[0]] = b
        out = padded[: b.shape[0]].copy()
        for k in range(1, 2 * r + 1):
            op(out, padded[k : k + b.shape[0]], out=out)
        a = np.moveaxis(out, 0, axis)
    return np.ascontiguousarray(a)


def _smooth_closed(pts: np.ndarray, half_window: float) -> np.ndarray:
    """Moving average of a closed, evenly sampled polyline over +-half_window metres (narrower in tight
    turns: :func:`_average`)."""
    step = float(np.linalg.norm(pts[1] - pts[0]))
    w = max(1, int(round(half_window / step)))
    return _average(np.concatenate([pts[-w:], pts, pts[:w]]), w, step)


def _average(padded: np.ndarray, w: int, step: float) -> np.ndarray:
    """[N, 2] the moving average over +-``w`` vertices of ``padded`` ([N + 2w, 2], evenly sampled ``step``
    apart) where the line turns gently, and over a narrower window +-k where it turns tightly: k the
    vertices of sqrt(6 SMOOTH_SHIFT R), R the radius the line turns on over +-w vertices (its heading
    change between the chords back and ahead), the least within +-w, so the window narrows before a turn
    as well. Vertices that keep +-w keep their bytes."""
    kern = np.ones(2 * w + 1) / (2 * w + 1)
    smoothed = np.stack([np.convolve(padded[:, j], kern, mode="valid") for j in range(2)], axis=1)
    a = padded[w:-w] - padded[: -2 * w]
    b = padded[2 * w :] - padded[w:-w]
    turn = np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(axis=1)))  # [N] rad
    radius = 2 * w * step / np.maximum(turn, 1e-12)
    k = np.clip(np.floor(np.sqrt(6.0 * SMOOTH_SHIFT * radius) / step), 1, w).astype(np.int64)
    if (k >= w).all():
        return smoothed
    k = _dilate(k[None, :], w, np.minimum, w)[0]
    tight = np.flatnonzero(k < w)
    csum = np.concatenate([np.zeros((1, 2)), np.cumsum(padded, axis=0)])
    mid, kk = tight + w, k[tight][:, None]
    out = smoothed.copy()
    out[tight] = (csum[mid + kk[:, 0] + 1] - csum[mid - kk[:, 0]]) / (2 * kk + 1)
    return out


def _open_length(pts: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def _closed_length(pts: np.ndarray) -> float:
    return float(np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1).sum())


def _resample_open(pts: np.ndarray, step: float) -> np.ndarray:
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(2, int(math.ceil(s[-1] / step)) + 1)
    si = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(si, s, pts[:, 0]), np.interp(si, s, pts[:, 1])], axis=1)


def _resample_closed(pts: np.ndarray, step: float) -> np.ndarray:
    closed = np.vstack([pts, pts[:1]])
    seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n = int(round(s[-1] / step))
    si = np.arange(n) * (s[-1] / n)
    return np.stack([np.interp(si, s, closed[:, 0]), np.interp(si, s, closed[:, 1])], axis=1)


def _resample_count(pts: np.ndarray, m: int, closed: bool) -> np.ndarray:
    """``m`` points evenly spaced by arc length along a polyline (closed: around the loop)."""
    p = np.vstack([pts, pts[:1]]) if closed else pts
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    si = np.arange(m) * (s[-1] / m) if closed else np.linspace(0.0, s[-1], m)
    return np.stack([np.interp(si, s, p[:, 0]), np.interp(si, s, p[:, 1])], axis=1)


def _open_reference(centre: np.ndarray) -> np.ndarray:
    """An open route's reference: the centre resampled every ~REF_STEP, run on straight for
    OPEN_EXTENSION metres beyond both ends, then smoothed as a loop's is (the straight runs absorb the
    smoothing window at the ends)."""
    core = _resample_open(centre, REF_STEP)
    h = float(np.linalg.norm(core[1] - core[0]))
    w = max(1, int(round(SMOOTH_HALF_WINDOW / h)))
    k = int(math.ceil(OPEN_EXTENSION / h)) + w
    u0 = (core[0] - core[1]) / np.linalg.norm(core[0] - core[1])
    u1 = (core[-1] - core[-2]) / np.linalg.norm(core[-1] - core[-2])
    steps = np.arange(1, k + 1)[:, None] * h
    ext = np.vstack([(core[0] + steps * u0)[::-1], core, core[-1] + steps * u1])
    return _average(ext, w, h)


#: the networks read in this process, the most recent last: (network, its mtime and size) -> sumolib net.
#: Roads on one network share it (read only): a recording's egos each drive a route of their own, and
#: reading a city's network took 0.2 s a route
_NETS: dict[tuple[str, int, int], Any] = {}
_MAX_NETS = 2


def _read_net(net_file: Path, scenario_file: Path | None = None) -> Any:
    """The sumolib network (internal lanes included), read once while the file is unchanged; one-line
    errors for a missing, malformed or left-hand network."""
    if net_file.is_file():
        st = net_file.stat()
        key = (str(net_file.resolve()), st.st_mtime_ns, st.st_size)
        net = _NETS.pop(key, None)
        if net is None:
            net = _parse_net(net_file, scenario_file)
        _NETS[key] = net
        while len(_NETS) > _MAX_NETS:
            del _NETS[next(iter(_NETS))]
        return net
    return _parse_net(net_file, scenario_file)


def _parse_net(net_file: Path, scenario_file: Path | None) -> Any:
    try:
        import sumolib  # lazy: sumolib parses XML with its own machinery, only needed here
    except ImportError:
        raise IrlsimError("sumolib is not installed: run 'make setup'") from None
    if not net_file.is_file():
        raise IrlsimError(f"network {net_file} not found: run 'irlsim net' (or 'make net') to build it")
    try:
        net = sumolib.net.readNet(str(net_file), withInternal=True)
    except Exception as e:  # sumolib raises bare SAX / attribute errors on malformed XML
        from irlsim.road.scenario import network_advice  # the fix that fits how the network was made

        fix = network_advice(net_file, scenario_file)
        raise IrlsimError(f"network {net_file} is malformed ({type(e).__name__}): {fix}") from None
    if _lefthand(net_file):
        raise IrlsimError(f"network {net_file} drives on the left: left-hand traffic is not supported")
    return net


def _lefthand(net_file: Path) -> bool:
    """True when the network says it drives on the left (``<net ... lefthand="true">``)."""
    with open(net_file, "rb") as f:
        head = f.read(4096)
    return b'lefthand="true"' in head


#: the roads loaded in this process, the most recent last: (network, its mtime, the scenario) -> Road
_ROADS: dict[tuple[str, float, str], Road] = {}
_MAX_ROADS = 8


def _road_of(net_file: Path, scn: Scenario) -> Road:
    """The Road of scenario ``scn`` on ``net_file``, made once while the network is unchanged."""
    key = (str(net_file.resolve()), net_file.stat().st_mtime, repr(scn))
    road = _ROADS.pop(key, None)
    if road is None:
        road = Road(
            key[0],
            scn.edges,
            scn.checkpoints or None,
            from_edge=scn.from_edge,
            to_edge=scn.to_edge,
            name=scn.name,
            scenario_file=scn.path.resolve(),
            demand=scn.demand,
            warmup=scn.warmup,
            additional=scn.additional,
        )
    _ROADS[key] = road
    while len(_ROADS) > _MAX_ROADS:
        del _ROADS[next(iter(_ROADS))]
    return road


def load_road(
    net_file: str | Path | None = None, build: bool = True, scenario: str | Path | Scenario | None = None
) -> Road:
    """The :class:`Road` of a scenario (a loaded :class:`irlsim.road.scenario.Scenario`, which is not
    read again, or a shipped name or a path; default the default scenario, the oval): the route and
    checkpoints its file names, on its network or on ``net_file``; builds the scenario's network first
    when it is missing or stale (if ``build`` and no ``net_file``)."""
    from irlsim.road.scenario import DEFAULT_SCENARIO, build_command, load_scenario

    spec = DEFAULT_SCENARIO if scenario is None else scenario
    scn = load_scenario(spec, build=build and net_file is None)
    p = scn.net_file if net_file is None else Path(net_file)
    if not p.is_file():
        raise IrlsimError(f"network {p} not found: run {build_command(spec)} to build it")
    return _road_of(p, scn)
