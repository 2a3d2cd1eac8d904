"""The style summary against closed-form answers on synthetic drivings, its pooling, and the style
distance's properties (zero to itself, symmetric, scale-free) and its normaliser against a closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from irlsim.rollout.style import (
    DERIVATIVE_BASE_S,
    STYLE_FIGURES,
    format_style,
    lane_changes,
    pool_styles,
    style_distances,
    style_report,
    style_spread,
    style_summary,
)

DT = 0.1


def _drive(n: int = 1001, v: float = 10.0, gap: float = float("nan"), lane: int = 1) -> dict:
    t = np.arange(n) * DT
    return {
        "t": t,
        "s": v * t,
        "v": np.full(n, v),
        "lane": np.full(n, lane),
        "gap": np.full(n, gap),
    }


def test_constant_speed_in_one_lane():
    r = style_summary(**_drive())
    assert r["style/time_s"] == pytest.approx(100.0)
    assert r["style/km"] == pytest.approx(1.0)
    assert r["style/mean_speed"] == pytest.approx(10.0)
    assert r["style/rms_accel"] == pytest.approx(0.0, abs=1e-9)
    assert r["style/rms_jerk"] == pytest.approx(0.0, abs=1e-9)
    assert r["style/lane_changes"] == 0 and r["style/full_stops"] == 0
    assert r["style/lane_share"] == [0.0, 1.0]
    assert math.isnan(r["style/headway_median_s"]) and r["style/following_s"] == 0.0


def test_known_headway_and_a_leader_out_of_range():
    d = _drive(v=10.0, gap=20.0)  # 20 m at 10 m/s: 2 s
    d["gap"][500:] = 150.0  # beyond FOLLOW_RANGE: not following
    r = style_summary(**d)
    assert r["style/headway_median_s"] == pytest.approx(2.0)
    assert r["style/headway_p10_s"] == pytest.approx(2.0)
    assert r["style/following_s"] == pytest.approx(50.0)
    d["gap"][:500] = np.linspace(10.0, 40.0, 500)  # headways 1..4 s, uniformly
    r = style_summary(**d)
    assert r["style/headway_median_s"] == pytest.approx(2.5, abs=1e-6)
    assert r["style/headway_p10_s"] == pytest.approx(1.3, abs=1e-6)


def test_one_lane_change_over_a_known_distance_and_the_lane_shares():
    d = _drive(n=501, v=10.0, lane=0)  # 500 m
    d["lane"][125:] = 1
    r = style_summary(**d)
    assert r["style/lane_changes"] == 1
    assert r["style/lane_changes_per_km"] == pytest.approx(2.0)
    assert r["style/lane_share"] == pytest.approx([125 / 501, 376 / 501])


def test_lane_changes_with_short_returns_not_counted():
    # lanes 0 (2 s), 1 (0.3 s), 0 (2 s), 1 (3 s), 2 (0.5 s), 1 (0.2 s), 2 (4 s), at 0.1 s steps
    lane = np.repeat([0, 1, 0, 1, 2, 1, 2], [20, 3, 20, 30, 5, 2, 40])
    assert (
        lane_changes(lane, DT)
        == 6
        == style_summary(**_drive(n=len(lane)) | {"lane": lane})["style/lane_changes"]
    )
    assert lane_changes(lane, DT, 1.0) == 2  # both returns dropped: 0 -> 1 -> 2
    assert lane_changes(lane, DT, 0.25) == 4  # only the 0.2 s return dropped
    flicker = np.repeat([1, 2, 1, 2, 1, 2, 1], [30, 1, 1, 1, 1, 1, 30])  # a flicker of returns: none
    assert lane_changes(flicker, DT, 1.0) == 0 and lane_changes(flicker, DT) == 6
    assert lane_changes(np.repeat([0, 1], [5, 5]), DT, 1.0) == 1  # a change that does not return counts
    assert lane_changes(np.array([2]), DT, 1.0) == 0


def test_a_known_jerk_and_a_full_stop():
    j = 0.5  # [m/s^3]: a = j t, v = 5 + j t^2 / 2
    t = np.arange(201) * DT
    v = 5.0 + 0.5 * j * t**2
    s = 5.0 * t + j * t**3 / 6
    r = style_summary(t, s, v, np.zeros(201, int), np.full(201, np.nan))
    assert r["style/rms_jerk"] == pytest.approx(j, rel=1e-9)
    base = DERIVATIVE_BASE_S  # the mean acceleration over each span: exact at the span's midpoint
    acc = j * (t[: -round(base / DT)] + base / 2)
    assert r["style/rms_accel"] == pytest.approx(float(np.sqrt(np.mean(acc**2))), rel=1e-9)
    v = np.concatenate([np.full(50, 5.0), np.zeros(20), np.full(50, 5.0), np.zeros(10)])
    r = style_summary(np.arange(130) * DT, np.cumsum(v) * DT, v, np.zeros(130, int), np.full(130, np.nan))
    assert r["style/full_stops"] == 2


def test_acceleration_and_jerk_do_not_depend_on_the_recording_rate():
    """A smooth driving's figures from its 0.1 s rows and from its 1 s rows resampled to the step (as a
    recording is) agree with each other and with the closed form; at the step itself they would not
    (the resampled speed is piecewise linear: its jerk is all in single steps)."""
    amp, w = 3.0, 0.5  # v = 12 + amp sin(w t): RMS accel amp w / sqrt(2), RMS jerk amp w^2 / sqrt(2)
    t = np.arange(6001) * DT
    v = 12.0 + amp * np.sin(w * t)
    coarse = np.interp(t, t[::10], v[::10])  # a 1 s recording, linearly resampled to the step
    fine, rec = (
        style_summary(t, np.cumsum(x) * DT, x, np.zeros(len(t), int), np.full(len(t), np.nan))
        for x in (v, coarse)
    )
    span = w * DERIVATIVE_BASE_S / 2  # a difference over the span sees sin(span) / span of the sinusoid
    assert fine["style/rms_accel"] == pytest.approx(amp * w / math.sqrt(2) * math.sin(span) / span, rel=1e-3)
    assert fine["style/rms_jerk"] == pytest.approx(
        amp * w**2 / math.sqrt(2) * (math.sin(span) / span) ** 2, rel=1e-3
    )
    for k in ("style/rms_accel", "style/rms_jerk"):
        assert rec[k] == pytest.approx(fine[k], rel=0.03)
    step_jerk = np.sqrt(np.mean((np.diff(coarse, 2) / DT**2) ** 2))
    assert step_jerk > 2.5 * fine["style/rms_jerk"]  # what the step basis would have measured


def test_a_driving_shorter_than_two_spans_has_no_jerk():
    t = np.arange(15) * DT  # 1.4 s: one span of acceleration, none of jerk
    v = 5.0 + t
    r = style_summary(t, np.cumsum(v) * DT, v, np.zeros(15, int), np.full(15, np.nan))
    assert r["style/rms_accel"] == pytest.approx(1.0) and r["style/rms_jerk"] == 0.0


def test_pooling_is_exact_for_additive_figures():
    a, b = _drive(n=501, v=10.0), _drive(n=1001, v=20.0, lane=0)
    ra, rb = style_summary(**a), style_summary(**b)
    p = pool_styles([ra, rb])
    assert p["style/km"] == pytest.approx(ra["style/km"] + rb["style/km"])
    assert p["style/mean_speed"] == pytest.approx(1000 * p["style/km"] / (50.0 + 100.0))
    assert p["style/lane_share"] == pytest.approx([100 / 150, 50 / 150])
    one = pool_styles([ra])
    assert one.pop("style/lane_share") == ra["style/lane_share"]
    assert one == pytest.approx({k: v for k, v in ra.items() if k != "style/lane_share"}, nan_ok=True)


def _styles() -> list[dict]:
    rng = np.random.default_rng(0)
    out = []
    for v, g in ((10.0, 20.0), (15.0, 30.0), (12.0, 60.0), (20.0, 25.0)):
        d = _drive(v=v, gap=g)
        d["v"] = d["v"] + rng.normal(0, 0.1, len(d["v"]))
        d["lane"][rng.integers(100, 900) :] = 0
        out.append(style_summary(**d))
    return out


def test_style_distance_properties():
    styles = _styles()
    dist = style_distances(styles)
    assert dist.shape == (4, 4)
    np.testing.assert_allclose(np.diag(dist), 0.0, atol=1e-12)  # zero to itself
    np.testing.assert_allclose(dist, dist.T)  # symmetric
    assert (dist[~np.eye(4, dtype=bool)] > 0).all()
    # scale-free: every figure in other units (km/h, ms, per mile, ...) gives the same distances
    scaled = [
        {**s, **{k: 3.7 * s[k] for k in STYLE_FIGURES}, "style/lane_share": s["style/lane_share"]}
        for s in styles
    ]
    np.testing.assert_allclose(style_distances(scaled), dist, rtol=1e-9)
    # and the same driving twice is at distance zero from itself and equally far from the others
    twice = style_distances([styles[0], styles[0], styles[1], styles[2]])
    assert twice[0, 1] == pytest.approx(0.0, abs=1e-12)
    assert twice[0, 2] == pytest.approx(twice[1, 2])


def test_the_terminal_line_says_when_no_leader_was_followed():
    alone = format_style(style_summary(**_drive()))  # 1 km at 10 m/s, nobody ahead
    assert "no leader followed" in alone and "nan" not in alone and "36.0 km/h" in alone
    following = format_style(style_summary(**_drive(gap=20.0)))  # 20 m at 10 m/s: 2 s
    assert "headway median 2.00 s p10 2.00 s" in following and "no leader" not in following


def test_the_report_gives_distances_from_three_drivings_and_says_why_not_for_two():
    drivings = [
        {"drive/model": name, "style": style_summary(**_drive(v=v, gap=g))}
        for name, v, g in (("a", 10.0, 20.0), ("b", 12.0, 30.0), ("c", 14.0, 20.0))
    ]
    two = style_report(drivings[:2])
    assert "needs more episodes than drivings, or three drivings" in two and "a vs b" not in two
    three = style_report(drivings).strip().splitlines()[-1]
    d = style_distances([r["style"] for r in drivings])
    assert three == f"style distance: a vs b {d[0, 1]:.2f}; a vs c {d[0, 2]:.2f}; b vs c {d[1, 2]:.2f}"
    # against a reference driving: the others by their distance to it, the nearest named first
    near = style_report(drivings, reference="c").strip().splitlines()[-1]
    (first, d_first), (second, d_second) = sorted(
        ((n, d[2, i]) for i, n in enumerate("ab")), key=lambda x: x[1]
    )
    assert near == f"nearest the c's style: {first} ({d_first:.2f}; {second} {d_second:.2f})"
    assert d_first < d_second
    assert "nearest" not in style_report(drivings, reference="x") and "nearest" not in two


def test_the_normaliser_is_each_figures_spread_over_the_episodes():
    # four 100 s episodes at 10, 12, 14 and 16 m/s, nobody ahead, one lane: only the speed varies
    speeds = (10.0, 12.0, 14.0, 16.0)
    eps = [{"drive/model": m, **style_summary(**_drive(v=v))} for m, v in zip("aabb", speeds, strict=True)]
    spread = style_spread(eps)
    speed = STYLE_FIGURES.index("style/mean_speed")
    assert spread[speed] == pytest.approx(math.sqrt(5.0))  # the standard deviation of 10, 12, 14, 16
    assert np.count_nonzero(spread > 0) == 1  # no other figure varies (headway: NaN, left out)
    # two drivings pooled from two episodes each, 11 and 15 m/s: their distance is 4 / sqrt(5), where
    # divided by their own spread (2) it would be 2 whatever the difference
    a, b = pool_styles(eps[:2]), pool_styles(eps[2:])
    d = style_distances([a, b], spread)
    assert d[0, 1] == pytest.approx(4.0 / math.sqrt(5.0))
    assert style_distances([a, b])[0, 1] == pytest.approx(2.0)
    # scale-free with its episodes: the speed in km/h everywhere gives the same distance
    kmh = [{**e, "style/mean_speed": 3.6 * e["style/mean_speed"]} for e in eps]
    a_kmh, b_kmh = ({**x, "style/mean_speed": 3.6 * x["style/mean_speed"]} for x in (a, b))
    assert style_distances([a_kmh, b_kmh], style_spread(kmh))[0, 1] == pytest.approx(d[0, 1])
    # the report: with more episodes than drivings, two drivings get that distance
    report = style_report([{"drive/model": "a", "style": a}, {"drive/model": "b", "style": b}], episodes=eps)
    assert f"style distance: a vs b {d[0, 1]:.2f}" in report
    assert style_spread([]).shape == (len(STYLE_FIGURES),)
