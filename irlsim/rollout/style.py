"""Driving style, measured: one summary of any driving (a collection's demonstrator, a closed-loop
drive), and the one style distance between drivings.

:class:`StyleObserver` records every simulation step (0.1 s): time, route position, speed, lane, and the
gap to the leader in the ego's lane. :func:`style_summary` turns such arrays into ``style/...`` figures
(vectorised over the steps):

- ``style/mean_speed`` [m/s]: distance along the route / time;
- ``style/headway_median_s``, ``style/headway_p10_s`` [s]: time headway gap / speed to the leader while
  following (a leader in the ego's lane within ``FOLLOW_RANGE`` m, speed above ``MIN_FOLLOW_SPEED``),
  median and 10th percentile (NaN when never following); ``style/following_s`` the time following;
- ``style/lane_changes``, ``style/lane_changes_per_km``: changes of the ego's lane between steps;
- ``style/rms_accel`` [m/s^2], ``style/rms_jerk`` [m/s^3]: RMS of the longitudinal acceleration and
  jerk, finite differences of the speed over ``DERIVATIVE_BASE_S`` (1 s) at every step: the mean
  acceleration over each second and its change from one second to the next. At the 0.1 s step the same
  driving measured from a recording's 1 s rows (resampled to the step by linear interpolation) would show
  2-3 times the jerk of its 0.1 s rows, and SUMO's single-step speed changes would count as style; over
  1 s a recording at 1 s or finer and a simulated driving give comparable figures (docs/results/styles.md,
  "Acceleration and jerk over a second");
- ``style/full_stops``, ``style/stops_per_km``: entries into standstill (speed to ``STOP_SPEED`` or
  below from above it);
- ``style/lane_share``: the share of time in each lane (route lane numbering, 0 = rightmost);
- ``style/time_s``, ``style/km``: what was driven.

:func:`pool_styles` combines episodes (time-, distance- and following-time-weighted: exact for every
figure but the two headway percentiles, which are the following-time-weighted mean of the episodes').
:func:`style_distances` is the style distance: the RMS over the figures of ``STYLE_FIGURES`` (and the lane
shares) of their differences, each divided by that figure's spread: its standard deviation over every
episode of the drivings compared (:func:`style_spread`; in a style table, the demonstrators' own
episodes, the same normaliser for every row). A difference then counts against how much the figure varies
from one episode to the next among the drivers compared: a figure the drivers nearly agree on weighs no
more than their episodes' variation says it can. Drivings known only pooled fall back to each figure's
standard deviation across the drivings themselves (the definition until 2026-12-01; where the drivers
nearly agree it weighs a small difference as much as a large one: docs/results/styles.md, "The style
distance's normaliser"). A figure that does not vary, or is NaN for one of the two, is left out.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from irlsim.rollout.runner import StepListener

#: [m] a leader farther ahead than this is not being followed
FOLLOW_RANGE = 100.0
#: [m/s] below this speed time headway is not defined (a queue standing still)
MIN_FOLLOW_SPEED = 1.0
#: [m/s] standstill (the scenarios' stop_speed)
STOP_SPEED = 0.1
#: [s] the time base of the acceleration and jerk figures (at least one step)
DERIVATIVE_BASE_S = 1.0
#: the scalar figures the style distance compares (besides each lane's share)
STYLE_FIGURES = (
    "style/mean_speed",
    "style/headway_median_s",
    "style/headway_p10_s",
    "style/lane_changes_per_km",
    "style/rms_accel",
    "style/rms_jerk",
    "style/stops_per_km",
)


def lane_visits(lane: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lane and the length [steps] of each visit of a per-step lane sequence (vectorised)."""
    lane = np.asarray(lane)
    edges = np.flatnonzero(lane[1:] != lane[:-1]) + 1
    bounds = np.concatenate([[0], edges, [len(lane)]])
    return lane[bounds[:-1]], np.diff(bounds)


def leader_ahead(sim: Any) -> tuple[float, int]:
    """The bumper gap [m] to the nearest vehicle ahead in the ego's lane and its index in
    ``sim.vehicles`` ((inf, -1) without one), vectorised over the vehicles."""
    e, veh = sim.ego, sim.vehicles
    if not veh.count:
        return float("inf"), -1
    ahead = (veh.s - e.s) % sim.road.lap_length
    same = np.asarray(sim.road.lane_of_d(veh.d)) == e.lane
    g = np.where(same & (ahead > 0), ahead - veh.length, np.inf)
    k = int(np.argmin(g))
    return (float(g[k]), k) if np.isfinite(g[k]) else (float("inf"), -1)


def lane_changes(lane: np.ndarray, dt: float, min_visit_s: float = 0.0) -> int:
    """The lane changes of a per-step lane sequence (steps ``dt`` apart): every change of lane, except that
    a visit to a lane lasting at most ``min_visit_s`` and returning to the lane it left is none (its two
    changes are dropped and the visits around it merge; repeatedly, so a flicker of several such returns
    is none either). ``min_visit_s`` 0: every change. Vectorised over the steps; the loop is over visits."""
    if len(lane) < 2:
        return 0
    lanes, lengths = lane_visits(lane)
    if min_visit_s <= 0 or len(lanes) == 1:
        return len(lanes) - 1
    kept: list[list[float]] = []  # [lane, duration [s]] of the visits so far
    for which, steps in zip(lanes.tolist(), lengths.tolist(), strict=True):
        if len(kept) >= 2 and kept[-1][1] <= min_visit_s + 1e-9 and kept[-2][0] == which:
            short = kept.pop()
            kept[-1][1] += short[1] + steps * dt
        else:
            kept.append([which, steps * dt])
    return len(kept) - 1


def _per_km(n: float, km: float) -> float:
    return float(n / km) if km > 0 else 0.0


def style_summary(
    t: np.ndarray, s: np.ndarray, v: np.ndarray, lane: np.ndarray, gap: np.ndarray
) -> dict[str, Any]:
    """The style figures of one driving from per-step arrays [S]: time [s], route position s [m],
    speed [m/s], lane (int), gap [m] from the ego's front to its leader's rear in its lane (NaN: none).
    Steps of equal spacing; at least two. Acceleration and jerk over ``DERIVATIVE_BASE_S`` (rounded to
    whole steps, at least one); a driving shorter than two such spans has neither (0)."""
    t, s, v, gap = (np.asarray(a, dtype=np.float64) for a in (t, s, v, gap))
    lane = np.asarray(lane, dtype=np.int64)
    assert t.ndim == 1 and len(t) >= 2 and s.shape == v.shape == lane.shape == gap.shape == t.shape
    dt = float(t[1] - t[0])
    time_s = float(t[-1] - t[0])
    km = float(np.abs(np.diff(s)).sum()) / 1000.0
    follow = np.isfinite(gap) & (gap <= FOLLOW_RANGE) & (v > MIN_FOLLOW_SPEED)
    headway = gap[follow] / v[follow]
    lag = max(1, round(DERIVATIVE_BASE_S / dt))
    acc = (v[lag:] - v[:-lag]) / (lag * dt)  # the mean acceleration over each span, at every step
    jerk = (acc[lag:] - acc[:-lag]) / (lag * dt)
    changes = lane_changes(lane, dt)
    stops = int(np.count_nonzero((v[1:] <= STOP_SPEED) & (v[:-1] > STOP_SPEED)))
    share = np.bincount(np.maximum(lane, 0), minlength=int(lane.max(initial=0)) + 1) / len(lane)
    return {
        "style/time_s": time_s,
        "style/km": km,
        "style/mean_speed": 1000.0 * km / time_s if time_s > 0 else 0.0,
        "style/headway_median_s": float(np.median(headway)) if headway.size else float("nan"),
        "style/headway_p10_s": float(np.percentile(headway, 10)) if headway.size else float("nan"),
        "style/following_s": float(follow.sum() * dt),
        "style/lane_changes": changes,
        "style/lane_changes_per_km": _per_km(changes, km),
        "style/rms_accel": float(np.sqrt(np.mean(acc**2))) if acc.size else 0.0,
        "style/rms_jerk": float(np.sqrt(np.mean(jerk**2))) if jerk.size else 0.0,
        "style/full_stops": stops,
        "style/stops_per_km": _per_km(stops, km),
        "style/lane_share": [float(x) for x in share],
    }


def pool_styles(records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Several episodes' style figures as one driving's (see the module docstring)."""
    recs = [r for r in records if r.get("style/time_s", 0) > 0]
    if not recs:
        return {}
    w = np.array([r["style/time_s"] for r in recs])
    km = float(sum(r["style/km"] for r in recs))
    time_s = float(w.sum())
    fol = np.array([r["style/following_s"] for r in recs])
    out: dict[str, Any] = {"style/time_s": time_s, "style/km": km}
    out["style/mean_speed"] = 1000.0 * km / time_s
    for k in ("style/headway_median_s", "style/headway_p10_s"):
        x = np.array([r[k] for r in recs], dtype=np.float64)
        ok = np.isfinite(x) & (fol > 0)
        out[k] = float(np.average(x[ok], weights=fol[ok])) if ok.any() else float("nan")
    out["style/following_s"] = float(fol.sum())
    counts = (("style/lane_changes", "style/lane_changes_per_km"), ("style/full_stops", "style/stops_per_km"))
    for n, per in counts:
        total = int(sum(r[n] for r in recs))
        out[n], out[per] = total, _per_km(total, km)
    for k in ("style/rms_accel", "style/rms_jerk"):
        out[k] = float(np.sqrt(np.average([r[k] ** 2 for r in recs], weights=w)))
    n_lanes = max(len(r["style/lane_share"]) for r in recs)
    shares = np.stack([style_vector(r, n_lanes)[len(STYLE_FIGURES) :] for r in recs])
    out["style/lane_share"] = [float(x) for x in np.average(shares, axis=0, weights=w)]
    return out


def style_vector(record: dict[str, Any], n_lanes: int) -> np.ndarray:
    """[len(STYLE_FIGURES) + n_lanes] the figures the style distance compares."""
    share = np.zeros(n_lanes)
    got = np.asarray(record.get("style/lane_share", []), dtype=np.float64)[:n_lanes]
    share[: len(got)] = got
    return np.concatenate([[float(record.get(k, np.nan)) for k in STYLE_FIGURES], share])


def style_spread(episodes: Sequence[dict[str, Any]], n_lanes: int | None = None) -> np.ndarray:
    """[len(STYLE_FIGURES) + n_lanes] each figure's standard deviation over ``episodes`` (style summaries
    of single episodes: of every driving compared, or in a style table of the demonstrators'): the style
    distance's normaliser. ``n_lanes``: the lane shares' count (default: the most any episode has)."""
    if n_lanes is None:
        n_lanes = max((len(e.get("style/lane_share", [])) for e in episodes), default=0)
    if not episodes:
        return np.zeros(len(STYLE_FIGURES) + n_lanes)
    x = np.stack([style_vector(e, n_lanes) for e in episodes])
    with warnings.catch_warnings():  # a figure NaN in every episode (no leader: no headway) has no spread
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanstd(x, axis=0)


def style_distances(records: Sequence[dict[str, Any]], spread: np.ndarray | None = None) -> np.ndarray:
    """[n, n] the style distance between every two of ``records`` (style summaries): the RMS over the
    figures of their difference divided by ``spread`` [F] (:func:`style_spread` of the episodes of the
    drivings compared, the definition); without it, by the figure's standard deviation across ``records``
    (drivings known only pooled). Figures without spread or NaN in either driving are left out (0 when
    none is left). Zero on the diagonal, symmetric, unchanged when a figure is scaled (units) in every
    record and its episodes."""
    n_lanes = max((len(r.get("style/lane_share", [])) for r in records), default=0)
    if spread is not None:
        n_lanes = len(spread) - len(STYLE_FIGURES)
    x = np.stack([style_vector(r, n_lanes) for r in records]) if records else np.zeros((0, 0))
    with warnings.catch_warnings():  # a figure NaN in every driving (no leader: no headway) has no spread
        warnings.simplefilter("ignore", RuntimeWarning)
        if spread is None:
            spread = np.nanstd(x, axis=0) if len(x) else np.zeros(0)
    z = x / np.where(spread > 0, spread, np.nan)
    diff = z[:, None, :] - z[None, :, :]  # [n, n, F]
    ok = np.isfinite(diff)
    sq = np.where(ok, diff, 0.0) ** 2
    count = ok.sum(axis=2)
    return np.sqrt(np.divide(sq.sum(axis=2), count, out=np.zeros(count.shape), where=count > 0))


def format_style(record: dict[str, Any]) -> str:
    """One line of a style summary for a terminal."""
    if not record:
        return "style: not recorded (no episode figures with style)"
    share = "/".join(f"{100 * x:.0f}" for x in record["style/lane_share"])
    median, p10 = record["style/headway_median_s"], record["style/headway_p10_s"]
    headway = "no leader followed" if math.isnan(median) else f"headway median {median:.2f} s p10 {p10:.2f} s"
    return (
        f"style: {3.6 * record['style/mean_speed']:.1f} km/h, {headway}, "
        f"{record['style/lane_changes_per_km']:.2f} lane changes/km, RMS accel "
        f"{record['style/rms_accel']:.2f} m/s^2 jerk {record['style/rms_jerk']:.2f} m/s^3, "
        f"{record['style/full_stops']} full stops, lane share % {share} ({record['style/km']:.2f} km)"
    )


class StyleObserver(StepListener):
    """The per-step recording of :func:`style_summary` (an episode runner observer that registers on
    the simulation's per-step listeners, like the scorecard's); :meth:`summary` after the episode."""

    def __init__(self) -> None:
        self.rows: list[tuple[float, float, float, int, float]] = []

    def start(self, sim: Any) -> None:
        self.rows = []

    def on_step(self, sim: Any) -> None:
        e = sim.ego
        gap, k = leader_ahead(sim)  # the leader in the ego's lane
        self.rows.append((e.t, e.s, e.v, int(e.lane), gap if k >= 0 else float("nan")))

    def summary(self) -> dict[str, Any]:
        """The episode's style figures (empty before two steps were recorded)."""
        if len(self.rows) < 2:
            return {}
        t, s, v, lane, gap = (np.array(c) for c in zip(*self.rows, strict=True))
        return style_summary(t, s, v, lane, gap)


def style_report(
    summaries: list[dict[str, Any]], reference: str | None = None, episodes: Sequence[dict[str, Any]] = ()
) -> str:
    """Each model's driving style on one line, and their style distances
    (:func:`irlsim.rollout.style.style_distances`, each figure divided by its spread over ``episodes``,
    the single episodes of every driving, :func:`style_spread`). A distance needs more episodes than
    drivings, or without them three drivings or more (each figure is then divided by its spread across
    the drivings: between two, every figure that differs counts exactly 2), and a line says so instead of
    a number. ``reference``: the name of a driving the others are compared with (``irlsim drive``'s
    demonstrator): a last line names the one nearest it."""
    names = [str(s.get("drive/model", i)) for i, s in enumerate(summaries)]
    lines = [f"{n}: {format_style(s.get('style') or {})}" for n, s in zip(names, summaries, strict=True)]
    eps = [e for e in episodes if e.get("style/time_s", 0) > 0]
    per_episode = len(eps) > len(summaries)
    if len(summaries) == 2 and not per_episode:
        lines.append(
            "style distance: needs more episodes than drivings, or three drivings (each figure is divided "
            "by its spread: between two single drivings, every figure that differs counts 2): add episodes"
        )
    if len(summaries) > 2 or (len(summaries) == 2 and per_episode):
        styles = [s.get("style") or {} for s in summaries]
        n_lanes = max((len(r.get("style/lane_share", [])) for r in [*styles, *eps]), default=0)
        dist = style_distances(styles, style_spread(eps, n_lanes) if per_episode else None)
        lines.append(
            "style distance: "
            + "; ".join(
                f"{names[i]} vs {names[j]} {dist[i, j]:.2f}"
                for i in range(len(names))
                for j in range(i + 1, len(names))
            )
        )
        if reference in names:
            r = names.index(reference)
            others = sorted((float(dist[r, i]), names[i]) for i in range(len(names)) if i != r)
            lines.append(
                f"nearest the {reference}'s style: {others[0][1]} ({others[0][0]:.2f}; "
                + ", ".join(f"{n} {d:.2f}" for d, n in others[1:])
                + ")"
            )
    return "\n".join(["", *lines, ""])
