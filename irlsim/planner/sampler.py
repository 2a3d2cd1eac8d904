"""Reward-agnostic sampling of ~2,500 policies per cycle in the route frame, fully vectorised.

Structure (why it is fast): a policy is a pair (lateral profile j, longitudinal profile l). Longitudinal
profiles (s, v, a over time) and lateral profiles (d over time) are sampled separately as small banks
(L ~ 80 and J ~ 40 profiles of T = 51 states) and combined by index arrays ``lon_idx``, ``lat_idx`` [N].
Every feature is lon-only, lat-only, or a sum over time of products of a lateral and a longitudinal
series, which is an exact [J, T] @ [T, L] matrix product (proximity and the collision label too, since
exp(-a - b) = exp(-a) exp(-b) and a box test is a product of two interval tests). So the cost is
O((J + L) T M) plus O(N T) gathers, not O(N T M). Exit-taking profiles, whose offset follows the ramp
and so depends on s, are lateral profiles bound to one longitudinal profile each.

Longitudinal actions (two stages, [0, split] and [split, horizon], the split ``cfg.lon_stage_split``): a
target acceleration per stage (``cfg.accels_stage1/2`` plus "reach v_target"), reached from the current
acceleration by a cubic smoothstep of ``cfg.accel_ramp`` seconds, so a(t) is continuous and starts at the
ego's a; v is clamped at 0 (a car that stops stands). Plus up to three quintic stop profiles that bring
the front bumper to rest exactly ``cfg.stop_margin`` before an active stop line (fastest, middle,
gentlest feasible), up to three more that stand ``cfg.stop_line_gap`` before the line itself once that
stop point is closer than a comfortable stop (:func:`stop_distances`), and up to three behind the nearest
slow vehicle in each lane.

Lateral actions (two stages): a quintic from the ego's (d, d_dot, d_ddot) to a stage-1 target (lane
centres 0/1/2 with durations ``cfg.lat_durations``, staying at d, or a partial swerve of ``cfg.swerves``
off the current lane centre), then from the state at ``split`` a quintic to a stage-2 lane centre. Near
an exit (lane 0, ``cfg.exit_reach``) exit-taking profiles move to lane 0 and then follow the ramp.

Feasibility: |a| <= max(|a_min|, a_max) by construction, 0 <= v <= v_max, |d_ddot + v^2 kappa| <=
a_lat_max and |d_dot| <= tan(max_slip) v + 0.05 m/s; infeasible pairs are dropped. The count is then made
exactly ``cfg.n_policies``: essential pairs (lane keeping at every speed profile, every lateral profile
with cruise / reach-target / stop profiles, all exit-taking pairs) are kept, the others are subsampled
evenly; a small set is padded by repeating pairs. Policies are finally sorted by progress (stable).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from irlsim.planner.config import PlannerConfig
from irlsim.road import Road
from irlsim.sim.types import Observation

F32 = np.float32


def smoothstep(x: np.ndarray) -> np.ndarray:
    """Cubic 3x^2 - 2x^3 on [0, 1], 0 below, 1 above."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def quintic(
    p0: np.ndarray | float,
    v0: np.ndarray | float,
    a0: np.ndarray | float,
    p1: np.ndarray | float,
    dur: np.ndarray,
    t: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Quintic from (p0, v0, a0) at t = 0 to (p1, 0, 0) at t = dur, held at p1 afterwards.

    Parameters broadcast against each other ([P, 1]); ``t`` is [T]. Returns position, velocity,
    acceleration and jerk, each [P, T].
    """
    return _quintic(p0, v0, a0, p1, QuinticGrid(dur, t))


class QuinticGrid:
    """The powers of the duration and of the clipped time grid a :func:`quintic` needs; they depend
    only on (dur, t), so the sampler builds them once and reuses them every cycle."""

    def __init__(self, dur: np.ndarray | float, t: np.ndarray):
        T = dur
        self.T1, self.T2 = T, T**2
        self.T3, self.T4, self.T5 = 2 * T**3, 2 * T**4, 2 * T**5
        tt = np.minimum(t, T)
        self.inside = t < T
        self.t1, self.t2, self.t3, self.t4, self.t5 = tt, tt**2, tt**3, tt**4, tt**5


def _quintic(
    p0: np.ndarray | float,
    v0: np.ndarray | float,
    a0: np.ndarray | float,
    p1: np.ndarray | float,
    g: QuinticGrid,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`quintic` on a precomputed grid (the same operations, so the same values)."""
    h = p1 - p0
    T, T2 = g.T1, g.T2
    c3 = (20 * h - 12 * v0 * T - 3 * a0 * T2) / g.T3
    c4 = (-30 * h + 16 * v0 * T + 3 * a0 * T2) / g.T4
    c5 = (12 * h - 6 * v0 * T - a0 * T2) / g.T5
    tt, tt2, tt3, tt4 = g.t1, g.t2, g.t3, g.t4
    inside = g.inside
    p = p0 + v0 * tt + 0.5 * a0 * tt2 + c3 * tt3 + c4 * tt4 + c5 * g.t5
    v = np.where(inside, v0 + a0 * tt + 3 * c3 * tt2 + 4 * c4 * tt3 + 5 * c5 * tt4, 0.0)
    a = np.where(inside, a0 + 6 * c3 * tt + 12 * c4 * tt2 + 20 * c5 * tt3, 0.0)
    j = np.where(inside, 6 * c3 + 24 * c4 * tt + 60 * c5 * tt2, 0.0)
    return p, v, a, j


_HASH_W: dict[int, np.ndarray] = {}


def first_unique_rows(a: np.ndarray) -> np.ndarray:
    """Sorted indices of the first occurrence of each distinct row of ``a`` [P, T]: the same as
    ``np.sort(np.unique(a, axis=0, return_index=True)[1])``, ~10x faster. Rows are grouped by a
    random projection (identical rows give identical keys), then the grouping is verified exactly
    (falls back to ``np.unique(axis=0)`` on a key collision, which practically never happens)."""
    n, t = a.shape
    if n <= 1:
        return np.arange(n)
    w = _HASH_W.get(t)
    if w is None:
        w = np.random.default_rng(12345).uniform(0.5, 1.5, size=(t,))
        _HASH_W[t] = w
    key = (a * w).sum(axis=1)
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    if not np.array_equal(a, a[first[inv]]):
        _, first = np.unique(a, axis=0, return_index=True)
    return np.sort(first)


@dataclass
class LonBank:
    """L longitudinal profiles, each array [L, T] (s relative to the ego's s)."""

    s: np.ndarray
    v: np.ndarray
    a: np.ndarray
    kind: np.ndarray  # [L] int8: 0 sampled accelerations, 1 reach v_target / cruise, 2 stop at the line


@dataclass
class LatBank:
    """J lateral profiles, each array [J, T]: offset d and its time derivatives."""

    d: np.ndarray
    dd: np.ndarray
    ddd: np.ndarray
    dddd: np.ndarray
    target: np.ndarray  # [J] final target offset [m] (lat_overshoot)
    bound_lon: np.ndarray  # [J] int: the lon profile an exit profile is bound to; -1 = combines freely
    keep: np.ndarray  # [J] bool: the lane-keeping profile (essential)


class Sampler:
    """Builds the longitudinal and lateral banks of one cycle. Pure numpy, deterministic."""

    def __init__(self, road: Road, cfg: PlannerConfig):
        self.road = road
        self.cfg = cfg
        T = cfg.n_steps
        self.t = np.arange(T) * cfg.dt  # [T] s
        ts, tau = cfg.lon_stage_split, cfg.accel_ramp
        # acceleration basis: a(t) = a0 b0 + a1 b1 + a2 b2; integrals by a fine trapezoid, exact enough
        fine = np.linspace(0.0, cfg.horizon, (T - 1) * 50 + 1)
        fb = self._basis(fine, ts, tau)
        cum = np.concatenate(
            [np.zeros((3, 1)), np.cumsum(0.5 * (fb[:, 1:] + fb[:, :-1]) * (fine[1] - fine[0]), axis=1)],
            axis=1,
        )
        self._b = self._basis(self.t, ts, tau)  # [3, T]
        self._B = cum[:, ::50]  # [3, T]  integral of each basis function from 0 to t
        self._i_split = int(round(cfg.stage_split / cfg.dt))  # the lateral actions' split
        self._i_lon_split = int(round(ts / cfg.dt))
        # cached quintic grids (they depend on the configuration only)
        self._stop_durs = np.geomspace(0.3, 30.0, 64)[:, None]
        self._stop_durs_f = np.geomspace(0.3, 30.0, 256)[:, None]
        frac = np.linspace(0.0, 1.0, 101)[None, :]
        self._stop_grid = QuinticGrid(self._stop_durs, frac * self._stop_durs)
        self._stop_grid_f = QuinticGrid(self._stop_durs_f, frac * self._stop_durs_f)
        self._lat_grids: dict[tuple[float, ...], QuinticGrid] = {}
        t2 = np.maximum(self.t - self.t[self._i_split], 0.0)[None, :]
        self._lat_grid2 = QuinticGrid(cfg.horizon - cfg.stage_split, t2)
        self._late = self.t[None, :] > self.t[self._i_split]
        self._exit_grid = QuinticGrid(cfg.stage_split, self.t[None, :])

    def _lat_grid(self, durs: np.ndarray) -> QuinticGrid:
        """Grid of the stage-1 lateral quintics for a [P, 1] column of durations (cached by value)."""
        key = tuple(durs[:, 0].tolist())
        g = self._lat_grids.get(key)
        if g is None:
            if len(self._lat_grids) > 64:
                self._lat_grids.clear()
            g = self._lat_grids[key] = QuinticGrid(durs, self.t[None, :])
        return g

    @staticmethod
    def _basis(t: np.ndarray, ts: float, tau: float) -> np.ndarray:
        h1 = smoothstep(t / tau)
        h2 = smoothstep((t - ts) / tau)
        return np.stack([1.0 - h1, h1 - h2, h2])

    # ------------------------------------------------------------------ longitudinal
    def lon_bank(
        self, v0: float, a0: float, stops: tuple[float, ...] = (), v_target: float | None = None
    ) -> LonBank:
        """Longitudinal profiles from speed ``v0`` [m/s], acceleration ``a0`` [m/s^2].

        ``stops`` [m]: distances from the ego's front bumper to points where it may have to stand (the
        active stop line, the tail of a standing queue); each within ``stop_reach`` gets stop profiles.
        ``v_target`` [m/s]: the speed to reach, below the config's where the road's limit is lower.
        """
        cfg = self.cfg if v_target is None else dataclasses.replace(self.cfg, v_target=v_target)
        a0 = float(np.clip(a0, cfg.a_min, cfg.a_max))
        b, B = self._b, self._B
        isp = self._i_lon_split
        a1 = np.array(list(cfg.accels_stage1) + [np.nan])
        # 'reach v_target' at the end of stage 1 (nan marks it): v(ts) = v0 + a0 B0 + a1 B1
        a1[-1] = (cfg.v_target - v0 - a0 * B[0, isp]) / B[1, isp]
        a1 = np.clip(a1, cfg.a_min, cfg.a_max)
        n1 = len(a1)
        a2_fixed = np.array(cfg.accels_stage2)
        A1 = np.repeat(a1, len(a2_fixed) + 1)
        A2 = np.tile(np.append(a2_fixed, np.nan), n1)
        # 'reach v_target' at the horizon: v(T) = v0 + a0 B0(T) + a1 B1(T) + a2 B2(T)
        reach = np.isnan(A2)
        A2[reach] = (cfg.v_target - v0 - a0 * B[0, -1] - A1[reach] * B[1, -1]) / B[2, -1]
        A2 = np.clip(A2, cfg.a_min, cfg.a_max)
        # kind 1 (essential): reach v_target in both stages, or cruise at the current acceleration 0
        row_reach = np.arange(len(A1)) // (len(a2_fixed) + 1) == n1 - 1
        cruise = (~row_reach) & (~reach) & (A1 == 0.0) & (A2 == 0.0)
        kind = np.where((row_reach & reach) | cruise, 1, 0).astype(np.int8)
        a_raw = a0 * b[0] + A1[:, None] * b[1] + A2[:, None] * b[2]  # [L, T]
        v_raw = v0 + a0 * B[0] + A1[:, None] * B[1] + A2[:, None] * B[2]
        # a car that reaches standstill stands until its acceleration turns positive
        stopped = np.minimum.accumulate(v_raw, axis=1) <= 0.0
        v = np.maximum(v_raw, 0.0)
        a = np.where(stopped & (v_raw <= 0.0), 0.0, a_raw)
        ok = v.max(axis=1) <= max(cfg.v_max, v0 + 1e-6)
        if not ok.any():  # above v_max and still speeding up (a driver the planner did not drive): the
            # profiles that add no speed to what the initial acceleration, common to all, adds
            ok = v.max(axis=1) <= v0 + max(0.0, float((a0 * B[0]).max())) + 1e-6
        v, a, kind = v[ok], a[ok], kind[ok]
        s = np.concatenate(
            [np.zeros((len(v), 1)), np.cumsum(0.5 * (v[:, 1:] + v[:, :-1]) * cfg.dt, axis=1)], axis=1
        )
        for dist in stops:
            if math.isfinite(dist) and dist < cfg.stop_reach:
                sv, sa, ss = self._stop_profiles(v0, a0, max(dist, 0.0))
                v = np.concatenate([v, sv])
                a = np.concatenate([a, sa])
                s = np.concatenate([s, ss])  # exact quintic positions
                kind = np.concatenate([kind, np.full(len(sv), 2, np.int8)])
        # drop duplicates (clipped reach-target actions coincide with sampled ones)
        keep = first_unique_rows(np.round(v, 4))
        return LonBank(s=s[keep], v=v[keep], a=a[keep], kind=kind[keep])

    def _stop_profiles(self, v0: float, a0: float, dist: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Up to 3 quintic stops at exactly ``dist`` metres: the fastest, a middle and the gentlest
        feasible duration (v >= 0, no overshoot, a within limits). Falls back to the hardest braking."""
        cfg = self.cfg
        if v0 < 1e-3 and dist < 0.05:
            z = np.zeros((1, len(self.t)))
            return z, z.copy(), z.copy()
        durs = self._stop_durs
        p, v, a, _ = _quintic(0.0, v0, a0, dist, self._stop_grid)
        feas = (
            (v.min(axis=1) >= -1e-3)
            & (p.max(axis=1) <= dist + 0.02)
            & (a.min(axis=1) >= cfg.a_min)
            & (a.max(axis=1) <= cfg.a_max)
        )
        cand = np.flatnonzero(feas)
        if len(cand) == 0:
            # cannot stop at the line: brake as hard as allowed (the stop_line feature will cost it)
            d = np.array([max(dist, v0**2 / (2 * -cfg.a_min) * 1.05)])
            durs_f = self._stop_durs_f
            p, v, a, _ = _quintic(0.0, v0, a0, d, self._stop_grid_f)
            feas = (v.min(axis=1) >= -1e-3) & (a.min(axis=1) >= cfg.a_min) & (a.max(axis=1) <= cfg.a_max)
            cand = np.flatnonzero(feas) if feas.any() else np.array([255])
            dist = float(d[0])
            durs = durs_f
        pick = np.array(sorted({int(cand[0]), int(cand[len(cand) // 2]), int(cand[-1])}))
        ps, vs, as_, _ = quintic(0.0, v0, a0, dist, durs[pick], self.t[None, :])
        return _hold_after_stop(ps, vs, as_)

    # ------------------------------------------------------------------ lateral
    def lat_bank(self, d0: float, dd0: float, ddd0: float, centres: np.ndarray | None = None) -> LatBank:
        """Generic lateral profiles from the ego's offset ``d0`` [m], ``dd0`` [m/s], ``ddd0`` [m/s^2],
        to the lane centres ``centres`` [m] (default: every lane's; where lanes are added or dropped, the
        planner passes those that exist where the policies end)."""
        cfg = self.cfg
        centres = self.road.lane_centres if centres is None else centres
        k = len(centres)
        cur = float(centres[np.argmin(np.abs(centres - d0))])
        t1_targets, t1_durs = [], []
        for c in centres:
            for dur in cfg.lat_durations:
                t1_targets.append(c)
                t1_durs.append(dur)
        t1_targets.append(d0)  # stay (a lane-centre target when the ego is on one)
        t1_durs.append(cfg.lat_durations[0])
        for sgn in (-1.0, 1.0):  # partial swerves, inside the loop's outer lane centres
            for mag in cfg.swerves:
                tgt = cur + sgn * mag
                if centres[0] - 1e-6 <= tgt <= centres[-1] + 1e-6:
                    t1_targets.append(tgt)
                    t1_durs.append(cfg.stage_split)
        n1 = len(t1_targets)
        D1 = np.repeat(np.array(t1_targets), k)[:, None]
        DUR = np.repeat(np.array(t1_durs), k)[:, None]
        D2 = np.tile(centres, n1)[:, None]
        isp = self._i_split
        # stage 1: one quintic per (target, duration), each repeated for the k stage-2 targets
        q1 = _quintic(
            d0, dd0, ddd0, np.array(t1_targets)[:, None], self._lat_grid(np.array(t1_durs)[:, None])
        )
        p1, v1, a1, j1 = (np.repeat(q, k, axis=0) for q in q1)
        # stage 2 from the stage-1 state at the split, to a lane centre at the horizon
        p2, v2, a2, j2 = _quintic(
            p1[:, isp : isp + 1], v1[:, isp : isp + 1], a1[:, isp : isp + 1], D2, self._lat_grid2
        )
        late = self._late
        d = np.where(late, p2, p1)
        dd = np.where(late, v2, v1)
        ddd = np.where(late, a2, a1)
        dddd = np.where(late, j2, j1)
        keep_idx = first_unique_rows(np.round(d, 3))
        d, dd, ddd, dddd = d[keep_idx], dd[keep_idx], ddd[keep_idx], dddd[keep_idx]
        target = D2[keep_idx, 0]
        # the lane-keeping profile: to the current lane centre, shortest duration, stays there
        is_keep = (
            (np.abs(D1[keep_idx, 0] - cur) < 1e-9)
            & (np.abs(target - cur) < 1e-9)
            & (DUR[keep_idx, 0] == cfg.lat_durations[0])
        )
        return LatBank(
            d=d,
            dd=dd,
            ddd=ddd,
            dddd=dddd,
            target=target,
            bound_lon=np.full(len(d), -1, np.int64),
            keep=is_keep,
        )

    def exit_bank(self, d0: float, dd0: float, ddd0: float, s0: float, lon: LonBank) -> LatBank | None:
        """Exit-taking profiles (one per longitudinal profile) when an exit starts within reach."""
        cfg = self.cfg
        road = self.road
        for ex in road.exits:
            rel = (ex.s_start - s0 + road.lap_length / 2) % road.lap_length - road.lap_length / 2
            if -(ex.ramp_s[-1] - ex.s_start) < rel < cfg.exit_reach:
                break
        else:
            return None
        # the centre of the rightmost lane where the exit leaves it
        lo = int(road.lane_bounds(np.array(ex.s_start - 1.0))[0]) if road.lanes_vary else 0
        c0 = float(road.lane_centres[lo])
        if d0 > c0 + road.lane_width / 2:  # only from that lane
            return None
        s_abs = ex.s_start - rel + lon.s  # [L, T] in the exit's own unwrapped frame (ego at s_start - rel)
        ramp = np.interp(s_abs, ex.ramp_s, ex.ramp_d, left=c0, right=ex.ramp_d[-1]) - c0
        # the quintic moves the ego's offset from the ramp's centre (not from the lane's) to 0, so that
        # every profile starts at the ego also inside the ramp zone, where the ramp has left the lane
        p, v, a, j = _quintic(d0 - ramp[:, :1], dd0, ddd0, c0, self._exit_grid)
        d = p + ramp
        dd = np.gradient(d, cfg.dt, axis=1)
        ddd = np.gradient(dd, cfg.dt, axis=1)
        dddd = np.gradient(ddd, cfg.dt, axis=1)
        dd[:, 0], ddd[:, 0], dddd[:, 0] = dd0, ddd0, j[0, 0]
        taken = d.min(axis=1) < -road.half_road
        if not taken.any():
            return None
        idx = np.flatnonzero(taken)
        return LatBank(
            d=d[idx],
            dd=dd[idx],
            ddd=ddd[idx],
            dddd=dddd[idx],
            target=np.full(len(idx), np.nan),
            bound_lon=idx.astype(np.int64),
            keep=np.zeros(len(idx), bool),
        )


def _hold_after_stop(
    s: np.ndarray, v: np.ndarray, a: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(v, a, s) of stop profiles [P, T] that stand still once they reach v = 0: a quintic cut at the
    horizon (the fallback when no stop is feasible) may otherwise turn negative and roll backwards."""
    stopped = np.maximum.accumulate((v <= 0.0) & (np.arange(v.shape[1]) > 0), axis=1)
    first = np.argmax(stopped, axis=1)
    # the furthest point reached (v crosses 0 between steps: the quintic may already be backing up)
    s_stop = np.maximum.accumulate(s, axis=1)[np.arange(len(s)), first][:, None]
    return (
        np.where(stopped, 0.0, v),
        np.where(stopped, 0.0, a),
        np.where(stopped, s_stop, s),
    )


def concat_lat(a: LatBank, b: LatBank | None) -> LatBank:
    if b is None:
        return a
    return LatBank(
        *(
            np.concatenate([getattr(a, f), getattr(b, f)])
            for f in ("d", "dd", "ddd", "dddd", "target", "bound_lon", "keep")
        )
    )


def select_pairs(feasible: np.ndarray, essential: np.ndarray, n: int) -> np.ndarray:
    """Indices (into the candidate pairs) of exactly ``n`` pairs: feasible essential ones first, the
    rest evenly subsampled; repeated cyclically when fewer than ``n`` are feasible. Deterministic."""
    cand = np.flatnonzero(feasible)
    if len(cand) == 0:
        cand = np.array([0])
    if len(cand) <= n:
        return np.resize(cand, n)
    ess = cand[essential[cand]]
    rest = cand[~essential[cand]]
    if len(ess) >= n:
        return ess[np.linspace(0, len(ess) - 1, n).round().astype(np.int64)]
    k = n - len(ess)
    pick = rest[np.linspace(0, len(rest) - 1, k).round().astype(np.int64)] if k else rest[:0]
    return np.sort(np.concatenate([ess, pick]))


def stop_distances(obs: Observation, cfg: PlannerConfig, road: Road) -> tuple[float, ...]:
    """Distances [m] from the ego's front bumper to where it may have to stand: the active stop line
    (minus ``stop_margin``), the line itself (minus ``stop_line_gap``) once the ego can no longer stand at
    that stop point comfortably, and the tail of the nearest slow (< 2 m/s) vehicle ahead in each lane."""
    out = []
    if math.isfinite(obs.stop_s):
        to_line = float(obs.stop_s - obs.ego.s)
        out.append(to_line - cfg.stop_margin)
        comfort = obs.ego.v**2 / (2.0 * cfg.stop_decel_comfort)
        if cfg.stop_line_gap > 0 and to_line > cfg.stop_line_gap and to_line - cfg.stop_margin < comfort:
            out.append(to_line - cfg.stop_line_gap)
    veh = obs.vehicles
    if veh.count:
        lap = obs.lap_length
        ds = (veh.s - obs.ego.s % lap + lap / 2) % lap - lap / 2
        gap = ds - veh.length
        for c in road.lane_centres:  # the nearest slow vehicle ahead in each lane
            mask = (
                (ds > 0) & (np.abs(veh.d - c) < road.lane_width / 2) & (veh.v < 2.0) & (gap < cfg.stop_reach)
            )
            if mask.any():
                out.append(float(gap[mask].min() - cfg.safety_gap - 0.5))
    return tuple(out)
