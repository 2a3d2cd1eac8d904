"""Closed-loop figures: comfort from the executed odometry, per-episode metrics and the per-model summary.

Metric keys (namespaced ``drive/``; an episode record also keeps the simulator's ``sim/...`` keys):

    drive/model, drive/episode, drive/seed, drive/safety      what ran
    drive/cycles                                              planning cycles driven
    drive/laps                                                laps completed
    drive/collisions                                          ego collisions (the project's oriented boxes)
    drive/exits                                               exits taken (each fails the mission)
    drive/stop_lines_passed, drive/stop_lines_compliant       stop lines crossed / crossed after a full stop
    drive/stop_compliance                                     compliant / passed (None when none was passed)
    drive/checkpoints_passed, drive/checkpoints_in_lane       checkpoints crossed / crossed in required lane
    drive/checkpoint_compliance                               in lane / passed (None when none was passed)
    drive/mean_speed_kmh                                      [km/h] mean over simulation steps
    drive/distance_m, drive/time_s                            [m], [s] driven
    drive/rms_jerk_lon, drive/rms_jerk_lat                    [m/s^3] RMS jerk of the executed odometry
    drive/inference_ms_mean, drive/inference_ms_p90           [ms] reward inference per cycle (learned
                                                              models: the network's theta; the expert: its
                                                              model-based selection)
    drive/plan_ms_mean                                        [ms] policy sampling + features per cycle
    drive/wall_s                                              [s] wall time of the episode
    drive/end_reason                                          collision, exit, laps, timeout or max_cycles
    drive/checkpoints_missed                                  the checkpoints crossed out of lane: index (the
                                                              road's checkpoint order), time [s], lane driven
                                                              and lane required (-1: any of several); a
                                                              summary counts them per index
    drive/first_collision                                     None, or the episode's first collision: time
                                                              [s], the other vehicle, what (rear-end, side,
                                                              ...) and where (sim.collision.first_collision)

The nuPlan-style scorecard (``score/...`` keys, formulas in :mod:`irlsim.drive.scorecard`) follows in
every episode record and every summary (means over the episodes, ``score/score_std`` the spread).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

import numpy as np

from irlsim.drive.scorecard import summarize_scores

#: the keys every episode record has (besides the simulator's ``sim/...``)
EPISODE_KEYS: tuple[str, ...] = (
    "drive/model",
    "drive/episode",
    "drive/seed",
    "drive/safety",
    "drive/cycles",
    "drive/laps",
    "drive/collisions",
    "drive/exits",
    "drive/stop_lines_passed",
    "drive/stop_lines_compliant",
    "drive/stop_compliance",
    "drive/checkpoints_passed",
    "drive/checkpoints_in_lane",
    "drive/checkpoint_compliance",
    "drive/mean_speed_kmh",
    "drive/distance_m",
    "drive/time_s",
    "drive/rms_jerk_lon",
    "drive/rms_jerk_lat",
    "drive/inference_ms_mean",
    "drive/inference_ms_p90",
    "drive/plan_ms_mean",
    "drive/wall_s",
    "drive/end_reason",
)


def jerks(t: np.ndarray, v: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Longitudinal and lateral jerk [m/s^3] of an odometry sampled at times ``t`` [S] (S >= 4).

    Longitudinal: the second difference of the speed ``v`` [m/s]. Lateral: the difference of the lateral
    acceleration v * yaw_rate (yaw [rad] unwrapped, so it is the jerk of the motion the ego actually
    drove, curvature of the road included). Finite differences on the step grid; both arrays are [S - 3]
    (aligned on the same steps). Fewer than 4 samples give empty arrays.
    """
    t, v, yaw = (np.asarray(a, dtype=np.float64) for a in (t, v, yaw))
    assert t.shape == v.shape == yaw.shape and t.ndim == 1, (t.shape, v.shape, yaw.shape)
    if len(t) < 4:
        return np.zeros(0), np.zeros(0)
    dt = np.maximum(np.diff(t), 1e-9)  # [S-1]
    a_lon = np.diff(v) / dt  # [S-1], at step midpoints
    yaw_rate = np.diff(np.unwrap(yaw)) / dt
    a_lat = 0.5 * (v[1:] + v[:-1]) * yaw_rate
    dtm = np.maximum(0.5 * (dt[1:] + dt[:-1]), 1e-9)  # [S-2] spacing of the midpoints
    j_lon = np.diff(a_lon) / dtm
    j_lat = np.diff(a_lat) / dtm
    return j_lon[1:], j_lat[1:]  # drop the first: the reset state's acceleration is not a driven one


def rms(x: np.ndarray) -> float:
    x = np.asarray(x, dtype=np.float64)
    return float(np.sqrt(np.mean(x * x))) if len(x) else 0.0


def ratio(num: int, den: int) -> float | None:
    return round(num / den, 4) if den else None


def episode_metrics(
    sim_stats: dict[str, Any],
    odometry: dict[str, np.ndarray],
    inference_ms: Sequence[float],
    plan_ms: Sequence[float],
    *,
    model: str,
    episode: int,
    seed: int,
    safety: bool,
    cycles: int,
    wall_s: float,
    end_reason: str | None,
) -> dict[str, Any]:
    """The ``drive/`` record of one episode (module docstring), followed by the simulator's own keys."""
    j_lon, j_lat = jerks(odometry["t"], odometry["v"], odometry["yaw"])
    inf = np.asarray(inference_ms, dtype=np.float64)
    s = sim_stats
    rec: dict[str, Any] = {
        "drive/model": model,
        "drive/episode": episode,
        "drive/seed": seed,
        "drive/safety": safety,
        "drive/cycles": cycles,
        "drive/laps": int(s["sim/laps"]),
        "drive/collisions": int(s["sim/collisions"]),
        "drive/exits": int(s["sim/exits"]),
        "drive/stop_lines_passed": int(s["sim/stop_lines_passed"]),
        "drive/stop_lines_compliant": int(s["sim/stop_lines_compliant"]),
        "drive/stop_compliance": ratio(int(s["sim/stop_lines_compliant"]), int(s["sim/stop_lines_passed"])),
        "drive/checkpoints_passed": int(s["sim/checkpoints_passed"]),
        "drive/checkpoints_in_lane": int(s["sim/checkpoints_in_lane"]),
        "drive/checkpoint_compliance": ratio(
            int(s["sim/checkpoints_in_lane"]), int(s["sim/checkpoints_passed"])
        ),
        "drive/mean_speed_kmh": float(s["sim/mean_speed_kmh"]),
        "drive/distance_m": float(s["sim/distance_m"]),
        "drive/time_s": float(s["sim/time_s"]),
        "drive/rms_jerk_lon": round(rms(j_lon), 4),
        "drive/rms_jerk_lat": round(rms(j_lat), 4),
        "drive/inference_ms_mean": round(float(inf.mean()), 4) if len(inf) else 0.0,
        "drive/inference_ms_p90": round(float(np.percentile(inf, 90)), 4) if len(inf) else 0.0,
        "drive/plan_ms_mean": round(float(np.mean(plan_ms)), 4) if len(plan_ms) else 0.0,
        "drive/wall_s": round(wall_s, 3),
        "drive/end_reason": end_reason,
    }
    assert tuple(rec) == EPISODE_KEYS
    rec.update({k: v for k, v in s.items() if k.startswith("sim/")})
    return rec


def summarize(episodes: Sequence[dict[str, Any]], inference_ms: Sequence[float] = ()) -> dict[str, Any]:
    """One model's summary over its episodes: sums of counts, ratios of the sums, step-weighted speed,
    step-weighted RMS jerk, cycle-weighted mean inference time and the p90 over all cycles
    (``inference_ms``: every cycle's time pooled; without it the largest episode p90)."""
    if not episodes:
        return {}

    def tot(k: str) -> int:
        return int(sum(e[k] for e in episodes))

    cycles = tot("drive/cycles")
    dist = sum(e["drive/distance_m"] for e in episodes)
    time_s = sum(e["drive/time_s"] for e in episodes)
    steps = np.array([max(e.get("sim/steps", 1), 1) for e in episodes], dtype=np.float64)

    def wrms(k: str) -> float:  # RMS over all steps of all episodes
        x = np.array([e[k] for e in episodes], dtype=np.float64)
        return round(float(np.sqrt((steps * x * x).sum() / steps.sum())), 4)

    inf_mean = sum(e["drive/inference_ms_mean"] * e["drive/cycles"] for e in episodes) / max(cycles, 1)
    p90 = (
        float(np.percentile(inference_ms, 90))
        if len(inference_ms)
        else max(e["drive/inference_ms_p90"] for e in episodes)
    )
    return {
        "drive/model": episodes[0]["drive/model"],
        "drive/episodes": len(episodes),
        "drive/cycles": cycles,
        "drive/laps": tot("drive/laps"),
        "drive/collisions": tot("drive/collisions"),
        "drive/exits": tot("drive/exits"),
        "drive/stop_lines_passed": tot("drive/stop_lines_passed"),
        "drive/stop_lines_compliant": tot("drive/stop_lines_compliant"),
        "drive/stop_compliance": ratio(tot("drive/stop_lines_compliant"), tot("drive/stop_lines_passed")),
        "drive/checkpoints_passed": tot("drive/checkpoints_passed"),
        "drive/checkpoints_in_lane": tot("drive/checkpoints_in_lane"),
        "drive/checkpoint_compliance": ratio(
            tot("drive/checkpoints_in_lane"), tot("drive/checkpoints_passed")
        ),
        "drive/mean_speed_kmh": round(
            float((steps * np.array([e["drive/mean_speed_kmh"] for e in episodes])).sum() / steps.sum()), 3
        ),
        "drive/distance_m": round(dist, 3),
        "drive/time_s": round(time_s, 3),
        "drive/rms_jerk_lon": wrms("drive/rms_jerk_lon"),
        "drive/rms_jerk_lat": wrms("drive/rms_jerk_lat"),
        "drive/inference_ms_mean": round(inf_mean, 4),
        "drive/inference_ms_p90": round(p90, 4),
        "drive/plan_ms_mean": round(
            sum(e["drive/plan_ms_mean"] * e["drive/cycles"] for e in episodes) / max(cycles, 1), 4
        ),
        "drive/end_reasons": dict(Counter(str(e["drive/end_reason"]) for e in episodes)),
        "drive/checkpoints_missed": missed_by_checkpoint(episodes),
        **(summarize_scores(episodes) if "score/score" in episodes[0] else {}),
        # on a road with traffic lights only (the oval's summaries keep their keys)
        **(
            {"drive/red_crossings": tot("sim/red_crossings")}
            if all("sim/red_crossings" in e for e in episodes)
            else {}
        )
        | (
            {"drive/yield_violations": tot("sim/yield_violations")}
            if all("sim/yield_violations" in e for e in episodes)
            else {}
        ),
    }


def missed_checkpoints(events: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The checkpoints an episode crossed out of lane, from its events (:class:`irlsim.sim.episode.Episode`):
    index, time [s], lane driven, lane required."""
    return [
        {"index": e["index"], "t": round(float(e["t"]), 2), "lane": e["lane"], "required": e["required"]}
        for e in events
        if e["kind"] == "checkpoint" and not e["met"]
    ]


def missed_by_checkpoint(episodes: Sequence[dict[str, Any]]) -> dict[str, int]:
    """How often each checkpoint (by index, as a string: a JSON key) was crossed out of lane."""
    n = Counter(m["index"] for e in episodes for m in e.get("drive/checkpoints_missed", ()))
    return {str(k): n[k] for k in sorted(n)}


def _frac(k: int, n: int) -> str:
    return f"{k}/{n}" if n else "-"


def markdown_table(summaries: Sequence[dict[str, Any]]) -> str:
    """The side-by-side closed-loop table (one row per model) as GitHub Markdown."""
    head = (
        "| model | episodes | laps | collisions | exits | stop compliance | checkpoints in lane | mean km/h "
        "| RMS jerk lon / lat [m/s^3] | inference ms (mean / p90) | end reasons |"
    )
    rows = [head, "|" + "---|" * 11]
    for s in summaries:
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(s["drive/end_reasons"].items()))
        if "drive/red_crossings" in s:
            reasons += f"; red lights crossed {s['drive/red_crossings']}"
        if "drive/yield_violations" in s:
            reasons += f"; right of way not given {s['drive/yield_violations']}"
        rows.append(
            f"| {s['drive/model']} | {s['drive/episodes']} | {s['drive/laps']} | {s['drive/collisions']} "
            f"| {s['drive/exits']} | {_frac(s['drive/stop_lines_compliant'], s['drive/stop_lines_passed'])} "
            f"| {_frac(s['drive/checkpoints_in_lane'], s['drive/checkpoints_passed'])} "
            f"| {s['drive/mean_speed_kmh']:.1f} "
            f"| {s['drive/rms_jerk_lon']:.2f} / {s['drive/rms_jerk_lat']:.2f} "
            f"| {s['drive/inference_ms_mean']:.2f} / {s['drive/inference_ms_p90']:.2f} | {reasons} |"
        )
    return "\n".join(rows) + "\n"
