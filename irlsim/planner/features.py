"""The 15 path-integral features of a policy set (costs >= 0; order = ``irlsim.FEATURE_NAMES``).

Every feature is a discounted path integral f = sum_{t=1..T-1} gamma^t f_t dt over the policy's states
after t = 0 (t = 0 is the same for all policies), unless marked "event" / "end". Symbols: s the route
progress [m] (relative to the ego), v speed [m/s], a longitudinal acceleration [m/s^2], j = da/dt,
d lateral offset [m] (+ left), kappa the reference curvature [1/m], v_f = ``yaw_speed_floor``, LW = 3.2 m the lane
width. ``w_t = gamma^t dt`` [s].

| # | name          | f_t (per step), or the event / end value                                    | unit        |
|---|---------------|------------------------------------------------------------------------------|-------------|
| 1 | acc_lon       | a^2                                                                          | m^2/s^4 * s |
| 2 | jerk_lon      | j^2, j = (a_t - a_{t-1}) / dt                                                | m^2/s^6 * s |
| 3 | acc_lat       | (d_ddot + v^2 kappa)^2                                                       | m^2/s^4 * s |
| 4 | jerk_lat      | (d_dddot + d/dt(v^2 kappa))^2                                                | m^2/s^6 * s |
| 5 | velocity      | (v - v_ref)^2, v_ref = min(v_target, sqrt(2 b max(0, dist to stop point)))   | m^2/s^2 * s |
|   |               | before an active stop line within ``stop_reach``, else v_target (70 km/h)    |             |
| 6 | creep         | min(v, creep_speed) while 0 <= (stop line - s) <= creep_zone (active line)  | m/s * s     |
| 7 | end_heading   | end: atan2(d_dot_T, max(v_T, v_f))^2, heading to the lane at the horizon    | rad^2       |
| 8 | centerline    | (d - nearest lane centre)^2 (an exit ramp's centre counts as a centre)       | m^2 * s     |
| 9 | road_edge     | relu(m - gap_left)^2 + relu(m - gap_right)^2, gap = distance of the ego's   | m^2 * s     |
|   |               | side to the drivable edge (ramps included), m = ``edge_margin``              |             |
| 10| mission_lane  | u(s) |d - d_req| / LW, u = min(u_max, D / remaining distance to the target   | lanes * s   |
|   |               | checkpoint), 0 once past it; d_req the centre of its required lane; with     |             |
|   |               | ``mission_event`` E > 0 also the event gamma^tc u_max E |d_tc - d_req| / LW   |             |
|   |               | at the step tc the policy passes the checkpoint                              |             |
| 11| progress      | max(0, s_goal - s), s_goal = target checkpoint + ``progress_lookahead``; on an | m * s       |
|   |               | exit ramp (target unreachable) the route distance is capped at lap_length     |             |
| 12| stop_line     | event: gamma^tc (1 + v_tc) when crossing an active stop line at step tc      | m/s         |
|   |               | without having stood (v < v_stopped) before it (a red light: at all); else 0 |             |
| 13| lc_delay      | t |d_dot| (lateral motion weighted by its time in the horizon)               | m * s       |
| 14| lat_overshoot | relu(sgn (d - d_tgt))^2, sgn = direction from d_0 to the profile's target    | m^2 * s     |
| 15| proximity     | sum_m exp(-(ds_m / (sigma_s + (L + L_m)/2))^2 - (dd_m / sigma_d)^2), centre  | 1 * s       |
|   |               | distances to vehicle m's constant-velocity prediction in the route frame     |             |

With ``planner.feature_set = "lanes"`` two more (``irlsim.LANE_FEATURE_NAMES``; the 15 above price no lane
for its own sake: a policy and its mirror image cost the same but for mission_lane):

| # | name          | f_t (per step)                                                               | unit        |
|---|---------------|------------------------------------------------------------------------------|-------------|
| 16| lane_right    | max(0, (d - right edge) / LW - 1/2): whole lanes to the ego's right          | lanes * s   |
| 17| lane_left     | max(0, (left edge - d) / LW - 1/2): whole lanes to its left                  | lanes * s   |

(the edges of the lanes that exist at each step, an exit ramp's for an exit profile). Both are costs, so
positive weights prefer either side (their difference is the preference); a driver who keeps left, or
right, has a reward these can express.

Implementation: per-profile banks (lon [L, T], lat [J, T]); lon-only and lat-only parts are summed per
bank, the mixed parts (acc_lat, jerk_lat cross terms, mission_lane, proximity) are exact [J, T] @ [T, L]
products, so a policy's feature is F_lon[l] + F_lat[j] + F_cross[j, l]. float32 throughout.

The mixed parts are evaluated for the candidate pairs only (:class:`Pairs`): the free lateral profiles
against every lon profile (one matrix product), and each exit profile against its one bound lon profile
(a row-wise dot product), not the whole [J, L] grid (exit profiles would triple it near an exit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from irlsim import FEATURE_SETS
from irlsim.planner.config import PlannerConfig
from irlsim.planner.prediction import predicted_d, predicted_motion
from irlsim.planner.sampler import LatBank, LonBank
from irlsim.road import LANE_WIDTH, Road
from irlsim.sim.types import VehicleStates

#: every feature's column (the largest set's order; each set is a prefix of it)
IDX = {name: i for i, name in enumerate(FEATURE_SETS["lanes"])}
F32 = np.float32


@dataclass
class Context:
    """Per-cycle scalars the features need (all relative to the ego's unwrapped s)."""

    s_ego: float  # [m] unwrapped
    d0: float  # [m]
    goal: float  # [m] progress goal, relative
    target_rel: float  # [m] target checkpoint, relative
    req_d: float  # [m] centre of the required lane
    stop_rel: float  # [m] active stop line, relative (inf if none / beyond reach)
    lap_length: float
    lane_width: float = LANE_WIDTH  # [m]
    #: (lowest, highest) lane [T] at each step where lanes are added or dropped (Planner's lane_window);
    #: None on a road with the same lanes throughout
    lanes: tuple[np.ndarray, np.ndarray] | None = None
    stop_red: bool = False  # the active stop line is a red (or yellow) traffic light: standing allows nothing


@dataclass
class LonSeries:
    """Derived per-step series of the longitudinal bank ([L, T], float32 unless noted)."""

    c: np.ndarray  # v^2 kappa [m/s^2]
    cdot: np.ndarray  # d/dt(v^2 kappa) [m/s^3]
    urg: np.ndarray  # mission urgency u(s) [-]
    prog: np.ndarray  # max(0, goal - s) [m]


@dataclass
class Pairs:
    """The candidate (lat, lon) pairs of a cycle, C = len(free) * L + len(bound_j) of them, in this
    order: every free lateral profile (``free``, ascending) with every lon profile (lon index fastest),
    then each exit profile ``bound_j[k]`` with its bound lon profile ``bound_l[k]``. Pairwise terms are
    vectors [C] in this order."""

    free: np.ndarray  # [Jf] int64
    bound_j: np.ndarray  # [Jb] int64
    bound_l: np.ndarray  # [Jb] int64
    L: int

    @staticmethod
    def of(lat: LatBank, n_lon: int) -> Pairs:
        free = np.flatnonzero(lat.bound_lon < 0)
        bound = np.flatnonzero(lat.bound_lon >= 0)
        return Pairs(free, bound, lat.bound_lon[bound], n_lon)

    @property
    def all_free(self) -> bool:
        return len(self.bound_j) == 0

    def lat_idx(self) -> np.ndarray:
        """[C] lateral profile of each pair."""
        return np.concatenate([np.repeat(self.free, self.L), self.bound_j])

    def lon_idx(self) -> np.ndarray:
        """[C] longitudinal profile of each pair."""
        return np.concatenate([np.tile(np.arange(self.L), len(self.free)), self.bound_l])

    def dot(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """sum_k a[j, k] b[l, k] for every pair: a [J, K] (lat), b [L, K] (lon) -> [C]."""
        if self.all_free:
            return (a @ b.T).ravel()
        grid = (a[self.free] @ b.T).ravel()
        tail = np.einsum("ik,ik->i", a[self.bound_j], b[self.bound_l])
        return np.concatenate([grid, tail])

    def outer(self, f, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """f(a[j], b[l]) elementwise for every pair: a [J], b [L] -> [C]."""
        grid = f(a[self.free][:, None], b[None, :]).ravel()
        if self.all_free:
            return grid
        return np.concatenate([grid, f(a[self.bound_j], b[self.bound_l])])


def weights(cfg: PlannerConfig) -> np.ndarray:
    """w_t = gamma^t dt for t >= 1, 0 at t = 0: [T] float32."""
    t = np.arange(cfg.n_steps)
    w = (cfg.gamma**t * cfg.dt).astype(F32)
    w[0] = 0.0
    return w


def lon_features(
    lon: LonBank, kappa: np.ndarray, ctx: Context, cfg: PlannerConfig, w: np.ndarray
) -> tuple[np.ndarray, LonSeries]:
    """Lon-only feature parts [L, F] (F = ``cfg.feature_names``) and the series the mixed parts need."""
    L = len(lon.v)
    s, v, a = lon.s, lon.v, lon.a
    F = np.zeros((L, len(cfg.feature_names)), F32)
    F[:, IDX["acc_lon"]] = (a * a) @ w
    jerk = np.diff(a, axis=1, prepend=a[:, :1]) / cfg.dt
    F[:, IDX["jerk_lon"]] = (jerk * jerk) @ w
    vref = np.full(s.shape, cfg.v_target)
    if math.isfinite(ctx.stop_rel) and ctx.stop_rel < cfg.stop_reach:
        before = s <= ctx.stop_rel
        dist = np.maximum(ctx.stop_rel - cfg.stop_margin - s, 0.0)
        vref = np.where(before, np.minimum(cfg.v_target, np.sqrt(2 * cfg.stop_decel_comfort * dist)), vref)
        zone = before & (ctx.stop_rel - s <= cfg.creep_zone)
        F[:, IDX["creep"]] = (zone * np.minimum(v, cfg.creep_speed)) @ w
        crossed = s >= ctx.stop_rel
        crossed[:, 0] = False
        any_cross = crossed.any(axis=1)
        tc = np.argmax(crossed, axis=1)
        stood = np.minimum.accumulate(v, axis=1) < cfg.v_stopped
        stood_before = stood[np.arange(L), np.maximum(tc - 1, 0)]  # strictly before the crossing step
        ev = any_cross & (~stood_before | ctx.stop_red) & (ctx.stop_rel >= 0)
        F[:, IDX["stop_line"]] = np.where(ev, cfg.gamma**tc * (1.0 + v[np.arange(L), tc]), 0.0)
    F[:, IDX["velocity"]] = ((v - vref) ** 2) @ w
    prog = np.maximum(ctx.goal - s, 0.0)
    F[:, IDX["progress"]] = prog @ w
    c = v * v * kappa
    cdot = np.diff(c, axis=1, prepend=c[:, :1]) / cfg.dt
    F[:, IDX["acc_lat"]] = (c * c) @ w
    F[:, IDX["jerk_lat"]] = (cdot * cdot) @ w
    rem = ctx.target_rel - s
    urg = np.where(
        rem > 0, np.minimum(cfg.mission_urgency_max, cfg.mission_distance / np.maximum(rem, 1e-3)), 0.0
    )
    if cfg.mission_event > 0:
        # the step a policy passes the checkpoint carries the event: w_tc * extra = gamma^tc * u_max * event
        passing = (rem <= 0) & (np.arange(rem.shape[1]) >= 1) & (rem[:, :1] > 0)
        tc = np.argmax(passing, axis=1)
        hit = passing[np.arange(len(tc)), tc]
        urg[np.flatnonzero(hit), tc[hit]] += cfg.mission_urgency_max * cfg.mission_event / cfg.dt
    series = LonSeries(c=c.astype(F32), cdot=cdot.astype(F32), urg=urg.astype(F32), prog=prog.astype(F32))
    return F, series


def lat_features(
    lat: LatBank, lon: LonBank, series: LonSeries, road: Road, ctx: Context, cfg: PlannerConfig, w: np.ndarray
) -> np.ndarray:
    """Lat-only feature parts [J, F]; exit profiles use their bound longitudinal profile."""
    J = len(lat.d)
    d, dd = lat.d, lat.dd
    t = np.arange(cfg.n_steps) * cfg.dt
    F = np.zeros((J, len(cfg.feature_names)), F32)
    F[:, IDX["acc_lat"]] = (lat.ddd**2) @ w
    F[:, IDX["jerk_lat"]] = (lat.dddd**2) @ w
    # distance to the nearest lane centre, and the road's edges (of the lanes that exist at each step)
    dev, right_edge, left_edge = road.lane_geometry(d, ctx.lanes)
    half = road.half_road
    bound = lat.bound_lon >= 0
    if bound.any():
        sb = ctx.s_ego + lon.s[lat.bound_lon[bound]]
        edge = road.drivable_right_edge(sb)
        right_edge[bound] = edge
        ramp_c = edge + road.lane_width / 2
        on_ramp = edge < (-half if ctx.lanes is None else road.road_edges(sb)[0])
        dev[bound] = np.where(on_ramp, np.minimum(dev[bound], np.abs(d[bound] - ramp_c)), dev[bound])
        # on the ramp the target is unreachable: the route distance is capped at the lap length
        off = d[bound] < (-half if ctx.lanes is None else road.road_edges(sb)[0])
        prog = series.prog[lat.bound_lon[bound]]
        F[bound, IDX["progress"]] = (off * (ctx.lap_length - prog)) @ w
    F[:, IDX["centerline"]] = (dev * dev) @ w
    gap_l = left_edge - (d + cfg.ego_width / 2)
    gap_r = (d - cfg.ego_width / 2) - right_edge
    m = cfg.edge_margin
    F[:, IDX["road_edge"]] = (np.maximum(m - gap_l, 0.0) ** 2 + np.maximum(m - gap_r, 0.0) ** 2) @ w
    F[:, IDX["lc_delay"]] = (t * np.abs(dd)) @ w
    if "lane_right" in cfg.feature_names:  # whole lanes between the ego and each edge (a lane's centre)
        F[:, IDX["lane_right"]] = np.maximum((d - right_edge) / road.lane_width - 0.5, 0.0) @ w
        F[:, IDX["lane_left"]] = np.maximum((left_edge - d) / road.lane_width - 0.5, 0.0) @ w
    tgt = np.nan_to_num(lat.target, nan=0.0)[:, None]
    sgn = np.where(np.abs(tgt - ctx.d0) > 0.05, np.sign(tgt - ctx.d0), 0.0)
    sgn = np.where(np.isnan(lat.target)[:, None], 0.0, sgn)
    F[:, IDX["lat_overshoot"]] = (np.maximum(sgn * (d - tgt), 0.0) ** 2) @ w
    return F


#: the feature columns :func:`cross_features` returns, in its column order
CROSS_COLS: tuple[int, ...] = (IDX["acc_lat"], IDX["jerk_lat"], IDX["mission_lane"], IDX["end_heading"])


def cross_features(
    lat: LatBank,
    lon: LonBank,
    series: LonSeries,
    ctx: Context,
    w: np.ndarray,
    pairs: Pairs,
    v_floor: float,
) -> np.ndarray:
    """Mixed parts of the candidate pairs [C, 4] float32, columns ``CROSS_COLS`` (acc_lat, jerk_lat,
    mission_lane, end_heading; the other features have no mixed part)."""
    X = np.empty((_n_pairs(pairs), len(CROSS_COLS)), F32)
    wd = (lat.ddd * w).astype(F32)
    X[:, 0] = 2.0 * pairs.dot(wd, series.c)
    wj = (lat.dddd * w).astype(F32)
    X[:, 1] = 2.0 * pairs.dot(wj, series.cdot)
    lanes_away = (np.abs(lat.d - ctx.req_d) / ctx.lane_width * w).astype(F32)
    X[:, 2] = pairs.dot(lanes_away, series.urg)
    head = pairs.outer(np.arctan2, lat.dd[:, -1], np.maximum(lon.v[:, -1], v_floor))
    X[:, 3] = head * head
    return X


def _n_pairs(pairs: Pairs) -> int:
    return len(pairs.free) * pairs.L + len(pairs.bound_j)


@dataclass
class VehicleTerms:
    proximity: np.ndarray  # [C] float32 (one per candidate pair, see Pairs)
    collision: np.ndarray  # [C] bool
    risk: np.ndarray  # [C] float32, time-weighted intrusion into the expert's safety zone (0 = safe)


#: a vehicle farther than this many proximity length scales (sigma_s + half lengths) from every lon
#: profile at every step is dropped: each of its proximity terms is below exp(-36) ~ 2e-16 (far below
#: the float32 rounding of any feature that matters), and the collision / safety tests reach far less
_CULL_SCALES = 6.0


def vehicle_terms(
    lat: LatBank,
    lon: LonBank,
    vehicles: VehicleStates,
    ctx: Context,
    cfg: PlannerConfig,
    w: np.ndarray,
    stop_lines_s: tuple[float, ...] = (),
    pairs: Pairs | None = None,
) -> VehicleTerms:
    """Proximity, predicted collision and safety risk against the vehicles' predictions: constant speed
    along the route frame at constant d, except that a vehicle stands at the next stop line
    (``stop_lines_s``, wrapped route positions [m]) it reaches, and that one with a ``motion`` (a turning
    vehicle's way into the route, :func:`irlsim.planner.planner.route_frame_boxes`) moves by it, at its
    speed. Vectors over the candidate pairs."""
    L, T = len(lon.v), cfg.n_steps
    pairs = pairs if pairs is not None else Pairs.of(lat, L)
    lap = ctx.lap_length
    if vehicles.count:
        ds0 = (vehicles.s - (ctx.s_ego % lap) + lap / 2) % lap - lap / 2
        near = np.abs(ds0) < cfg.cull_distance
    else:
        near = np.zeros(0, bool)
    t = (np.arange(T) * cfg.dt).astype(F32)
    if near.any():
        sv_near, vv_near = predicted_motion(near, ds0, vehicles, lap, t, stop_lines_s)  # [M, T] each
        kept = _cull(near, sv_near, vv_near, lon, vehicles, cfg)
        sv, vm = sv_near[kept[near]], vv_near[kept[near]]
        near = kept
    if not near.any():
        C = _n_pairs(pairs)
        return VehicleTerms(np.zeros(C, F32), np.zeros(C, bool), np.zeros(C, F32))
    J = len(lat.d)
    vlen = vehicles.length[near].astype(F32)[:, None, None]
    vwid = vehicles.width[near].astype(F32)[:, None, None]
    vv = vehicles.v[near].astype(F32)[:, None, None]
    # route-frame centres: ego (front bumper s - L/2) minus vehicle's predicted centre: [M, L, T]
    dS = (lon.s.astype(F32) - cfg.ego_length / 2)[None, :, :] - sv[:, None, :]
    dD = lat.d.astype(F32)[None, :, :] - predicted_d(vehicles, near)[:, None, :]  # [M, J, T]
    M = int(near.sum())
    half_l = (cfg.ego_length + vlen) / 2
    half_w = (cfg.ego_width + vwid) / 2
    # proximity: sum_m sum_t w_t p_lon p_lat as one matrix product (p_lon depends on the lon profile and
    # the vehicle only, p_lat on the lat profile and the vehicle only)
    v_ego = lon.v.astype(F32)[None, :, :]  # [1, L, T]
    p_lon = proximity_lon(dS, half_l, v_ego, vm[:, None, :], cfg) * w
    p_lat = np.exp(-np.square(dD / F32(cfg.proximity_sigma_d)))
    a_lat = p_lat.transpose(1, 0, 2).reshape(J, M * T)
    a_lon = p_lon.transpose(1, 0, 2).reshape(L, M * T)
    prox = pairs.dot(a_lat, a_lon)
    # predicted collision: route-frame boxes with small margins, t >= 1
    live = (t > 0)[None, None, :]
    c_lon = ((np.abs(dS) < half_l + cfg.collision_margin_lon) & live).astype(F32)
    # a vehicle right behind the ego in its lane follows it (SUMO's car following): it is responsible
    # for that gap, so it counts for proximity but not for the collision label and the safety zone
    follower = (ds0[near] < -cfg.ego_length) & (
        np.abs(vehicles.d[near] - ctx.d0) < (cfg.ego_width + vehicles.width[near]) / 2
    )
    lead_or_side = (~follower).astype(F32)[:, None, None]
    c_lat = (np.abs(dD) < half_w + cfg.collision_margin_lat) * lead_or_side
    # time the boxes overlap, sum_t w_t [overlap_t]: a predicted collision is one with overlap > 0 (w_t > 0
    # for t >= 1), and proximity adds it times proximity_overlap, so a linear reward can price collisions
    overlap = pairs.dot(
        c_lat.transpose(1, 0, 2).reshape(J, M * T), (c_lon * w).transpose(1, 0, 2).reshape(L, M * T)
    )
    coll = overlap > 0.0
    prox = prox + F32(cfg.proximity_overlap) * overlap
    # safety zone: headway ahead of the ego (at its speed), a shorter one behind it (at the other's)
    front = half_l + cfg.safety_gap + cfg.safety_headway * v_ego
    rear = half_l + 1.0 + cfg.safety_rear_headway * vv
    omega = (np.exp(-t / 2.0) * (t > 0) * (t <= cfg.safety_time + 1e-6)).astype(F32)
    ts = slice(1, int(np.flatnonzero(omega)[-1]) + 1) if omega.any() else slice(0, 0)  # the steps omega > 0
    Ts = ts.stop - ts.start if omega.any() else 0
    u_lon = ((dS[:, :, ts] > -front[:, :, ts]) & (dS[:, :, ts] < rear)) * omega[ts]
    u_lat = (np.abs(dD[:, :, ts]) < half_w + cfg.safety_margin_lat) * lead_or_side
    risk = pairs.dot(u_lat.transpose(1, 0, 2).reshape(J, M * Ts), u_lon.transpose(1, 0, 2).reshape(L, M * Ts))
    return VehicleTerms(prox.astype(F32), coll, risk.astype(F32))


def safety_scale(
    behind: np.ndarray, v_ego: np.ndarray, v_other: np.ndarray, cfg: PlannerConfig
) -> np.ndarray:
    """[m] D, the longitudinal length scale of the proximity: the bumper gap a careful driver keeps.

    Ego behind the other vehicle: D = sigma_0 + h v_ego + max(0, v_ego^2 - v_other^2) / (2 b) (headway
    plus the distance needed to brake down to the other's speed). Ego ahead: the same with the roles
    swapped and the rear headway h_r. sigma_0 = ``proximity_sigma_s``, h = ``proximity_headway``,
    h_r = ``proximity_rear_headway``, b = ``proximity_decel``. Broadcasts its arguments."""
    b2 = F32(2.0 * cfg.proximity_decel)
    ve2, vo2 = v_ego * v_ego, v_other * v_other
    need_behind = F32(cfg.proximity_headway) * v_ego + np.maximum(ve2 - vo2, 0.0) / b2
    need_ahead = F32(cfg.proximity_rear_headway) * v_other + np.maximum(vo2 - ve2, 0.0) / b2
    return F32(cfg.proximity_sigma_s) + np.where(behind, need_behind, need_ahead)


def proximity_lon(
    dS: np.ndarray, half_l: np.ndarray, v_ego: np.ndarray, v_other: np.ndarray, cfg: PlannerConfig
) -> np.ndarray:
    """Longitudinal factor of the proximity, exp(-(max(gap, 0) / D)^2) in [0, 1]: 1 while the boxes
    overlap along the route (gap = |dS| - half lengths <= 0), exp(-1) at the safety distance D
    (:func:`safety_scale`), vanishing beyond. dS: ego centre minus the other's centre [m].

    The same as ``exp(-(gap / safety_scale(dS < 0, v_ego, v_other, cfg))^2)``, in fewer passes over the
    [M, L, T] arrays (in place, float32): the closing term is max(0, sgn (v_ego^2 - v_other^2)) / (2 b)
    with sgn = +1 behind and -1 ahead."""
    behind = dS < 0
    closing = np.square(v_ego) - np.square(v_other)  # [M, L, T]
    np.negative(closing, out=closing, where=~behind)
    np.maximum(closing, 0.0, out=closing)
    closing *= F32(0.5 / cfg.proximity_decel)
    closing += np.where(behind, F32(cfg.proximity_headway) * v_ego, F32(cfg.proximity_rear_headway) * v_other)
    closing += F32(cfg.proximity_sigma_s)  # D
    gap = np.abs(dS)
    gap -= half_l
    np.maximum(gap, 0.0, out=gap)
    gap /= closing
    np.square(gap, out=gap)
    np.negative(gap, out=gap)
    return np.exp(gap, out=gap)


def _cull(
    near: np.ndarray,
    sv_near: np.ndarray,
    vv_near: np.ndarray,
    lon: LonBank,
    vehicles: VehicleStates,
    cfg: PlannerConfig,
) -> np.ndarray:
    """``near`` without the vehicles that no lon profile comes close to at any step (their proximity
    terms are below 2e-16, their collision and safety tests false). ``sv_near``, ``vv_near``: [M, T]
    predicted centres and speeds."""
    sv = sv_near.astype(np.float64)
    ego_c = lon.s - cfg.ego_length / 2  # [L, T]
    lo, hi = ego_c.min(axis=0), ego_c.max(axis=0)  # [T]
    gap = np.maximum(np.maximum(lo[None, :] - sv, sv - hi[None, :]), 0.0).min(axis=1)  # [M] smallest |dS|
    half_l = (cfg.ego_length + vehicles.length[near]) / 2
    # the largest proximity scale any profile can have against each vehicle
    v_e = max(cfg.v_max, float(lon.v.max()))
    v_lo, v_hi = vv_near.min(axis=1).astype(np.float64), vv_near.max(axis=1).astype(np.float64)
    d_max = np.maximum(
        safety_scale(np.ones(1, bool), np.full(1, v_e), v_lo, cfg),  # the fastest ego behind
        safety_scale(np.zeros(1, bool), np.zeros(1), v_hi, cfg),  # a standing ego ahead
    )
    reach = (
        np.maximum(
            half_l + _CULL_SCALES * d_max,  # proximity
            half_l
            + cfg.safety_gap
            + cfg.safety_headway * v_e
            + 1.0
            + cfg.safety_rear_headway * vehicles.v[near]
            + cfg.collision_margin_lon,
        )
        + 1.0
    )
    out = near.copy()
    out[np.flatnonzero(near)[gap > reach]] = False
    return out
