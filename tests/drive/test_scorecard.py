"""The scorecard's metrics against hand-made trajectories with closed-form answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from irlsim.drive import scorecard as sc

DT = 0.1


def _line(v: np.ndarray, yaw: np.ndarray | None = None):
    t = np.arange(len(v)) * DT
    yaw = np.zeros(len(v)) if yaw is None else yaw
    return t, v, yaw


def test_comfort_constant_acceleration_exact():
    t = np.arange(50) * DT
    v = 10.0 + 2.0 * t  # a = 2, jerk 0, straight
    q = sc.comfort_series(t, v, np.zeros_like(t))
    np.testing.assert_allclose(q["lon_acc"], 2.0, atol=1e-9)
    np.testing.assert_allclose(q["lon_jerk"], 0.0, atol=1e-9)
    np.testing.assert_allclose(q["jerk"], 0.0, atol=1e-9)
    np.testing.assert_allclose(q["yaw_rate"], 0.0, atol=1e-12)
    assert sc.comfort_within(q).all()
    # 2.5 m/s^2 exceeds nuPlan's 2.40 upper bound everywhere
    assert not sc.comfort_within(sc.comfort_series(t, 10.0 + 2.5 * t, np.zeros_like(t))).any()


def test_comfort_quadratic_speed_gives_constant_jerk():
    t = np.arange(40) * DT
    v = 5.0 + 0.5 * 3.0 * t**2  # a = 3 t, lon. jerk 3 (inside 4.13) until a > 2.40 at t > 0.8 s
    q = sc.comfort_series(t, v, np.zeros_like(t))
    np.testing.assert_allclose(q["lon_acc"], 3.0 * t, atol=1e-9)
    np.testing.assert_allclose(q["lon_jerk"], 3.0, atol=1e-8)
    within = sc.comfort_within(q)
    np.testing.assert_array_equal(within, 3.0 * t <= 2.40 + 1e-12)


def test_comfort_circle_lateral_and_yaw():
    t = np.arange(30) * DT
    v, r = 10.0, 25.0
    yaw = v / r * t  # yaw rate 0.4 rad/s, lateral acc v^2 / r = 4 m/s^2
    q = sc.comfort_series(t, np.full_like(t, v), yaw)
    np.testing.assert_allclose(q["yaw_rate"], 0.4, atol=1e-9)
    np.testing.assert_allclose(q["lat_acc"], 4.0, atol=1e-9)
    np.testing.assert_allclose(q["yaw_acc"], 0.0, atol=1e-9)
    assert sc.comfort_within(q).all()
    q2 = sc.comfort_series(t, np.full_like(t, 12.0), 12.0 / r * t)  # 5.76 m/s^2 > 4.89
    assert not sc.comfort_within(q2).any()


def _veh(x, v, yaw=0.0, length=5.0, width=2.0):
    return np.array([[[x, 0.0, yaw, v, length, width]]])


def test_ttc_standing_vehicle_ahead_closed_form():
    # ego front bumper at 0 moving +x at 10 m/s; a standing car's front bumper at 10 m, length 5: its
    # rear is 5 m ahead, so the boxes first overlap after 0.5 s (on the 0.1 s grid: first tau > 0.5)
    ego = np.array([[0.0, 0.0, 0.0, 10.0]])
    ttc = sc.time_to_collision(ego, (5.0, 2.0), _veh(10.0, 0.0))
    assert ttc[0] == pytest.approx(0.6)  # touching at 0.5 s is no overlap; 0.6 s overlaps
    ttc = sc.time_to_collision(ego, (5.0, 2.0), _veh(10.05, 0.0))
    assert ttc[0] == pytest.approx(0.6)
    # same gap, the leader drives 5 m/s: closing speed 5, first overlap after 1.0 s -> beyond 1.0 -> inf
    assert math.isinf(sc.time_to_collision(ego, (5.0, 2.0), _veh(10.0, 5.0))[0])
    assert sc.time_to_collision(ego, (5.0, 2.0), _veh(9.9, 5.0))[0] == pytest.approx(1.0)


def test_ttc_ignores_behind_absent_and_standing_ego():
    ego = np.array([[0.0, 0.0, 0.0, 10.0]])
    behind = np.array([[[-6.0, 0.0, 0.0, 20.0, 5.0, 2.0]]])  # faster car behind: not the ego's fault
    assert math.isinf(sc.time_to_collision(ego, (5.0, 2.0), behind)[0])
    absent = np.full((1, 1, 6), np.nan)
    assert math.isinf(sc.time_to_collision(ego, (5.0, 2.0), absent)[0])
    stopped = np.array([[0.0, 0.0, 0.0, 0.0]])
    assert math.isinf(sc.time_to_collision(stopped, (5.0, 2.0), _veh(5.5, 0.0))[0])
    # other lane (3.2 m to the side): never overlaps
    side = np.array([[[10.0, 3.2, 0.0, 0.0, 5.0, 2.0]]])
    assert math.isinf(sc.time_to_collision(ego, (5.0, 2.0), side)[0])


def test_ttc_vectorised_over_steps_and_vehicles():
    # S = 3 steps, M = 2 vehicles (one missing at step 2): per-step minimum over vehicles
    ego = np.array([[0.0, 0.0, 0.0, 10.0]] * 3)
    veh = np.full((3, 2, 6), np.nan)
    veh[0, 0] = [10.0, 0.0, 0.0, 0.0, 5.0, 2.0]  # 0.6 s
    veh[0, 1] = [8.0, 0.0, 0.0, 0.0, 5.0, 2.0]  # rear 3 m ahead: 0.4 s
    veh[1, 0] = [10.0, 0.0, 0.0, 0.0, 5.0, 2.0]
    veh[2, 1] = [30.0, 0.0, 0.0, 0.0, 5.0, 2.0]  # 25 m: inf
    ttc = sc.time_to_collision(ego, (5.0, 2.0), veh)
    np.testing.assert_allclose(ttc[:2], [0.4, 0.6])
    assert math.isinf(ttc[2])


def test_speed_limit_compliance_closed_form():
    t = np.arange(11) * 1.0  # 10 s
    v = np.full(11, 20.0)
    assert sc.speed_limit_compliance(t, v, limit=25.0) == 1.0
    v[6:] = 26.0  # 1 m/s over during 5 of 10 s: mean 0.5 m/s over -> 1 - 0.5 / 2.23
    assert sc.speed_limit_compliance(t, v, limit=25.0) == pytest.approx(1.0 - 0.5 / 2.23)
    assert sc.speed_limit_compliance(t, np.full(11, 30.0), limit=25.0) == 0.0


def test_progress_ratio_closed_form():
    t = np.arange(101) * DT  # 10 s
    ego_s, exp_s = 100.0 + 10.0 * t, 50.0 + 20.0 * t
    assert sc.progress_ratio(t, ego_s, t, exp_s) == pytest.approx(0.5)
    # the ego's episode ends after 5 s (a collision): compare the first 5 s of both
    assert sc.progress_ratio(t[:51], 20.0 * t[:51], t, exp_s) == pytest.approx(1.0)
    assert sc.progress_ratio(t, 30.0 * t, t, exp_s) == 1.0  # capped
    assert sc.progress_ratio(t, 10.0 * t, t, np.zeros_like(t)) == 1.0


def test_drivable_intrusion():
    d = np.array([0.0, 3.0, 5.2, -6.0])
    exempt = np.array([False, False, False, True])
    assert sc.drivable_intrusion(d, 2.0, 4.8, exempt) == pytest.approx(5.2 + 1.0 - 4.8)
    assert sc.drivable_intrusion(d, 2.0, 4.8, np.array([False] * 4)) == pytest.approx(6.0 + 1.0 - 4.8)


def test_composite_weights_and_multipliers():
    ones = {k: 1.0 for k in sc.WEIGHTS}
    assert sc.composite({k: 1.0 for k in sc.MULTIPLIERS}, ones) == pytest.approx(100.0)
    terms = dict(ones, ttc=0.0)  # weight 5 of 20
    assert sc.composite({"a": 1.0}, terms) == pytest.approx(75.0)
    assert sc.composite({"a": 0.5}, terms) == pytest.approx(37.5)
    assert sc.composite({"a": 0.0}, ones) == 0.0
    terms = dict(ones, progress=None, mission=0.0)  # progress drops out: 1 - 4 / 15
    assert sc.composite({"a": 1.0}, terms) == pytest.approx(100.0 * 11.0 / 15.0)


def _episode(**kw):
    n = 51
    t = np.arange(n) * DT
    base = dict(
        t=t,
        x=15.0 * t,
        y=np.zeros(n),
        yaw=np.zeros(n),
        v=np.full(n, 15.0),
        s=15.0 * t,
        d=np.zeros(n),
        vehicles=np.zeros((n, 0, 6)),
        ego_size=(5.0, 2.0),
        half_road=4.8,
        exempt=np.zeros(n, dtype=bool),
        collisions=0,
        exits=0,
        stop_lines_passed=2,
        stop_lines_compliant=2,
        checkpoints_passed=4,
        checkpoints_in_lane=4,
        expert=(t, 15.0 * t),
    )
    base.update(kw)
    return sc.episode_scorecard(**base)


def test_episode_scorecard_perfect_and_failures():
    rec = _episode()
    assert rec["score/score"] == 100.0
    assert set(sc.SCORE_KEYS) <= set(rec)
    assert _episode(collisions=1)["score/score"] == 0.0
    assert _episode(exits=1)["score/score"] == 0.0
    # a route with yield points: failing to yield is a failure like a red crossing; without, no key
    assert _episode(yield_violations=1)["score/no_yield_violation"] == 0.0
    assert _episode(yield_violations=1)["score/score"] == 0.0
    assert _episode(yield_violations=0)["score/score"] == 100.0
    assert "score/no_yield_violation" not in rec
    assert _episode(stop_lines_compliant=1)["score/score"] == pytest.approx(50.0)
    # mission 2 of 4 in lane: 1 - 0.5 * 4 / 20
    assert _episode(checkpoints_in_lane=2)["score/score"] == pytest.approx(90.0)
    # half the expert's progress: progress term 0.5 (weight 5 of 20)
    n = 51
    t = np.arange(n) * DT
    assert _episode(expert=(t, 30.0 * t))["score/score"] == pytest.approx(87.5)
    # below 20 % of the expert's progress: the making-progress multiplier zeroes the score
    assert _episode(expert=(t, 100.0 * t))["score/score"] == 0.0
    # no expert run: progress None, weights renormalised over the rest
    rec = _episode(expert=None)
    assert rec["score/progress"] is None and rec["score/score"] == 100.0
    # off the road by more than 0.3 m
    assert _episode(d=np.full(n, 4.2))["score/drivable_area"] == 0.0
    assert _episode(d=np.full(n, 4.0))["score/drivable_area"] == 1.0


def test_summarize_scores_means_and_min():
    a, b = _episode(), _episode(stop_lines_compliant=1)
    s = sc.summarize_scores([a, b])
    assert s["score/score"] == pytest.approx(75.0)
    assert s["score/score_std"] == pytest.approx(25.0)
    assert s["score/stop_lines"] == pytest.approx(0.75)
