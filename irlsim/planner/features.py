"""The 15 path-integral features of a policy set (costs >= 0; order = ``irlsim.FEATURE_NAMES``).

Every feature is a discounted path integral f = sum_{t=1..T-1} gamma^t f_t dt over the policy's states
after t = 0 (t = 0 is the same for all policies), unless marked "event" / "end". Symbols: s the route
progress [m] (relative to the ego), v speed [m/s], a longitudinal acceleration [m/s^2], j = da/dt,
d lateral offset [m] (+ left), kappa the reference curvature [1/m], W the ego width, LW = 3.2 m the lane
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
| 7 | end_heading   | end: atan2(d_dot_T, v_T)^2, the heading to the lane direction at the horizon | rad^2       |
| 8 | centerline    | (d - nearest lane centre)^2 (an exit ramp's centre counts as a centre)       | m^2 * s     |
| 9 | road_edge     | relu(m - gap_left)^2 + relu(m - gap_right)^2, gap = distance of the ego's   | m^2 * s     |
|   |               | side to the drivable edge (ramps included), m = ``edge_margin``              |             |
| 10| mission_lane  | u(s) |d - d_req| / LW, u = min(u_max, D / remaining distance to the target   | lanes * s   |
|   |               | checkpoint), 0 once past it; d_req the centre of its required lane           |             |
| 11| progress      | max(0, s_goal - s), s_goal = target checkpoint + ``progress_lookahead``; on an | m * s       |
|   |               | exit ramp (target unreachable) the route distance is capped at lap_length     |             |
| 12| stop_line     | event: gamma^tc (1 + v_tc) when crossing an active stop line at step tc      | m/s         |
|   |               | without having stood (v < v_stopped) before it; 0 otherwise                  |             |
| 13| lc_delay      | t |d_dot| (lateral motion weighted by its time in the horizon)               | m * s       |
| 14| lat_overshoot | relu(sgn (d - d_tgt))^2, sgn = direction from d_0 to the profile's target    | m^2 * s     |
| 15| proximity     | sum_m exp(-(ds_m / (sigma_s + (L + L_m)/2))^2 - (dd_m / sigma_d)^2), centre  | 1 * s       |
|   |               | distances to vehicle m's constant-velocity prediction in the route frame     |             |

Implementation: per-profile banks (lon [L, T], lat [J, T]); lon-only and lat-only parts are summed per
bank, the mixed parts (acc_lat, jerk_lat cross terms, mission_lane, proximity) are exact [J, T] @ [T, L]
products, so a policy's feature is F_lon[l] + F_lat[j] + F_cross[j, l]. float32 throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.planner.config import PlannerConfig
from irlsim.planner.sampler import LatBank, LonBank
from irlsim.road import HALF_ROAD, LANE_WIDTH, Road
from irlsim.sim.types import VehicleStates

IDX = {name: i for i, name in enumerate(FEATURE_NAMES)}
NF = len(FEATURE_NAMES)
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


@dataclass
class LonSeries:
    """Derived per-step series of the longitudinal bank ([L, T], float32 unless noted)."""

    c: np.ndarray  # v^2 kappa [m/s^2]
    cdot: np.ndarray  # d/dt(v^2 kappa) [m/s^3]
    urg: np.ndarray  # mission urgency u(s) [-]
    prog: np.ndarray  # max(0, goal - s) [m]


def weights(cfg: PlannerConfig) -> np.ndarray:
    """w_t = gamma^t dt for t >= 1, 0 at t = 0: [T] float32."""
    t = np.arange(cfg.n_steps)
    w = (cfg.gamma**t * cfg.dt).astype(F32)
    w[0] = 0.0
    return w


def lon_features(lon: LonBank, kappa: np.ndarray, ctx: Context, cfg: PlannerConfig,
                 w: np.ndarray) -> tuple[np.ndarray, LonSeries]:
    """Lon-only feature parts [L, 15] and the series the mixed parts need."""
    L = len(lon.v)
    s, v, a = lon.s, lon.v, lon.a
    F = np.zeros((L, NF), F32)
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
        stood_before = stood[np.arange(L), tc]
        ev = any_cross & ~stood_before & (ctx.stop_rel >= 0)
        F[:, IDX["stop_line"]] = np.where(ev, cfg.gamma**tc * (1.0 + v[np.arange(L), tc]), 0.0)
    F[:, IDX["velocity"]] = ((v - vref) ** 2) @ w
    prog = np.maximum(ctx.goal - s, 0.0)
    F[:, IDX["progress"]] = prog @ w
    c = v * v * kappa
    cdot = np.diff(c, axis=1, prepend=c[:, :1]) / cfg.dt
    F[:, IDX["acc_lat"]] = (c * c) @ w
    F[:, IDX["jerk_lat"]] = (cdot * cdot) @ w
    rem = ctx.target_rel - s
    urg = np.where(rem > 0, np.minimum(cfg.mission_urgency_max, cfg.mission_distance / np.maximum(rem, 1e-3)), 0.0)
    series = LonSeries(c=c.astype(F32), cdot=cdot.astype(F32), urg=urg.astype(F32), prog=prog.astype(F32))
    return F, series


def lat_features(lat: LatBank, lon: LonBank, series: LonSeries, road: Road, ctx: Context,
                 cfg: PlannerConfig, w: np.ndarray) -> np.ndarray:
    """Lat-only feature parts [J, 15]; exit profiles use their bound longitudinal profile."""
    J = len(lat.d)
    d, dd = lat.d, lat.dd
    t = np.arange(cfg.n_steps) * cfg.dt
    F = np.zeros((J, NF), F32)
    F[:, IDX["acc_lat"]] = (lat.ddd**2) @ w
    F[:, IDX["jerk_lat"]] = (lat.dddd**2) @ w
    centres = np.array([-LANE_WIDTH, 0.0, LANE_WIDTH])
    dev = np.min(np.abs(d[..., None] - centres), axis=-1)
    right_edge = np.full(d.shape, -HALF_ROAD)
    bound = lat.bound_lon >= 0
    if bound.any():
        sb = ctx.s_ego + lon.s[lat.bound_lon[bound]]
        edge = road.drivable_right_edge(sb)
        right_edge[bound] = edge
        ramp_c = edge + LANE_WIDTH / 2
        on_ramp = edge < -HALF_ROAD
        dev[bound] = np.where(on_ramp, np.minimum(dev[bound], np.abs(d[bound] - ramp_c)), dev[bound])
        # on the ramp the target is unreachable: the route distance is capped at the lap length
        off = d[bound] < -HALF_ROAD
        prog = series.prog[lat.bound_lon[bound]]
        F[bound, IDX["progress"]] = (off * (ctx.lap_length - prog)) @ w
    F[:, IDX["centerline"]] = (dev * dev) @ w
    gap_l = HALF_ROAD - (d + cfg.ego_width / 2)
    gap_r = (d - cfg.ego_width / 2) - right_edge
    m = cfg.edge_margin
    F[:, IDX["road_edge"]] = (np.maximum(m - gap_l, 0.0) ** 2 + np.maximum(m - gap_r, 0.0) ** 2) @ w
    F[:, IDX["lc_delay"]] = (t * np.abs(dd)) @ w
    tgt = np.nan_to_num(lat.target, nan=0.0)[:, None]
    sgn = np.where(np.abs(tgt - ctx.d0) > 0.05, np.sign(tgt - ctx.d0), 0.0)
    sgn = np.where(np.isnan(lat.target)[:, None], 0.0, sgn)
    F[:, IDX["lat_overshoot"]] = (np.maximum(sgn * (d - tgt), 0.0) ** 2) @ w
    return F


def cross_features(lat: LatBank, lon: LonBank, series: LonSeries, ctx: Context, w: np.ndarray) -> np.ndarray:
    """Mixed parts [J, L, 15] (zero except acc_lat, jerk_lat, mission_lane, end_heading)."""
    J, L = len(lat.d), len(lon.v)
    X = np.zeros((J, L, NF), F32)
    wd = (lat.ddd * w).astype(F32)
    X[:, :, IDX["acc_lat"]] = 2.0 * (wd @ series.c.T)
    wj = (lat.dddd * w).astype(F32)
    X[:, :, IDX["jerk_lat"]] = 2.0 * (wj @ series.cdot.T)
    lanes_away = (np.abs(lat.d - ctx.req_d) / LANE_WIDTH * w).astype(F32)
    X[:, :, IDX["mission_lane"]] = lanes_away @ series.urg.T
    head = np.arctan2(lat.dd[:, -1][:, None], np.maximum(lon.v[:, -1][None, :], 1e-3))
    X[:, :, IDX["end_heading"]] = head * head
    return X


@dataclass
class VehicleTerms:
    proximity: np.ndarray  # [J, L] float32
    collision: np.ndarray  # [J, L] bool
    risk: np.ndarray  # [J, L] float32, time-weighted intrusion into the expert's safety zone (0 = safe)


def vehicle_terms(lat: LatBank, lon: LonBank, vehicles: VehicleStates, ctx: Context, cfg: PlannerConfig,
                  w: np.ndarray, stop_lines_s: tuple[float, ...] = ()) -> VehicleTerms:
    """Proximity, predicted collision and safety risk against the vehicles' predictions: constant speed
    along the route frame at constant d, except that a vehicle stands at the next stop line
    (``stop_lines_s``, wrapped route positions [m]) it reaches."""
    J, L, T = len(lat.d), len(lon.v), cfg.n_steps
    lap = ctx.lap_length
    if vehicles.count:
        ds0 = (vehicles.s - (ctx.s_ego % lap) + lap / 2) % lap - lap / 2
        near = np.abs(ds0) < cfg.cull_distance
    else:
        near = np.zeros(0, bool)
    if not near.any():
        z = np.zeros((J, L), F32)
        return VehicleTerms(z, np.zeros((J, L), bool), z.copy())
    t = (np.arange(T) * cfg.dt).astype(F32)
    vlen = vehicles.length[near].astype(F32)[:, None, None]
    vwid = vehicles.width[near].astype(F32)[:, None, None]
    vv = vehicles.v[near].astype(F32)[:, None, None]
    # route-frame centres: ego (front bumper s - L/2) minus vehicle's predicted centre: [M, L, T]
    travel = vehicles.v[near].astype(F32)[:, None] * t[None, :]
    if stop_lines_s:
        # a vehicle heading for a stop line is predicted to stand at it (they all stop there)
        # constant deceleration b = v^2 / (2 dist) to stand at the line (SUMO brakes about like that)
        ahead = np.stack([(sl - vehicles.s[near]) % lap for sl in stop_lines_s]).min(axis=0)
        dist = np.maximum(ahead - 0.3, 0.1).astype(F32)[:, None]
        v_m = vehicles.v[near].astype(F32)[:, None]
        b = v_m * v_m / (2 * dist) + F32(1e-3)
        tt = np.minimum(t[None, :], v_m / b)
        braking = np.minimum(v_m * tt - 0.5 * b * tt * tt, dist)
        travel = np.where(dist < 80.0, braking, travel)
    sv = ds0[near].astype(F32)[:, None] + travel - vehicles.length[near].astype(F32)[:, None] / 2
    dS = (lon.s.astype(F32) - cfg.ego_length / 2)[None, :, :] - sv[:, None, :]
    dD = lat.d.astype(F32)[None, :, :] - vehicles.d[near].astype(F32)[:, None, None]  # [M, J, T]
    M = int(near.sum())
    half_l = (cfg.ego_length + vlen) / 2
    half_w = (cfg.ego_width + vwid) / 2
    # proximity: sum_m sum_t w_t exp(-(dS/sig_s)^2) exp(-(dD/sig_d)^2) as one matrix product
    p_lon = np.exp(-np.square(dS / (cfg.proximity_sigma_s + half_l))) * w
    p_lat = np.exp(-np.square(dD / F32(cfg.proximity_sigma_d)))
    a_lat = p_lat.transpose(1, 0, 2).reshape(J, M * T)
    a_lon = p_lon.transpose(1, 0, 2).reshape(L, M * T)
    prox = a_lat @ a_lon.T
    # predicted collision: route-frame boxes with small margins, t >= 1
    live = (t > 0)[None, None, :]
    c_lon = ((np.abs(dS) < half_l + cfg.collision_margin_lon) & live).astype(F32)
    # a vehicle right behind the ego in its lane follows it (SUMO's car following): it is responsible
    # for that gap, so it counts for proximity but not for the collision label and the safety zone
    follower = ((ds0[near] < -cfg.ego_length) &
                (np.abs(vehicles.d[near] - ctx.d0) < (cfg.ego_width + vehicles.width[near]) / 2))
    lead_or_side = (~follower).astype(F32)[:, None, None]
    c_lat = (np.abs(dD) < half_w + cfg.collision_margin_lat) * lead_or_side
    coll = (c_lat.transpose(1, 0, 2).reshape(J, M * T) @ c_lon.transpose(1, 0, 2).reshape(L, M * T).T) > 0.5
    # safety zone: headway ahead of the ego (at its speed), a shorter one behind it (at the other's)
    v_ego = lon.v.astype(F32)[None, :, :]
    front = half_l + cfg.safety_gap + cfg.safety_headway * v_ego
    rear = half_l + 1.0 + cfg.safety_rear_headway * vv
    omega = (np.exp(-t / 2.0) * (t > 0) * (t <= cfg.safety_time + 1e-6)).astype(F32)
    u_lon = ((dS > -front) & (dS < rear)) * omega
    u_lat = (np.abs(dD) < half_w + cfg.safety_margin_lat) * lead_or_side
    risk = u_lat.transpose(1, 0, 2).reshape(J, M * T) @ u_lon.transpose(1, 0, 2).reshape(L, M * T).T
    return VehicleTerms(prox.astype(F32), coll, risk.astype(F32))
