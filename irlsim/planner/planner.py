"""The planner: ``Planner(road, cfg).plan(obs) -> PolicySet``, one call per planning cycle (0.2 s).

See :mod:`irlsim.planner.sampler` for how policies are sampled and :mod:`irlsim.planner.features` for
the 15 features. Sampling is reward-agnostic: the same stored set can be scored under any theta.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from irlsim.planner.config import PlannerConfig
from irlsim.planner.features import (
    Context,
    cross_features,
    lat_features,
    lon_features,
    vehicle_terms,
    weights,
)
from irlsim.planner.policy_set import PolicySet
from irlsim.planner.sampler import LatBank, LonBank, Sampler, concat_lat, select_pairs, stop_distances
from irlsim.road import HALF_ROAD, Road, wrap_angle
from irlsim.sim.types import Observation, Trajectory

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
        self.last: PlanInternals | None = None
        self.last_ms = 0.0

    # ------------------------------------------------------------------ main entry
    def plan(self, obs: Observation) -> PolicySet:
        """One planning cycle from ``obs``: exactly ``cfg.n_policies`` policies sorted by progress."""
        t0 = time.perf_counter()
        cfg, road, ego = self.cfg, self.road, obs.ego
        lap = obs.lap_length
        lon = self.sampler.lon_bank(ego.v, ego.a, stop_distances(obs, cfg))
        lat = concat_lat(self.sampler.lat_bank(ego.d, ego.d_dot, ego.d_ddot),
                         self.sampler.exit_bank(ego.d, ego.d_dot, ego.d_ddot, ego.s, lon))
        L = len(lon.v)
        s_abs = ego.s + lon.s  # [L, T]
        kappa = road.curvature(s_abs)
        stop_rel = obs.stop_s - ego.s if np.isfinite(obs.stop_s) else np.inf
        ctx = Context(
            s_ego=ego.s, d0=ego.d, goal=obs.target_s - ego.s + cfg.progress_lookahead,
            target_rel=obs.target_s - ego.s,
            req_d=float(road.lane_center(road.checkpoints[obs.target_checkpoint].lane)),
            stop_rel=float(stop_rel), lap_length=lap,
        )
        f_lon, series = lon_features(lon, kappa, ctx, cfg, self.w)
        f_lat = lat_features(lat, lon, series, road, ctx, cfg, self.w)
        f_x = cross_features(lat, lon, series, ctx, self.w)
        veh = vehicle_terms(lat, lon, obs.vehicles, ctx, cfg, self.w, self._stop_lines)

        # ---- candidate pairs: free lateral profiles x all lon profiles, exit profiles x their bound one
        free = np.flatnonzero(lat.bound_lon < 0)
        bound = np.flatnonzero(lat.bound_lon >= 0)
        cj = np.concatenate([np.repeat(free, L), bound])
        cl = np.concatenate([np.tile(np.arange(L), len(free)), lat.bound_lon[bound]])
        feas_jl = self._feasible(lat, lon, kappa)
        feasible = feas_jl[cj, cl]
        essential = lat.keep[cj] | (lon.kind[cl] > 0) | (lat.bound_lon[cj] >= 0)
        pick = select_pairs(feasible, essential, cfg.n_policies)
        cj, cl = cj[pick], cl[pick]
        progress = lon.s[cl, -1].astype(F32)
        order = np.argsort(progress, kind="stable")
        cj, cl, progress = cj[order], cl[order], progress[order]

        # ---- trajectories [N, T]
        d = lat.d[cj]
        s = s_abs[cl]
        v = lon.v[cl]
        bx, by = road.to_xy(s_abs, np.zeros_like(s_abs))
        nx, ny = road.to_xy(s_abs, np.ones_like(s_abs))
        nx, ny = nx - bx, ny - by
        x = bx[cl] + nx[cl] * d
        y = by[cl] + ny[cl] * d
        head = road.heading(s_abs)
        dd = lat.dd[cj].astype(F32)
        # head is wrapped and |psi| < pi/2: one conditional shift wraps the sum (cheaper than a modulo)
        yaw = head[cl] + np.arctan2(dd, np.maximum(v, 1e-3).astype(F32))
        yaw[yaw >= np.pi] -= 2 * np.pi
        yaw[yaw < -np.pi] += 2 * np.pi
        lane = road.lane_of_d(d)

        # ---- features, labels
        feats = f_lon[cl] + f_lat[cj] + f_x[cj, cl]
        feats[:, 14] = veh.proximity[cj, cl]
        np.maximum(feats, 0.0, out=feats)
        offroad_j = self._offroad(lat, lon, ego.s)
        exit_j = (lat.bound_lon >= 0) & (lat.d.min(axis=1) < -HALF_ROAD)
        labels = np.stack([veh.collision[cj, cl], offroad_j[cj], exit_j[cj]], axis=1)

        # ---- control points and actions [N, K, .]
        cols = self.cp_cols
        cp = np.stack([
            lat.d[:, cols][cj] - ego.d,
            wrap_angle(yaw[:, cols] - ego.yaw),
            lon.s[:, cols][cl],
        ], axis=2).astype(F32)
        actions = np.stack([lon.a[:, cols][cl], lat.dd[:, cols][cj]], axis=2).astype(F32)

        ps = PolicySet(
            t=ego.t, x=x, y=y, yaw=yaw.astype(np.float64), v=v, s=s, d=d, lane=lane,
            progress=progress, features=feats.astype(F32), control_points=cp, actions=actions,
            labels=labels,
        )
        self.last = PlanInternals(
            obs=obs, lon=lon, lat=lat, lon_idx=cl, lat_idx=cj, risk=veh.risk[cj, cl],
            exit_profile=lat.bound_lon[cj] >= 0, kind=lon.kind[cl],
            a=lon.a[cl].astype(F32), d_dot=dd, d_ddot=lat.ddd[cj].astype(F32),
        )
        self.last_ms = (time.perf_counter() - t0) * 1e3
        return ps

    # ------------------------------------------------------------------ helpers
    def _feasible(self, lat: LatBank, lon: LonBank, kappa: np.ndarray) -> np.ndarray:
        """[J, L] bool: total lateral acceleration and heading (slip) limits. Exact where a cheap bound
        cannot decide."""
        cfg = self.cfg
        c = lon.v * lon.v * kappa  # [L, T]
        lat_acc_bound = np.abs(lat.ddd).max(axis=1)[:, None] + np.abs(c).max(axis=1)[None, :]
        slip_need = np.abs(lat.dd).max(axis=1)[:, None]
        slip_have = np.tan(cfg.max_slip) * lon.v.min(axis=1)[None, :] + 0.05
        ok = (lat_acc_bound <= cfg.a_lat_max) & (slip_need <= slip_have)
        unsure = np.argwhere(~ok)
        if len(unsure):
            j, l = unsure[:, 0], unsure[:, 1]
            acc = np.abs(lat.ddd[j] + c[l]).max(axis=1) <= cfg.a_lat_max
            slip = (np.abs(lat.dd[j]) <= np.tan(cfg.max_slip) * lon.v[l] + 0.05).all(axis=1)
            ok[j, l] = acc & slip
        return ok

    def _offroad(self, lat: LatBank, lon: LonBank, s_ego: float) -> np.ndarray:
        """[J] bool: the ego's body beyond the drivable area (ramps included) at some step."""
        cfg = self.cfg
        left = (lat.d + cfg.ego_width / 2 > HALF_ROAD + 0.2).any(axis=1)
        right_edge = np.full(len(lat.d), -HALF_ROAD)[:, None] * np.ones_like(lat.d)
        bound = lat.bound_lon >= 0
        if bound.any():
            right_edge[bound] = self.road.drivable_right_edge(s_ego + lon.s[lat.bound_lon[bound]])
        right = (lat.d - cfg.ego_width / 2 < right_edge - 0.2).any(axis=1)
        return left | right

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
        yaw = wrap_angle(self.road.heading(s) + np.arctan2(p.lat.dd[j], np.maximum(v, 1e-3)))
        return Trajectory(
            t0=ego.t, dt=self.cfg.dt, x=x, y=y, yaw=yaw, v=v.copy(), a=p.lon.a[l].copy(), s=s, d=d.copy(),
            d_dot=p.lat.dd[j].copy(), d_ddot=p.lat.ddd[j].copy(), lane=self.road.lane_of_d(d),
        )
