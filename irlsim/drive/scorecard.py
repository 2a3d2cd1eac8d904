"""The nuPlan-style closed-loop scorecard, adapted to the oval course: pure functions over arrays.

nuPlan's closed-loop score (CLS) multiplies a few hard multipliers with a weighted mean of soft terms.
Here every quantity comes from the executed odometry (one sample per 0.1 s simulation step, front-bumper
poses as everywhere in irlsim) and the other vehicles' states at the same steps; the formulas, with
S steps, step times t_k and dt_k = t_{k+1} - t_k:

Multipliers (each in [0, 1]; any 0 zeroes the score)

    no_collision        1 if the ego had no collision (oriented boxes), else 0
    no_exit             1 if the ego took no exit (each one fails the mission), else 0
    stop_lines          stop lines crossed after a full stop / crossed (1 when none was crossed)
    drivable_area       1 if max_k (|d_k| + W/2 - HALF_ROAD) <= 0.3 m over the steps outside an exit's
                        ramp zone (the ego's box, heading ignored, leaves the loop's edge by at most
                        nuPlan's 0.3 m), else 0
    making_progress     1 if progress (below) >= 0.2, else 0 (nuPlan's ego_is_making_progress)

Weighted terms (each in [0, 1]; weights as nuPlan's CLS, mission is this course's addition)

    ttc          5  share of steps with TTC_k >= 0.95 s. TTC_k: the first time tau in {0, 0.1, ..., 1.0} s
                    at which the ego's box, moved on at constant speed along its heading, overlaps a vehicle
                    box moved on the same way; only vehicles whose centre lies ahead of the ego's centre
                    (along the ego's heading) count, and steps where the ego stands (v < 0.05 m/s) count as
                    within bound (nuPlan's rules: the ego is not at fault for being hit from behind)
    progress     5  min(1, D_ego(T) / D_exp(T)): route metres driven by time T = min(duration_ego,
                    duration_exp), the ego against the expert's episode on the same seed (1 when the expert
                    drove <= 0 m; None without an expert run)
    speed_limit  4  max(0, 1 - mean_k(max(v_k - v_max, 0)) / 2.23 m/s), time-weighted by dt_k;
                    v_max = the loop's SUMO speed limit 27.78 m/s (100 km/h)
    comfort      2  share of steps at which all six comfort quantities are within nuPlan's bounds:
                    lon. acc in [-4.05, 2.40] m/s^2, |lat. acc| <= 4.89 m/s^2, |jerk| <= 8.37 m/s^3,
                    |lon. jerk| <= 4.13 m/s^3, |yaw rate| <= 0.95 rad/s, |yaw acc| <= 1.93 rad/s^2
                    (derivatives: second-order finite differences, np.gradient, of v and the unwrapped
                    yaw; lon. acc = dv/dt, lat. acc = v * yaw rate, jerk = d|a|/dt with |a| the norm of
                    (lon. acc, lat. acc), lon. jerk = d(lon. acc)/dt; nuPlan uses the same quantities but
                    smooths with a Savitzky-Golay filter first)
    mission      4  checkpoints passed in the required lane / passed (1 when none was passed)

    score = 100 * prod(multipliers) * sum_i(w_i * term_i) / sum_i(w_i)        (0..100)

A term that is None (progress without an expert run) drops out of both sums. nuPlan's boolean comfort
and TTC metrics become shares of time here, as the course's episodes are minutes long, not 15 s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from irlsim.sim.collision import box_centers, obb_collide

#: nuPlan's comfort bounds: quantity -> (low, high)
COMFORT_BOUNDS: dict[str, tuple[float, float]] = {
    "lon_acc": (-4.05, 2.40),  # [m/s^2]
    "lat_acc": (-4.89, 4.89),  # [m/s^2]
    "jerk": (-8.37, 8.37),  # [m/s^3]
    "lon_jerk": (-4.13, 4.13),  # [m/s^3]
    "yaw_rate": (-0.95, 0.95),  # [rad/s]
    "yaw_acc": (-1.93, 1.93),  # [rad/s^2]
}
TTC_BOUND = 0.95  # [s]
TTC_HORIZON = 1.0  # [s]
TTC_DT = 0.1  # [s]
TTC_STOPPED = 0.05  # [m/s] the ego counts as standing below this speed
DRIVABLE_TOLERANCE = 0.3  # [m]
MAX_OVERSPEED = 2.23  # [m/s] nuPlan's max_overspeed_value_threshold
SPEED_LIMIT = 27.78  # [m/s] the loop edges' speed in sumo_net/oval.edg.xml
MIN_PROGRESS = 0.2
#: weighted terms and their weights (nuPlan CLS: TTC 5, progress 5, speed limit 4, comfort 2; mission ours)
WEIGHTS: dict[str, float] = {"ttc": 5.0, "progress": 5.0, "speed_limit": 4.0, "comfort": 2.0, "mission": 4.0}
MULTIPLIERS = ("no_collision", "no_exit", "stop_lines", "drivable_area", "making_progress")


# ------------------------------------------------------------------------------------------ comfort


def comfort_series(t: np.ndarray, v: np.ndarray, yaw: np.ndarray) -> dict[str, np.ndarray]:
    """The six comfort quantities [S] of an odometry (t [s], v [m/s], yaw [rad]), see the module docstring."""
    t, v, yaw = (np.asarray(a, dtype=np.float64) for a in (t, v, yaw))
    assert t.shape == v.shape == yaw.shape and t.ndim == 1, (t.shape, v.shape, yaw.shape)
    if len(t) < 3:
        z = np.zeros(len(t))
        return {k: z for k in COMFORT_BOUNDS}
    lon_acc = np.gradient(v, t, edge_order=2)
    yaw_rate = np.gradient(np.unwrap(yaw), t, edge_order=2)
    lat_acc = v * yaw_rate
    return {
        "lon_acc": lon_acc,
        "lat_acc": lat_acc,
        "jerk": np.gradient(np.hypot(lon_acc, lat_acc), t, edge_order=2),
        "lon_jerk": np.gradient(lon_acc, t, edge_order=2),
        "yaw_rate": yaw_rate,
        "yaw_acc": np.gradient(yaw_rate, t, edge_order=2),
    }


def comfort_within(series: Mapping[str, np.ndarray]) -> np.ndarray:
    """[S] bool: every comfort quantity within its bound at that step."""
    ok = None
    for k, (lo, hi) in COMFORT_BOUNDS.items():
        x = np.asarray(series[k])
        inside = (x >= lo - 1e-12) & (x <= hi + 1e-12)
        ok = inside if ok is None else ok & inside
    assert ok is not None
    return ok


# ------------------------------------------------------------------------------------------ TTC


def time_to_collision(
    ego: np.ndarray,
    ego_size: tuple[float, float],
    vehicles: np.ndarray,
    *,
    horizon: float = TTC_HORIZON,
    dt: float = TTC_DT,
    stopped: float = TTC_STOPPED,
) -> np.ndarray:
    """TTC [s] per step, vectorised over steps, vehicles and projection times.

    ``ego``: [S, 4] (x, y, yaw, v) front-bumper poses; ``ego_size``: (length, width) [m]. ``vehicles``:
    [S, M, 6] (x, y, yaw, v, length, width) per step, NaN rows where fewer than M vehicles exist. Returns
    [S]: the first tau on the grid {0, dt, ..., horizon} at which the constant-velocity boxes overlap, over
    the vehicles ahead of the ego; ``inf`` when none does within the horizon or the ego stands.
    """
    ego = np.asarray(ego, dtype=np.float64)
    veh = np.asarray(vehicles, dtype=np.float64)
    s_steps = ego.shape[0]
    out = np.full(s_steps, np.inf)
    if s_steps == 0 or veh.ndim != 3 or veh.shape[1] == 0:
        return out
    tau = np.arange(0.0, horizon + 1e-9, dt)  # [K]
    el, ew = ego_size
    ex, ey, eyaw, ev = (ego[:, i, None, None] for i in range(4))  # [S, 1, 1]
    vx, vy, vyaw, vv, vl, vw = (veh[:, :, i, None] for i in range(6))  # [S, M, 1]
    present = np.isfinite(veh).all(axis=2)  # [S, M]
    vx, vy, vyaw, vv, vl, vw = (np.nan_to_num(a, nan=0.0) for a in (vx, vy, vyaw, vv, vl, vw))
    vl, vw = np.maximum(vl, 1e-3), np.maximum(vw, 1e-3)
    # ahead: the vehicle's box centre lies in front of the ego's box centre along the ego's heading
    ecx, ecy = box_centers(ex[:, :, 0], ey[:, :, 0], eyaw[:, :, 0], el)
    vcx, vcy = box_centers(vx[:, :, 0], vy[:, :, 0], vyaw[:, :, 0], vl[:, :, 0])
    ahead = (vcx - ecx) * np.cos(eyaw[:, :, 0]) + (vcy - ecy) * np.sin(eyaw[:, :, 0]) > 0.0  # [S, M]
    hit = obb_collide(
        ex + ev * np.cos(eyaw) * tau,
        ey + ev * np.sin(eyaw) * tau,
        eyaw,
        el,
        ew,
        vx + vv * np.cos(vyaw) * tau,
        vy + vv * np.sin(vyaw) * tau,
        vyaw,
        vl,
        vw,
    )  # [S, M, K]
    hit &= (present & ahead)[:, :, None]
    any_hit = hit.any(axis=2)  # [S, M]
    first = np.where(any_hit, tau[np.argmax(hit, axis=2)], np.inf)  # [S, M]
    out = first.min(axis=1)
    out[ego[:, 3] < stopped] = np.inf
    return out


# ------------------------------------------------------------------------------------------ terms


def drivable_intrusion(d: np.ndarray, ego_width: float, half_road: float, exempt: np.ndarray) -> float:
    """[m] the largest lateral intrusion of the ego's box beyond the loop's edge, max_k (|d_k| + W/2 -
    half_road) over the steps not ``exempt`` (an exit's ramp zone); <= 0 when always inside."""
    d = np.asarray(d, dtype=np.float64)
    keep = ~np.asarray(exempt, dtype=bool)
    if not keep.any():
        return 0.0
    return float(np.max(np.abs(d[keep]) + 0.5 * ego_width - half_road))


def speed_limit_compliance(
    t: np.ndarray, v: np.ndarray, limit: float = SPEED_LIMIT, max_overspeed: float = MAX_OVERSPEED
) -> float:
    """max(0, 1 - time-mean overspeed / max_overspeed); the overspeed of interval k is max(v_{k+1} -
    limit, 0) weighted by its length t_{k+1} - t_k. 1 for fewer than 2 samples."""
    t, v = np.asarray(t, dtype=np.float64), np.asarray(v, dtype=np.float64)
    if len(t) < 2 or t[-1] <= t[0]:
        return 1.0
    over = np.maximum(v[1:] - limit, 0.0)
    mean_over = float(np.sum(over * np.diff(t)) / (t[-1] - t[0]))
    return max(0.0, 1.0 - mean_over / max_overspeed)


def progress_ratio(t_ego: np.ndarray, s_ego: np.ndarray, t_exp: np.ndarray, s_exp: np.ndarray) -> float:
    """min(1, D_ego(T) / D_exp(T)) with D(T) = s(t0 + T) - s(t0) (linear interpolation) and T the shorter
    episode's duration; 1 when the expert drove <= 0 m in T."""
    t_ego, s_ego, t_exp, s_exp = (np.asarray(a, dtype=np.float64) for a in (t_ego, s_ego, t_exp, s_exp))
    if len(t_ego) < 2 or len(t_exp) < 2:
        return 1.0
    horizon = min(t_ego[-1] - t_ego[0], t_exp[-1] - t_exp[0])
    d_ego = float(np.interp(t_ego[0] + horizon, t_ego, s_ego) - s_ego[0])
    d_exp = float(np.interp(t_exp[0] + horizon, t_exp, s_exp) - s_exp[0])
    if d_exp <= 0.0:
        return 1.0
    return float(min(1.0, max(d_ego, 0.0) / d_exp))


def ratio_or_one(num: int, den: int) -> float:
    return num / den if den else 1.0


def composite(multipliers: Mapping[str, float], terms: Mapping[str, float | None]) -> float:
    """100 * prod(multipliers) * weighted mean of the terms that are not None (WEIGHTS)."""
    used = {k: v for k, v in terms.items() if v is not None}
    if not used:
        return 0.0
    wsum = sum(WEIGHTS[k] for k in used)
    mean = sum(WEIGHTS[k] * float(v) for k, v in used.items()) / wsum
    return 100.0 * float(np.prod([float(m) for m in multipliers.values()])) * mean


# ------------------------------------------------------------------------------------------ one episode


def episode_scorecard(
    *,
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    yaw: np.ndarray,
    v: np.ndarray,
    s: np.ndarray,
    d: np.ndarray,
    vehicles: np.ndarray,
    ego_size: tuple[float, float],
    half_road: float,
    exempt: np.ndarray,
    collisions: int,
    exits: int,
    stop_lines_passed: int,
    stop_lines_compliant: int,
    checkpoints_passed: int,
    checkpoints_in_lane: int,
    expert: tuple[np.ndarray, np.ndarray] | None = None,
    speed_limit: float = SPEED_LIMIT,
    red_crossings: int | None = None,
    yield_violations: int | None = None,
) -> dict[str, Any]:
    """The ``score/`` record of one episode from its per-step arrays [S] (and ``vehicles`` [S, M, 6]);
    ``expert``: the expert's (t, s) on the same seed, for progress. Keys: ``score/<multiplier>``,
    ``score/<term>``, ``score/comfort_<quantity>`` (share of steps within that bound), ``score/ttc_min``
    [s], ``score/drivable_intrusion_m``, ``score/progress`` and ``score/score``. On a road with traffic
    lights (``red_crossings`` given) crossing one on red is a failure like a collision:
    ``score/no_red_crossing``. On a route with yield points (``yield_violations`` given) entering a
    minor link's conflict area ahead of a foe with priority is one too: ``score/no_yield_violation``."""
    ttc = time_to_collision(np.stack([x, y, yaw, v], axis=1), ego_size, vehicles)
    series = comfort_series(t, v, yaw)
    within = comfort_within(series)
    intrusion = drivable_intrusion(d, ego_size[1], half_road, exempt)
    progress = None if expert is None else progress_ratio(t, s, expert[0], expert[1])
    mult = {
        "no_collision": float(collisions == 0),
        "no_exit": float(exits == 0),
        "stop_lines": ratio_or_one(stop_lines_compliant, stop_lines_passed),
        "drivable_area": float(intrusion <= DRIVABLE_TOLERANCE),
        "making_progress": 1.0 if progress is None else float(progress >= MIN_PROGRESS),
    }
    if red_crossings is not None:
        mult["no_red_crossing"] = float(red_crossings == 0)
    if yield_violations is not None:
        mult["no_yield_violation"] = float(yield_violations == 0)
    n = max(len(t), 1)
    terms: dict[str, float | None] = {
        "ttc": float(np.mean(ttc >= TTC_BOUND)) if len(ttc) else 1.0,
        "progress": progress,
        "speed_limit": speed_limit_compliance(t, v, speed_limit),
        "comfort": float(within.sum() / n) if len(t) else 1.0,
        "mission": ratio_or_one(checkpoints_in_lane, checkpoints_passed),
    }
    rec: dict[str, Any] = {f"score/{k}": round(val, 4) for k, val in mult.items()}
    rec.update({f"score/{k}": None if val is None else round(val, 4) for k, val in terms.items()})
    for k, (lo, hi) in COMFORT_BOUNDS.items():
        q = series[k]
        rec[f"score/comfort_{k}"] = (
            round(float(np.mean((q >= lo - 1e-12) & (q <= hi + 1e-12))), 4) if len(q) else 1.0
        )
    finite = ttc[np.isfinite(ttc)]
    rec["score/ttc_min"] = round(float(finite.min()), 3) if len(finite) else None
    rec["score/drivable_intrusion_m"] = round(intrusion, 3)
    rec["score/score"] = round(composite(mult, terms), 2)
    return rec


SCORE_KEYS: tuple[str, ...] = (
    *(f"score/{k}" for k in MULTIPLIERS),
    *(f"score/{k}" for k in WEIGHTS),
    *(f"score/comfort_{k}" for k in COMFORT_BOUNDS),
    "score/ttc_min",
    "score/drivable_intrusion_m",
    "score/score",
)


def summarize_scores(episodes: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Per-model scorecard: the mean over episodes of every ``score/`` figure (None-valued ones skipped;
    None if all are), ``score/ttc_min`` the minimum, and ``score/score_std`` the spread (population std)
    of the episode scores. As nuPlan, the model's score is the mean of its episodes' scores."""
    out: dict[str, Any] = {}
    for k in SCORE_KEYS:
        vals = [e[k] for e in episodes if e.get(k) is not None]
        if k == "score/ttc_min":
            out[k] = min(vals) if vals else None
        else:
            out[k] = round(float(np.mean(vals)), 4) if vals else None
    scores = [e["score/score"] for e in episodes if e.get("score/score") is not None]
    out["score/score_std"] = round(float(np.std(scores)), 2) if scores else None
    return out


def scorecard_table(summaries: Sequence[Mapping[str, Any]]) -> str:
    """The scorecard per model as GitHub Markdown (means over episodes)."""

    def f(x: Any, nd: int = 2) -> str:
        return "-" if x is None else f"{x:.{nd}f}"

    head = (
        "| model | score (mean ± std) | no collision | no exit | stop lines | drivable area "
        "| making progress | TTC >= 0.95 s | progress | speed limit | comfort | mission | min TTC [s] |"
    )
    rows = [head, "|" + "---|" * 13]
    for s in summaries:
        rows.append(
            f"| {s['drive/model']} | {f(s['score/score'], 1)} ± {f(s['score/score_std'], 1)} "
            + "".join(f"| {f(s[f'score/{k}'])} " for k in MULTIPLIERS)
            + "".join(f"| {f(s[f'score/{k}'])} " for k in WEIGHTS)
            + f"| {f(s['score/ttc_min'])} |"
        )
    return "\n".join(rows) + "\n"
