"""Road geometry of the oval in the route frame, read from the SUMO network with sumolib.

The route frame: ``s`` is arc length [m] along the reference line (the centreline of the middle loop
lane, which is the drawn line of the one-way 3-lane loop), ``d`` the signed lateral offset [m],
positive to the left (towards the inner lane). Lane ``k`` has its centre at ``d = (k - 1) * LANE_WIDTH``.
Yaw is ENU: radians, 0 = east, counter-clockwise. SUMO angles are degrees, 0 = north, clockwise.

The reference line is the concatenation of the middle lane's shapes, internal (junction) lanes included,
resampled every ``REF_STEP`` metres. Projection xy -> (s, d) is onto that polyline; (s, d) -> xy uses the
normal interpolated between vertex normals, and the projection inverts exactly that, so a round trip is
exact (float precision).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from irlsim.errors import IrlsimError

LANE_WIDTH = 3.2  # [m]
N_LANES = 3
HALF_ROAD = N_LANES * LANE_WIDTH / 2  # [m] |d| of the loop's road edges
REF_STEP = 0.5  # [m] reference line resampling
LOOP_EDGES = ("A_S1", "S1_X1", "X1_B", "B_S2", "S2_X2", "X2_A")
EXIT_EDGES = ("exit1", "exit2")
ENTRY_EDGES = ("entry1", "entry2")
#: checkpoints: (world x [m], world y [m], required lane); alternate inner (2) and outer (0)
CHECKPOINTS_XY = ((250.0, 0.0, 2), (850.0, 150.0, 0), (450.0, 300.0, 2), (-150.0, 150.0, 0))
SMOOTH_HALF_WINDOW = 8.0  # [m] the reference is smoothed over +-8 m: SUMO's 6-degree shape kinks vanish
RAMP_RANGE = 160.0  # [m] of an exit ramp kept in the route frame, from where it leaves lane 0


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap angles [rad] into [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def yaw_to_sumo_angle(yaw: float) -> float:
    """ENU yaw [rad] -> SUMO angle [deg, 0 = north, clockwise]."""
    return (90.0 - math.degrees(yaw)) % 360.0


def sumo_angle_to_yaw(angle: float) -> float:
    return float(wrap_angle(math.radians(90.0 - angle)))


@dataclass(frozen=True)
class Checkpoint:
    index: int
    s: float  # [m] route frame
    x: float  # [m]
    y: float  # [m]
    lane: int  # required lane


@dataclass(frozen=True)
class StopLine:
    node: str  # the allway_stop node
    s: float  # [m] route frame position of the line (end of the incoming lanes)
    x: float  # [m] world position of the line on the middle lane
    y: float


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


class Road:
    """Geometry and topology of the oval, from a ``.net.xml``. Build with :func:`load_road`."""

    def __init__(self, net_file: str | Path):
        import sumolib

        net_file = Path(net_file)
        if not net_file.is_file():
            raise IrlsimError(f"network {net_file} not found: run 'irlsim net' (or 'make net') to build it")
        try:
            self.net = sumolib.net.readNet(str(net_file), withInternal=True)
        except Exception as e:  # sumolib raises bare SAX / attribute errors on malformed XML
            raise IrlsimError(
                f"network {net_file} is malformed ({type(e).__name__}): delete it and run 'irlsim net'"
            ) from None
        self.net_file = net_file
        missing = [e for e in LOOP_EDGES + EXIT_EDGES if not self.net.hasEdge(e)]
        if missing:
            raise IrlsimError(
                f"network {net_file} lacks edge '{missing[0]}': it is not the oval course; rebuild it "
                "with 'irlsim net'"
            )
        self.lane_shapes = [self._loop_lane_shape(k) for k in range(N_LANES)]
        ref = _smooth_closed(_resample_closed(self.lane_shapes[1], REF_STEP), SMOOTH_HALF_WINDOW)
        self._set_reference(ref)
        self.lane_lengths = tuple(float(_closed_length(sh)) for sh in self.lane_shapes)
        self.stop_lines = self._stop_lines()
        self.exits = self._exits()
        self.checkpoints = tuple(
            Checkpoint(i, float(self.to_frenet(np.array([x]), np.array([y]))[0][0]), x, y, lane)
            for i, (x, y, lane) in enumerate(CHECKPOINTS_XY)
        )
        self._edge_cost = functools.lru_cache(maxsize=None)(self._edge_cost_uncached)
        # SUMO edge of each route-frame position of the middle lane, for Dijkstra queries
        self._edge_bounds = self._loop_edge_bounds()

    # ------------------------------------------------------------------ construction
    def _loop_lane_shape(self, k: int) -> np.ndarray:
        """Closed centreline of loop lane k (internal lanes included): [P, 2], first point not repeated."""
        pts: list[tuple[float, float]] = []
        for i, eid in enumerate(LOOP_EDGES):
            lane = self.net.getEdge(eid).getLane(k)
            pts.extend(lane.getShape())
            nxt = LOOP_EDGES[(i + 1) % len(LOOP_EDGES)]
            via = [
                c for c in lane.getOutgoing() if c.getTo().getID() == nxt and c.getToLane().getIndex() == k
            ]
            if not via:
                raise IrlsimError(
                    f"network: lane {eid}_{k} does not continue on {nxt}; rebuild with 'irlsim net'"
                )
            via_id = via[0].getViaLaneID()
            if via_id:
                pts.extend(self.net.getLane(via_id).getShape())
        arr = np.asarray(pts, dtype=np.float64)
        keep = np.ones(len(arr), bool)
        keep[1:] = np.linalg.norm(np.diff(arr, axis=0), axis=1) > 1e-6
        arr = arr[keep]
        if np.linalg.norm(arr[0] - arr[-1]) < 1e-6:
            arr = arr[:-1]
        return arr

    def _set_reference(self, ref: np.ndarray) -> None:
        self.ref_xy = ref  # [M, 2], closed (segment M-1 joins the last point to the first)
        seg = np.roll(ref, -1, axis=0) - ref
        self._seg_len = np.linalg.norm(seg, axis=1)  # [M]
        self._seg_dir = seg / self._seg_len[:, None]
        self._seg_normal = np.stack([-self._seg_dir[:, 1], self._seg_dir[:, 0]], axis=1)  # left normal
        # vertex normals (mean of the adjacent segments'); to_xy interpolates them, so the frame is
        # continuous and to_frenet can invert it exactly
        vn = self._seg_normal + np.roll(self._seg_normal, 1, axis=0)
        self._vtx_normal = vn / np.linalg.norm(vn, axis=1)[:, None]
        self.ref_s = np.concatenate([[0.0], np.cumsum(self._seg_len)[:-1]])  # [M] s of each vertex
        self.lap_length = float(np.sum(self._seg_len))  # [m]
        self._seg_heading = np.arctan2(self._seg_dir[:, 1], self._seg_dir[:, 0])
        # curvature at vertices from heading change over the neighbouring half segments
        dh = wrap_angle(self._seg_heading - np.roll(self._seg_heading, 1))
        kappa_v = dh / (0.5 * (self._seg_len + np.roll(self._seg_len, 1)))
        # smooth over +-2.5 m (the reference itself is already smooth)
        w = max(1, int(round(2.5 / REF_STEP)))
        kern = np.ones(2 * w + 1) / (2 * w + 1)
        padded = np.concatenate([kappa_v[-w:], kappa_v, kappa_v[:w]])
        self._kappa = np.convolve(padded, kern, mode="valid")  # [M]
        # coarse index for projection: every COARSE-th vertex
        self._coarse = 20
        self._coarse_xy = ref[:: self._coarse]
        # fast lookups for to_xy / heading (same values as the [M, 2] tables, one contiguous array per
        # component). The vertices are spaced ~REF_STEP apart, so a vertex index is a division plus a
        # few corrections (exactly what searchsorted would give), not a binary search.
        m = len(ref)
        self._h = self.lap_length / m
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

    def _stop_lines(self) -> tuple[StopLine, ...]:
        out = []
        for node in self.net.getNodes():
            if node.getType() != "allway_stop":
                continue
            inc = [e for e in node.getIncoming() if e.getID() in LOOP_EDGES]
            if not inc:
                continue
            x, y = inc[0].getLane(1).getShape()[-1]
            s = float(self.to_frenet(np.array([x]), np.array([y]))[0][0])
            out.append(StopLine(node.getID(), s, float(x), float(y)))
        if len(out) != 2:
            raise IrlsimError(
                f"network has {len(out)} allway_stop lines, expected 2: rebuild with 'irlsim net'"
            )
        return tuple(sorted(out, key=lambda sl: sl.s))

    def _exits(self) -> tuple[Exit, ...]:
        out = []
        for eid in EXIT_EDGES:
            edge = self.net.getEdge(eid)
            pts: list[tuple[float, float]] = []
            # the internal lane from lane 0 into the ramp, then the ramp itself
            inc = [
                c
                for e in edge.getFromNode().getIncoming()
                if e.getID() in LOOP_EDGES
                for c in e.getLane(0).getOutgoing()
                if c.getTo().getID() == eid
            ]
            if not inc:
                raise IrlsimError(
                    f"network: exit {eid} is not reachable from lane 0; rebuild with 'irlsim net'"
                )
            via = inc[0].getViaLaneID()
            if via:
                pts.extend(self.net.getLane(via).getShape())
            pts.extend(edge.getLane(0).getShape())
            xy = _resample_open(np.asarray(pts), 1.0)
            s, d = self.to_frenet(xy[:, 0], xy[:, 1])
            s0 = s[0]
            s_rel = (s - s0) % self.lap_length
            keep = s_rel <= RAMP_RANGE
            # keep the monotone part only (the ramp bends away; projection stays monotone near the loop)
            s_keep, d_keep = s_rel[keep], d[keep]
            mono = np.concatenate([[True], np.diff(s_keep) > 1e-6])
            mono = np.cumprod(mono).astype(bool)
            out.append(Exit(eid, float(s0), s0 + s_keep[mono], d_keep[mono]))
        return tuple(sorted(out, key=lambda e: e.s_start))

    def _loop_edge_bounds(self) -> list[tuple[str, float, float]]:
        """(edge id, s at its start, s at its end) of each loop edge on the middle lane."""
        out = []
        for eid in LOOP_EDGES:
            shape = np.asarray(self.net.getEdge(eid).getLane(1).getShape())
            s, _ = self.to_frenet(shape[[0, -1], 0], shape[[0, -1], 1])
            out.append((eid, float(s[0]), float(s[1])))
        return out

    # ------------------------------------------------------------------ frame conversions
    def to_frenet(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World xy [m] -> route frame (s in [0, lap_length), d) [m]; any shape, vectorised."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        shape = x.shape
        p = np.stack([x.ravel(), y.ravel()], axis=1)  # [Q, 2]
        m = len(self.ref_xy)
        # coarse: nearest of every 20th vertex, then exact projection on a window of segments around it
        out_s = np.empty(len(p))
        out_d = np.empty(len(p))
        chunk = 65536
        offs = np.arange(-self._coarse - 5, self._coarse + 6)
        for i in range(0, len(p), chunk):  # bounded memory for large queries
            q = p[i : i + chunk]
            d2 = ((q[:, None, :] - self._coarse_xy[None, :, :]) ** 2).sum(-1)
            c = np.argmin(d2, axis=1) * self._coarse
            idx = (c[:, None] + offs[None, :]) % m  # [Q, W] segment ids
            a = self.ref_xy[idx]  # [Q, W, 2]
            u = self._seg_dir[idx]
            rel = q[:, None, :] - a
            t = np.clip((rel * u).sum(-1), 0.0, self._seg_len[idx])
            foot = a + u * t[..., None]
            dist2 = ((q[:, None, :] - foot) ** 2).sum(-1)
            j = np.argmin(dist2, axis=1)
            rows = np.arange(len(q))
            seg = idx[rows, j]
            out_s[i : i + chunk], out_d[i : i + chunk] = self._project_smooth(q, seg, t[rows, j])
        return out_s.reshape(shape), out_d.reshape(shape)

    def _project_smooth(
        self, q: np.ndarray, seg: np.ndarray, t_clip: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Exact inverse of :meth:`to_xy` near segment ``seg``: the foot t where q - P(t) is parallel to
        the interpolated normal N(t) (a quadratic in t), tried on seg, then its neighbours.

        With piecewise-constant normals, points in the wedge outside a vertex have no exact (s, d) and the
        round trip misses by |d| x (turn angle per vertex), ~1.5 cm on the outer lane's curves.
        """
        m = len(self.ref_xy)
        best_t = np.full(len(q), np.nan)
        best_seg = seg.copy()
        for off in (0, -1, 1):
            jj = (seg + off) % m
            a, u, ln = self.ref_xy[jj], self._seg_dir[jj], self._seg_len[jj]
            n0 = self._vtx_normal[jj]
            k = (self._vtx_normal[(jj + 1) % m] - n0) / ln[:, None]
            r = q - a
            c0 = _cross(r, n0)
            c1 = _cross(r, k) - _cross(u, n0)
            c2 = -_cross(u, k)
            # the root near -c0/c1 (numerically stable form; the other root is ~1/c2 away)
            sq = np.sqrt(np.maximum(c1 * c1 - 4.0 * c2 * c0, 0.0))
            tt = -2.0 * c0 / (c1 + np.where(c1 >= 0, 1.0, -1.0) * sq)
            ok = np.isnan(best_t) & (tt >= -1e-9) & (tt <= ln + 1e-9)
            best_t = np.where(ok, tt, best_t)
            best_seg = np.where(ok, jj, best_seg)
        best_t = np.where(np.isnan(best_t), t_clip, np.clip(best_t, 0.0, self._seg_len[best_seg]))
        foot = self.ref_xy[best_seg] + self._seg_dir[best_seg] * best_t[:, None]
        n = self._normal_at(best_seg, best_t)
        s = (self.ref_s[best_seg] + best_t) % self.lap_length
        return s, ((q - foot) * n).sum(-1)

    def _normal_at(self, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Unit left normal [..., 2] at distance t along segment seg, linear between vertex normals."""
        f = (t / self._seg_len[seg])[..., None]
        n = self._vtx_normal[seg] * (1.0 - f) + self._vtx_normal[(seg + 1) % len(self.ref_xy)] * f
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def segment_of(self, s: np.ndarray) -> np.ndarray:
        """Index of the reference segment containing route position(s) s (wrapped)."""
        sw = np.asarray(s, dtype=np.float64) % self.lap_length
        return self._segment_of_wrapped(sw)

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
        seg = self._segment_of_wrapped(sw % self.lap_length)
        t = sw - self.ref_s[seg]
        # the normal interpolated between vertex normals, as _normal_at (per component, same operations)
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
        seg = self._segment_of_wrapped(sw % self.lap_length)
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
    @staticmethod
    def lane_center(lane: np.ndarray | int) -> np.ndarray:
        """Lateral offset [m] of lane centre(s)."""
        return (np.asarray(lane, dtype=np.float64) - 1.0) * LANE_WIDTH

    @staticmethod
    def lane_of_d(d: np.ndarray) -> np.ndarray:
        """Loop lane index (int8) of lateral offset(s) d; -1 beyond the loop's road edges."""
        d = np.asarray(d, dtype=np.float64)
        lane = np.clip(np.floor(d / LANE_WIDTH + 1.5), 0, N_LANES - 1).astype(np.int8)
        return np.where(np.abs(d) <= HALF_ROAD, lane, -1).astype(np.int8)

    def lane_at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Loop lane index of world point(s); -1 off the loop (on a ramp, off the road)."""
        _, d = self.to_frenet(x, y)
        return self.lane_of_d(d)

    # ------------------------------------------------------------------ route distance (Dijkstra)
    def _edge_cost_uncached(self, from_edge: str, to_edge: str) -> float:
        path, cost = self.net.getShortestPath(self.net.getEdge(from_edge), self.net.getEdge(to_edge))
        return math.inf if path is None else float(cost)

    def route_distance(self, from_edge: str, from_pos: float, to_edge: str, to_pos: float) -> float:
        """Road distance [m] from (edge, pos) to (edge, pos) by Dijkstra on the SUMO network, cached.

        Equals ``sumolib`` ``net.getShortestPath(..., fromPos, toPos)`` and goes once round the loop when
        the target lies behind the start on the same edge. ``inf`` when the target is unreachable
        (from an exit ramp). Edge-to-edge costs are cached; positions are applied in closed form.
        """
        if from_edge == to_edge and to_pos >= from_pos:
            return float(to_pos - from_pos)
        if from_edge == to_edge:
            # once round: leave this edge, come back to it
            nxt = [e.getID() for e in self.net.getEdge(from_edge).getOutgoing()]
            best = min((self._edge_cost(n, to_edge) for n in nxt if n in LOOP_EDGES), default=math.inf)
            length = self.net.getEdge(from_edge).getLength()
            return float(length - from_pos + best - self.net.getEdge(to_edge).getLength() + to_pos)
        cost = self._edge_cost(from_edge, to_edge)
        if math.isinf(cost):
            return math.inf
        # sumolib's cost counts both end edges whole; cut to the positions
        return float(cost - from_pos - (self.net.getEdge(to_edge).getLength() - to_pos))

    def remaining_distance(self, s: np.ndarray, s_target: float) -> np.ndarray:
        """Route distance [m] from loop position(s) s to the route target at s_target, along the loop.

        The loop offers a single path, so Dijkstra reduces to ``(s_target - s) mod lap_length`` in the
        route frame (checked against sumolib in the tests). Vectorised, for the planner.
        """
        return (s_target - np.asarray(s, dtype=np.float64)) % self.lap_length

    # ------------------------------------------------------------------ summaries
    def drivable_right_edge(self, s: np.ndarray) -> np.ndarray:
        """Lowest drivable d [m] at s: the loop's right edge, or the far edge of an exit ramp beside it."""
        s = np.asarray(s, dtype=np.float64)
        edge = np.full(s.shape, -HALF_ROAD)
        for ex in self.exits:
            ds = (s - ex.s_start) % self.lap_length + ex.s_start
            rd = ex.d_at(ds)
            edge = np.where(np.isfinite(rd), np.minimum(edge, rd - LANE_WIDTH / 2), edge)
        return edge

    def describe(self) -> dict[str, object]:
        return {
            "lap_length_m": round(self.lap_length, 2),
            "lane_lengths_m": [round(v, 2) for v in self.lane_lengths],
            "stop_lines_s_m": [round(sl.s, 2) for sl in self.stop_lines],
            "exits_s_m": [round(e.s_start, 2) for e in self.exits],
            "checkpoints": [(round(c.s, 2), c.lane) for c in self.checkpoints],
        }


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _smooth_closed(pts: np.ndarray, half_window: float) -> np.ndarray:
    """Moving average of a closed, evenly sampled polyline over +-half_window metres."""
    step = float(np.linalg.norm(pts[1] - pts[0]))
    w = max(1, int(round(half_window / step)))
    kern = np.ones(2 * w + 1) / (2 * w + 1)
    padded = np.concatenate([pts[-w:], pts, pts[:w]])
    return np.stack([np.convolve(padded[:, k], kern, mode="valid") for k in range(2)], axis=1)


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


@functools.lru_cache(maxsize=4)
def _load_road_cached(path: str, mtime: float) -> Road:
    return Road(path)


def load_road(net_file: str | Path | None = None, build: bool = True) -> Road:
    """The oval's :class:`Road`; builds the network first when it is missing or stale (if ``build``)."""
    from irlsim.road.network import build_net, net_path

    if net_file is None:
        net_file = build_net() if build else net_path()
    p = Path(net_file)
    if not p.is_file():
        raise IrlsimError(f"network {p} not found: run 'irlsim net' (or 'make net') to build it")
    return _load_road_cached(str(p.resolve()), p.stat().st_mtime)
