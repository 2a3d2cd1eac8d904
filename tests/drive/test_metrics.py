"""Comfort and summary figures against closed-form answers."""

from __future__ import annotations

import numpy as np

from irlsim.drive.metrics import EPISODE_KEYS, jerks, markdown_table, rms, summarize


def test_constant_longitudinal_jerk_is_recovered():
    t = np.arange(0.0, 5.0, 0.1)
    j = 0.8  # [m/s^3]: v = 2 + j t^2 / 2
    j_lon, j_lat = jerks(t, 2.0 + 0.5 * j * t**2, np.zeros_like(t))
    np.testing.assert_allclose(j_lon, j, atol=1e-9)
    assert rms(j_lat) == 0.0


def test_steady_circle_has_no_lateral_jerk_and_a_curve_entry_has_some():
    t = np.arange(0.0, 10.0, 0.1)
    v = np.full_like(t, 20.0)
    _, j_lat = jerks(t, v, np.pi - 0.1 * t)  # 20 m/s on a 200 m circle, heading wrapping through +-pi
    np.testing.assert_allclose(j_lat, 0.0, atol=1e-9)
    # yaw rate ramping from 0 to 0.1 rad/s in 2 s: a_lat = v * rate grows at 1 m/s^3
    rate = np.clip(t - 4.0, 0.0, 2.0) * 0.05
    yaw = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * 0.1)])
    _, j_lat = jerks(t, v, yaw)
    assert 0.9 < np.abs(j_lat).max() < 1.1 and rms(j_lat) > 0.1


def _episode(model="m", collisions=0, speed=50.0, steps=100, p90=2.0, compliant=1):
    rec = dict.fromkeys(EPISODE_KEYS, 0)
    rec.update(
        {
            "drive/model": model,
            "drive/cycles": steps // 2,
            "drive/laps": 1,
            "drive/collisions": collisions,
            "drive/stop_lines_passed": 1,
            "drive/stop_lines_compliant": compliant,
            "drive/checkpoints_passed": 2,
            "drive/checkpoints_in_lane": 2,
            "drive/mean_speed_kmh": speed,
            "drive/distance_m": 1000.0,
            "drive/time_s": 72.0,
            "drive/rms_jerk_lon": 1.0,
            "drive/rms_jerk_lat": 2.0,
            "drive/inference_ms_mean": 1.0,
            "drive/inference_ms_p90": p90,
            "drive/end_reason": "laps",
            "sim/steps": steps,
        }
    )
    return rec


def test_summary_sums_counts_and_weights_rates():
    s = summarize(
        [_episode(collisions=1, speed=40.0, steps=100, compliant=0), _episode(speed=60.0, steps=300)],
        inference_ms=list(range(1, 11)),
    )
    assert s["drive/episodes"] == 2 and s["drive/collisions"] == 1 and s["drive/laps"] == 2
    assert s["drive/stop_compliance"] == 0.5 and s["drive/checkpoint_compliance"] == 1.0
    assert s["drive/mean_speed_kmh"] == 55.0  # step-weighted
    assert s["drive/rms_jerk_lon"] == 1.0 and s["drive/inference_ms_p90"] == np.percentile(range(1, 11), 90)
    assert s["drive/end_reasons"] == {"laps": 2}
    table = markdown_table([s, summarize([_episode("expert")])])
    assert table.count("\n") == 4 and "| m | 2 | 2 | 1 | 0 | 1/2 | 4/4 | 55.0 |" in table
