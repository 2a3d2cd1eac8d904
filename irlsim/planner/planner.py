"""The planner: ``Planner(road, cfg).plan(obs) -> PolicySet``, one call per planning cycle (0.2 s).

See :mod:`irlsim.planner.sampler` for how policies are sampled and :mod:`irlsim.planner.features` for
the 15 features. Sampling is reward-agnostic: the same stored set can be scored under any theta.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from irlsim.planner.config import PlannerConfig
from irlsim.planner.features import (
    CROSS_COLS,
    IDX,
    Context,
    Pairs,
    cross_features,
    lat_features,
    lon_features,
    vehicle_terms,
    weights,
)
from irlsim.planner.policy_set import LazyWorld, PolicySet
from irlsim.planner.sampler import LatBank, LonBank, Sampler, concat_lat, select_pairs, stop_distances
from irlsim.road import Road, wrap_angle
from irlsim.road.angles import atan
from irlsim.sim.types import PATH_STEP, EgoState, Observation, Trajectory, VehicleStates

F32 = np.float32


@dataclass
class PlanInternals:
    """What one ``plan`` call built besides the PolicySet (for drivers, tests and plots)."""

    obs: Observation
    lon: LonBank
    lat: LatBank
    lon_idx: np.ndarray  # [N] index into the lon bank, in the PolicySet's (sorted) order
    lat_idx: np.ndarray  # [N]
    risk: np.ndarray  # [N] float32: time-weighted intrusion into the safety zone of a vehicle (0 = safe)
    exit_profile: np.ndarray  # [N] bool: an exit-taking profile (whether or not it leaves the loop in 5 s)
    kind: np.ndarray  # [N] int8: lon kind (0 sampled, 1 cruise / reach v_target, 2 stop)
    a: np.ndarray  # [N, T] longitudinal acceleration (float32)
    d_dot: np.ndarray  # [N, T] (float32)
    d_ddot: np.ndarray  # [N, T] (float32)


class _World:
    """World-frame x / y / yaw of a PolicySet, computed on first read (``LazyWorld``): most cycles
    nobody reads them, and they are most of a cycle's cost. Holds the cycle's arrays, not the road's
    SUMO network: the road is dropped once everything is computed (and before pickling)."""

    def __init__(
        self,
        road: Road,
        s_abs: np.ndarray,
        lon_idx: np.ndarray,
        d: np.ndarray,
        v: np.ndarray,
        dd: np.ndarray,
        v_floor: float,
    ):
        self.road, self.s_abs, self.cl, self.d, self.v, self.dd = road, s_abs, lon_idx, d, v, dd
        self.v_floor = v_floor
        self.shape = d.shape

    def xy(self) -> tuple[np.ndarray, np.ndarray]:
        """x, y [N, T] float64: the reference point of each lon state plus d times the frame normal
        (computed per lon profile [L, T], then gathered)."""
        road, s_abs, cl = self.road, self.s_abs, self.cl
        bx, by = road.to_xy(s_abs, np.zeros_like(s_abs))
        nx, ny = road.to_xy(s_abs, np.ones_like(s_abs))
        nx, ny = nx - bx, ny - by
        return bx[cl] + nx[cl] * self.d, by[cl] + ny[cl] * self.d

    def yaw(self) -> np.ndarray:
        """yaw [N, T] float64: reference heading plus the heading to the lane, atan(d_dot / v)."""
        head = self.road.heading(self.s_abs)
        return policy_yaw(head[self.cl], self.dd, self.v, self.v_floor)

    def __getstate__(self) -> dict:
        raise TypeError("a lazy PolicySet source is not picklable; PolicySet materialises it first")


def policy_yaw(head: np.ndarray, dd: np.ndarray, v: np.ndarray, v_floor: float) -> np.ndarray:
    """World yaw [rad, float64] from the reference heading ``head`` (wrapped, float64), d_dot ``dd``
    (float32) and v (float64), elementwise: head + atan2(d_dot, max(v, v_floor)), wrapped to [-pi, pi).
    ``v_floor`` is ``PlannerConfig.yaw_speed_floor``: a car that barely moves does not turn its body by a
    slow lateral drift.

    atan2(y, x) with x > 0 is atan(y / x), by :func:`irlsim.road.angles.atan`: numpy's own rounds otherwise
    on an AVX-512 CPU, and the same collection would write other bytes there."""
    yaw = head + atan(dd / np.maximum(v, v_floor).astype(F32))
    # head is wrapped and |psi| < pi/2: one conditional shift wraps the sum (cheaper than a modulo)
    yaw[yaw >= np.pi] -= 2 * np.pi
    yaw[yaw < -np.pi] += 2 * np.pi
    return yaw


class Planner:
    """Samples ``cfg.n_policies`` policies per cycle and computes their features, control points,
    actions and labels. ``plan`` is deterministic; its wall time is kept in ``last_ms``."""

    def __init__(self, road: Road, cfg: PlannerConfig | None = None):
        self.road = road
        self.cfg = cfg or PlannerConfig()
        self.cfg.validate()
        self.sampler = Sampler(road, self.cfg)
        self.w = weights(self.cfg)
        T = self.cfg.n_steps
        step = (T - 1) // self.cfg.n_control_points
        self.cp_cols = np.arange(step, T, step)  # [K] columns of the control points
        self._stop_lines = tuple(float(sl.s) for sl in road.stop_lines)
        self._feas_block = 10  # steps per block of the feasibility pre-test
        self.last: PlanInternals | None = None
        self.last_ms = 0.0

    # ------------------------------------------------------------------ main entry
    # size-ok: one vectorised pass over the cycle (sample, features, labels), read top to bottom
    def plan(self, obs: Observation) -> PolicySet:
        """One planning cycle from ``obs``: exactly ``cfg.n_policies`` policies sorted by progress."""
        t0 = time.perf_counter()
        cfg, road, ego = self.cfg, self.road, obs.ego
        lap = obs.lap_length
        # the road's speed limit (and a turn's speed) over the reach of the horizon, where it is below
        # the target speed
        reach = ego.s + cfg.horizon * max(ego.v, cfg.v_target)
        v_cap = min(road.speed_limit_over(ego.s, reach), road.turn_speed_over(ego.s, reach))
        cfg_c = cfg if v_cap >= cfg.v_target else dataclasses.replace(cfg, v_target=v_cap)
        lon = self.sampler.lon_bank(
            ego.v, ego.a, stop_distances(obs, cfg, road), None if cfg_c is cfg else v_cap
        )
        lanes = lane_window(road, ego.s, lon.s) if road.lanes_vary else None
        targets = None if lanes is None else lane_targets(road, lanes, ego.d)
        lat = concat_lat(
            self.sampler.lat_bank(ego.d, ego.d_dot, ego.d_ddot, targets),
            self.sampler.exit_bank(ego.d, ego.d_dot, ego.d_ddot, ego.s, lon),
        )
        L = len(lon.v)
        s_abs = ego.s + lon.s  # [L, T]
        kappa = road.curvature(s_abs)
        stop_rel = obs.stop_s - ego.s if np.isfinite(obs.stop_s) else np.inf
        ctx = Context(
            s_ego=ego.s,
            d0=ego.d,
            goal=obs.target_s - ego.s + cfg.progress_lookahead,
            target_rel=obs.target_s - ego.s,
            req_d=float(road.lane_center(road.required_lane(obs.target_checkpoint, ego.d))),
            stop_rel=float(stop_rel),
            lap_length=lap,
            lane_width=road.lane_width,
            lanes=lanes,
            stop_red=obs.stop_red,
        )
        # ---- candidate pairs: free lateral profiles x all lon profiles, exit profiles x their bound one.
        # Pairwise terms are vectors over the C candidates (see Pairs), gathered at the picked ones.
        pairs = Pairs.of(lat, L)
        f_lon, series = lon_features(lon, kappa, ctx, cfg_c, self.w)
        f_lat = lat_features(lat, lon, series, road, ctx, cfg, self.w)
        f_x = cross_features(lat, lon, series, ctx, self.w, pairs, cfg.yaw_speed_floor)
        boxes = route_frame_boxes(road, obs.vehicles, ego, np.arange(cfg.n_steps) * cfg.dt)
        veh = vehicle_terms(lat, lon, boxes, ctx, cfg, self.w, self._stop_lines, pairs)

        cj, cl = pairs.lat_idx(), pairs.lon_idx()
        feasible = self._feasible(lat, lon, kappa, pairs)
        essential = lat.keep[cj] | (lon.kind[cl] > 0) | (lat.bound_lon[cj] >= 0)
        pick = select_pairs(feasible, essential, cfg.n_policies)
        cj, cl = cj[pick], cl[pick]
        progress = lon.s[cl, -1].astype(F32)
        order = np.argsort(progress, kind="stable")
        sel = pick[order]  # candidate index of each policy
        cj, cl, progress = cj[order], cl[order], progress[order]

        # ---- trajectories [N, T] (x, y, yaw on first read: _World)
        d = lat.d[cj]
        s = s_abs[cl]
        v = lon.v[cl]
        dd_f = lat.dd.astype(F32)
        dd = dd_f[cj]
        lane = road.lane_of_d(lat.d)[cj]  # per lateral profile, then gathered

        # ---- features, labels
        feats = f_lon[cl] + f_lat[cj]
        feats[:, CROSS_COLS] += f_x[sel]
        feats[:, IDX["proximity"]] = veh.proximity[sel]
        np.maximum(feats, 0.0, out=feats)
        if lanes is None:
            offroad = self._offroad(lat, lon, ego.s)[cj]
        else:  # where lanes end or begin, the lanes that exist where each lon profile is
            offroad = self._offroad_pairs(lat, lon, ego.s, pairs)[sel]
        exit_j = (lat.bound_lon >= 0) & (lat.d.min(axis=1) < -road.half_road)
        labels = np.stack([veh.collision[sel], offroad, exit_j[cj]], axis=1)

        # ---- control points and actions [N, K, .]; the yaw at the K columns only
        cols = self.cp_cols
        s_cols = s_abs[:, cols]
        yaw_cols = policy_yaw(
            road.heading(s_cols)[cl], dd_f[:, cols][cj], lon.v[:, cols][cl], cfg.yaw_speed_floor
        )
        rel_yaw = yaw_cols - ego.yaw  # both in [-pi, pi): one conditional shift wraps it
        rel_yaw[rel_yaw >= np.pi] -= 2 * np.pi
        rel_yaw[rel_yaw < -np.pi] += 2 * np.pi
        cp = np.empty((len(cj), len(cols), 3), F32)
        cp[:, :, 0] = lat.d[:, cols][cj] - ego.d
        cp[:, :, 1] = rel_yaw
        cp[:, :, 2] = lon.s[:, cols][cl]
        actions = np.empty((len(cj), len(cols), 2), F32)
        actions[:, :, 0] = lon.a[:, cols][cl]
        actions[:, :, 1] = lat.dd[:, cols][cj]

        world = LazyWorld(_World(road, s_abs, cl, d, v, dd, cfg.yaw_speed_floor))
        ps = PolicySet(
            t=ego.t,
            x=world,  # type: ignore[arg-type]  # LazyWorld: computed on first read
            y=world,  # type: ignore[arg-type]
            yaw=world,  # type: ignore[arg-type]
            v=v,
            s=s,
            d=d,
            lane=lane,
            progress=progress,
            features=feats.astype(F32),
            control_points=cp,
            actions=actions,
            labels=labels,
        )
        self.last = PlanInternals(
            obs=obs,
            lon=lon,
            lat=lat,
            lon_idx=cl,
            lat_idx=cj,
            risk=veh.risk[sel],
            exit_profile=lat.bound_lon[cj] >= 0,
            kind=lon.kind[cl],
            a=lon.a.astype(F32)[cl],
            d_dot=dd,
            d_ddot=lat.ddd.astype(F32)[cj],
        )
        self.last_ms = (time.perf_counter() - t0) * 1e3
        return ps

    # ------------------------------------------------------------------ helpers
    def _feasible(self, lat: LatBank, lon: LonBank, kappa: np.ndarray, pairs: Pairs) -> np.ndarray:
        """[C] bool over the candidate pairs: total lateral acceleration |d_ddot + v^2 kappa| <= a_lat_max
        and heading (slip) |d_dot| <= tan(max_slip) v + 0.05 at every step.

        Exact. A cheap sufficient test first, on blocks of steps (per block: max |d_ddot| + max |v^2 kappa|,
        and max |d_dot| against the smallest allowed one; float rounding is monotone, so a pair passing it
        passes the exact test); the exact per-step test only for the pairs it cannot decide."""
        cfg = self.cfg
        T = lon.v.shape[1]
        c = lon.v * lon.v * kappa  # [L, T]
        have = math.tan(cfg.max_slip) * lon.v + 0.05  # [L, T]
        abs_ddd, abs_dd = np.abs(lat.ddd), np.abs(lat.dd)
        edges = np.arange(0, T, self._feas_block)
        mx_ddd = np.maximum.reduceat(abs_ddd, edges, axis=1)  # [J, B]
        mx_dd = np.maximum.reduceat(abs_dd, edges, axis=1)
        mx_c = np.maximum.reduceat(np.abs(c), edges, axis=1)  # [L, B]
        mn_have = np.minimum.reduceat(have, edges, axis=1)
        jf = pairs.free
        ok_grid = (
            ((mx_ddd[jf][:, None, :] + mx_c[None, :, :]) <= cfg.a_lat_max)
            & (mx_dd[jf][:, None, :] <= mn_have[None, :, :])
        ).all(axis=2)
        ok = ok_grid.ravel()
        if not pairs.all_free:
            jb, lb = pairs.bound_j, pairs.bound_l
            ok_b = (((mx_ddd[jb] + mx_c[lb]) <= cfg.a_lat_max) & (mx_dd[jb] <= mn_have[lb])).all(axis=1)
            ok = np.concatenate([ok, ok_b])
        unsure = np.flatnonzero(~ok)
        if len(unsure):
            j, l = pairs.lat_idx()[unsure], pairs.lon_idx()[unsure]
            # cheap exact witnesses of infeasibility: the per-step test at the step of each lateral
            # profile's largest |d_dot| and largest |d_ddot| (the same operations as the full test)
            tw = np.argmax(abs_dd, axis=1)[j]
            ta = np.argmax(abs_ddd, axis=1)[j]
            bad = (abs_dd[j, tw] > have[l, tw]) | (np.abs(lat.ddd[j, ta] + c[l, ta]) > cfg.a_lat_max)
            ok[unsure[bad]] = False
            keep = ~bad
            unsure, j, l = unsure[keep], j[keep], l[keep]
            acc = np.abs(lat.ddd[j] + c[l]).max(axis=1) <= cfg.a_lat_max
            slip = (abs_dd[j] <= have[l]).all(axis=1)
            ok[unsure] = acc & slip
        return ok

    def _offroad(self, lat: LatBank, lon: LonBank, s_ego: float) -> np.ndarray:
        """[J] bool, on a road with the same lanes throughout: the ego's body beyond the drivable area
        (ramps included) at some step. Where lanes are added or dropped: :meth:`_offroad_pairs`."""
        cfg = self.cfg
        half = self.road.half_road
        left = (lat.d + cfg.ego_width / 2 > half + 0.2).any(axis=1)
        right_edge = np.full(len(lat.d), -half)[:, None] * np.ones_like(lat.d)
        bound = lat.bound_lon >= 0
        if bound.any():
            right_edge[bound] = self.road.drivable_right_edge(s_ego + lon.s[lat.bound_lon[bound]])
        right = (lat.d - cfg.ego_width / 2 < right_edge - 0.2).any(axis=1)
        return left | right

    def _offroad_pairs(self, lat: LatBank, lon: LonBank, s_ego: float, pairs: Pairs) -> np.ndarray:
        """[C] bool over the candidate pairs where lanes are added or dropped: the ego's body beyond the
        lanes that exist where the pair's lon profile is at some step (a policy that stands in a lane
        before it ends stays on the road; one that drives on in it past its end does not)."""
        cfg, road = self.cfg, self.road
        half_w = road.lane_width / 2
        lo, hi = road.lane_bounds(s_ego + lon.s)  # [L, T]
        right = road.lane_center(lo) - half_w - 0.2 + cfg.ego_width / 2  # the body's centre limits
        left = road.lane_center(hi) + half_w + 0.2 - cfg.ego_width / 2
        d = lat.d[pairs.free]
        grid = ((d[:, None, :] < right[None]) | (d[:, None, :] > left[None])).any(axis=2).ravel()
        if pairs.all_free:
            return grid
        jb, lb = pairs.bound_j, pairs.bound_l
        edge = road.drivable_right_edge(s_ego + lon.s[lb]) + cfg.ego_width / 2 - 0.2
        tail = ((lat.d[jb] < edge) | (lat.d[jb] > left[lb])).any(axis=1)
        return np.concatenate([grid, tail])

    def trajectory(self, i: int) -> Trajectory:
        """Policy ``i`` of the last PolicySet as a :class:`Trajectory` (what a driver returns)."""
        if self.last is None:
            raise RuntimeError("Planner.trajectory: call plan() first")
        p = self.last
        j, l = int(p.lat_idx[i]), int(p.lon_idx[i])
        ego = p.obs.ego
        s = ego.s + p.lon.s[l]
        d = p.lat.d[j]
        v = p.lon.v[l]
        bx, by = self.road.to_xy(s, np.zeros_like(s))
        nx, ny = self.road.to_xy(s, np.ones_like(s))
        x = bx + (nx - bx) * d
        y = by + (ny - by) * d
        yaw = policy_yaw(self.road.heading(s), p.lat.dd[j], v, self.cfg.yaw_speed_floor)
        return Trajectory(
            t0=ego.t,
            dt=self.cfg.dt,
            x=x,
            y=y,
            yaw=yaw,
            v=v.copy(),
            a=p.lon.a[l].copy(),
            s=s,
            d=d.copy(),
            d_dot=p.lat.dd[j].copy(),
            d_ddot=p.lat.ddd[j].copy(),
            lane=self.road.lane_of_d(d),
        )


def lane_window(road: Road, s_ego: float, lon_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lowest, highest) lane [T] the policies may use at each step where lanes are added or dropped:
    those that exist both where the slowest and where the fastest longitudinal profile is at that step
    (``lon_s`` [L, T] relative to ``s_ego``), so no policy is sent into a lane that ends before it gets
    there or that has not begun yet. Where the two share no lane, the fastest profile's lanes."""
    lo_n, hi_n = road.lane_bounds(s_ego + lon_s.min(axis=0))
    lo_f, hi_f = road.lane_bounds(s_ego + lon_s.max(axis=0))
    lo, hi = np.maximum(lo_n, lo_f), np.minimum(hi_n, hi_f)
    none = lo > hi
    return np.where(none, lo_f, lo), np.where(none, hi_f, hi)


#: [rad] a vehicle turned further than this to the route (turning, crossing, standing on another approach
#: to a junction) is seen as its rotated box's extent in the route frame; below it, as its own box (on the
#: oval no vehicle turns further than 3 degrees: measured over three 200 s drives, so its bytes are kept)
BOX_TURN_MIN = 0.15


#: [m] on a route that comes back near itself, a vehicle this close to the ego but placed on another pass
#: of the route (far along it) is seen on the ego's pass
OTHER_PASS_REACH = 40.0


def route_frame_boxes(
    road: Road, vehicles: VehicleStates, ego: EgoState | None = None, t: np.ndarray | None = None
) -> VehicleStates:
    """``vehicles`` as the planner's collision and proximity terms see them, boxes aligned with the route
    frame: a vehicle turned by theta > :data:`BOX_TURN_MIN` to the route's heading at its position gets the
    extent of its body's four corners in the route frame, so that a car standing at an angle beside a
    junction is not thinner, in the frame, than it is (on a straight stretch: length L|cos| + W|sin|, width
    L|sin| + W|cos| about the body's centre), and a car following its own lane through a tight turn, at an
    angle to the route's reference there, is not wider than it is. Where a
    route passes a place twice, a vehicle within OTHER_PASS_REACH of the ``ego``
    that the frame puts on the other pass (further along the route than it is away) is projected onto the
    ego's pass: at a junction both passes share, it stands beside the ego, not a lap away. With the
    horizon's times ``t`` [T] [s], a turned vehicle that has a way into the route (``path``: inside a
    junction, bound for the route's edge) gets its box's ``motion`` along it at its speed
    (:func:`path_motion`)."""
    if not vehicles.count:
        return vehicles
    if ego is not None:
        lap = road.lap_length
        ds = (vehicles.s - ego.s + lap / 2) % lap - lap / 2
        dist = np.hypot(vehicles.x - ego.x, vehicles.y - ego.y)
        other = np.flatnonzero((dist < OTHER_PASS_REACH) & (np.abs(ds) > dist + OTHER_PASS_REACH))
        if len(other):
            s2, d2 = road.project_near(vehicles.x[other], vehicles.y[other], ego.s)
            here = np.abs((s2 - ego.s + lap / 2) % lap - lap / 2) <= dist[other] + OTHER_PASS_REACH
            if here.any():  # on the ego's pass, within the road there (else it keeps its own place)
                s_new, d_new = vehicles.s.copy(), vehicles.d.copy()
                s_new[other[here]], d_new[other[here]] = s2[here], d2[here]
                vehicles = dataclasses.replace(vehicles, s=s_new, d=d_new)
    theta = wrap_angle(vehicles.yaw - road.heading(vehicles.s))
    turned = np.abs(theta) > BOX_TURN_MIN
    if not turned.any():
        return vehicles
    k = np.flatnonzero(turned)
    lap = road.lap_length
    # the body's corners (x, y is the front bumper's centre), in the frame by each vehicle's own place
    yaw, ln, wd = vehicles.yaw[k], vehicles.length[k], vehicles.width[k]
    back, side = np.array([0.0, 0.0, 1.0, 1.0]), np.array([0.5, -0.5, 0.5, -0.5])
    along, across = -back[None, :] * ln[:, None], side[None, :] * wd[:, None]  # [K, 4] in the body's frame
    cx = vehicles.x[k, None] + along * np.cos(yaw)[:, None] - across * np.sin(yaw)[:, None]
    cy = vehicles.y[k, None] + along * np.sin(yaw)[:, None] + across * np.cos(yaw)[:, None]
    cs, cd = road.to_frenet(cx, cy, near=vehicles.s[k, None])  # near: broadcast over the corners
    ds = (cs - vehicles.s[k, None] + lap / 2) % lap - lap / 2  # [K, 4] about the vehicle's own s
    s_new, d_new = vehicles.s.copy(), vehicles.d.copy()
    length, width = vehicles.length.copy(), vehicles.width.copy()
    s_new[k] = (vehicles.s[k] + ds.max(axis=1)) % lap
    d_new[k] = (cd.min(axis=1) + cd.max(axis=1)) / 2
    length[k], width[k] = ds.max(axis=1) - ds.min(axis=1), cd.max(axis=1) - cd.min(axis=1)
    motion = None
    if t is not None and vehicles.path is not None:
        k = k[np.isfinite(vehicles.path[k, 0, 0])]
        if len(k):
            motion = np.full((vehicles.count, len(t), 2), np.nan)
            motion[k] = path_motion(road, vehicles.path[k], vehicles.v[k], vehicles.s[k], t)
    return dataclasses.replace(vehicles, s=s_new, d=d_new, length=length, width=width, motion=motion)


def path_motion(road: Road, path: np.ndarray, v: np.ndarray, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """[K, T, 2] (s, d) [m] displacement in the route frame of K vehicles going along their ``path``
    ([K, P, 2] xy, a point every :data:`irlsim.sim.types.PATH_STEP` metres from the front) at their
    speed ``v`` [K] over the times ``t`` [T]; ``s`` [K] their route positions (where each lies, on a
    route that comes back near itself)."""
    at = np.clip(v[:, None] * np.asarray(t, np.float64)[None, :] / PATH_STEP, 0.0, path.shape[1] - 1.0)
    i0 = np.minimum(at.astype(int), path.shape[1] - 2)
    f = (at - i0)[..., None]
    rows = np.arange(len(path))[:, None]
    xy = path[rows, i0] * (1.0 - f) + path[rows, i0 + 1] * f  # [K, T, 2]
    ps, pd = road.to_frenet(xy[..., 0], xy[..., 1], near=np.broadcast_to(s[:, None], at.shape))
    lap = road.lap_length
    return np.stack([(ps - ps[:, :1] + lap / 2) % lap - lap / 2, pd - pd[:, :1]], axis=-1)


def lane_targets(road: Road, lanes: tuple[np.ndarray, np.ndarray], d0: float) -> np.ndarray:
    """Lane centres [m] the lateral profiles may end in where lanes are added or dropped: those of
    :func:`lane_window` at the horizon, and the ego's own lane, so that a policy may stay and stand in it
    where it does not go on (behind a queue before a junction) instead of every one changing lanes."""
    own = road.lane_of_d(np.array([d0]))[0]
    own = int(np.clip(own, lanes[0][0], lanes[1][0]))
    ids = np.union1d(np.arange(lanes[0][-1], lanes[1][-1] + 1), [own])
    return road.lane_centres[ids]
