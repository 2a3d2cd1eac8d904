"""The 15 features: non-negative, named, and hand-computed cases (issue 3, point 4)."""

from __future__ import annotations

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.road import LANE_WIDTH

from .conftest import make_obs, make_vehicles

F = {n: i for i, n in enumerate(FEATURE_NAMES)}
STRAIGHT_S = 250.0


def _cruise(planner, ps, v0):
    """Index of the lane-keeping policy at constant speed v0 (a = 0 throughout)."""
    inner = planner.last
    keep = np.all(np.abs(ps.d - ps.d[:, :1]) < 1e-9, axis=1)
    const = np.all(np.abs(ps.v - v0) < 1e-9, axis=1) & np.all(np.abs(inner.a) < 1e-9, axis=1)
    idx = np.flatnonzero(keep & const)
    assert len(idx), "no constant-speed lane keeping policy"
    return int(idx[0])


def test_features_non_negative_everywhere(road, planner):
    cases = [
        make_obs(
            road, STRAIGHT_S, 0.0, 15.0, vehicles=make_vehicles(road, [(270.0, 0.0, 5.0), (240.0, 3.2, 9.0)])
        ),
        make_obs(road, road.stop_lines[0].s - 30.0, LANE_WIDTH, 10.0, stop_s=road.stop_lines[0].s),
        make_obs(road, road.exits[0].s_start - 30.0, -LANE_WIDTH, 18.0),
        make_obs(road, 700.0, 0.0, 19.0),  # in a curve
    ]
    for obs in cases:
        ps = planner.plan(obs)
        assert np.all(np.isfinite(ps.features)) and np.all(ps.features >= 0)
    assert len(FEATURE_NAMES) == ps.features.shape[1] == 15


def test_constant_speed_on_straight_lane_centre_costs_nothing(road, planner):
    v0 = 0.0 + 15.0
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, v0))
    i = _cruise(planner, ps, v0)
    f = ps.features[i]
    for name in (
        "acc_lon",
        "jerk_lon",
        "acc_lat",
        "jerk_lat",
        "centerline",
        "lc_delay",
        "lat_overshoot",
        "end_heading",
        "road_edge",
        "proximity",
        "stop_line",
        "creep",
    ):
        assert f[F[name]] < 1e-6, f"{name} = {f[F[name]]}"
    # velocity: (70 km/h - 15 m/s)^2 * sum_t gamma^t dt
    w = planner.w.astype(np.float64)
    assert f[F["velocity"]] == np.float32(((70 / 3.6 - v0) ** 2 * w.sum()).astype(np.float32)) or np.isclose(
        f[F["velocity"]], (70 / 3.6 - v0) ** 2 * w.sum(), rtol=1e-4
    )


def test_lc_delay_grows_when_the_same_lane_change_comes_later(road, planner):
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0))
    inner = planner.last
    v = np.all(np.abs(ps.v - 15.0) < 1e-9, axis=1) & np.all(np.abs(inner.a) < 1e-9, axis=1)
    to_left = v & (np.abs(ps.d[:, -1] - LANE_WIDTH) < 1e-6)
    # when the offset first exceeds half a lane: early (stage 1) vs late (stage 2) lane changes
    t_cross = np.argmax(ps.d > LANE_WIDTH / 2, axis=1)
    early = to_left & (t_cross < 20)
    late = to_left & (t_cross > 30)
    assert early.any() and late.any()
    assert ps.features[late, F["lc_delay"]].min() > ps.features[early, F["lc_delay"]].max()


def test_a_policy_through_a_predicted_vehicle_has_high_proximity(road, planner):
    veh = make_vehicles(road, [(STRAIGHT_S + 30.0, 0.0, 5.0)])  # slower, ahead in the ego's lane
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0, vehicles=veh))
    prox = ps.features[:, F["proximity"]]
    hit = ps.labels[:, 0]
    assert hit.any() and (~hit).any()
    i = _cruise(planner, ps, 15.0)
    assert hit[i], "driving on at 15 m/s into a 5 m/s vehicle 30 m ahead must be a predicted collision"
    assert prox[i] > 0.5
    assert prox[i] > 5 * np.median(prox[~hit])
    # the other lanes, kept away from the vehicle, see (almost) none of it
    other = np.all(np.abs(ps.d - LANE_WIDTH) < 1e-6, axis=1)[:] | np.all(
        np.abs(ps.d + LANE_WIDTH) < 1e-6, axis=1
    )
    assert prox[other].max() < 0.05 if other.any() else True


def test_stop_line_costs_crossing_at_speed_not_stopping(road, planner):
    line = road.stop_lines[1].s
    ps = planner.plan(make_obs(road, line - 30.0, 0.0, 12.0, stop_s=line))
    cost = ps.features[:, F["stop_line"]]
    crossed = ps.s.max(axis=1) >= line
    stood = ps.v.min(axis=1) < 0.1
    fast = crossed & ~stood
    assert fast.any() and np.all(cost[fast] > 1.0)
    # each crossing costs at least gamma^t (1 + v) with v its speed at the line
    stopped_before = ~crossed & stood
    assert stopped_before.any() and np.all(cost[stopped_before] == 0)
    # without an active stop line nothing costs
    ps2 = planner.plan(make_obs(road, line - 30.0, 0.0, 12.0))
    assert np.all(ps2.features[:, F["stop_line"]] == 0)


def test_taking_an_exit_costs_progress(road, planner):
    ex = road.exits[0]
    ps = planner.plan(make_obs(road, ex.s_start - 30.0, -LANE_WIDTH, 15.0))
    inner = planner.last
    exits = np.flatnonzero(ps.labels[:, 2])
    assert len(exits)
    keep = np.all(np.abs(ps.d + LANE_WIDTH) < 1e-6, axis=1)
    for i in exits[:20]:
        same_lon = np.flatnonzero(keep & (inner.lon_idx == inner.lon_idx[i]))
        assert len(same_lon)
        assert ps.features[i, F["progress"]] > ps.features[same_lon[0], F["progress"]] + 100.0


def test_mission_lane_prefers_the_required_lane(road, planner):
    cp = road.checkpoints[1]  # requires lane 0
    ps = planner.plan(make_obs(road, cp.s - 150.0, LANE_WIDTH, 15.0))
    f = ps.features[:, F["mission_lane"]]
    end_lane = ps.lane[:, -1]
    assert f[end_lane == 0].min() < f[end_lane == 2].min()


def test_velocity_target_is_zero_at_an_active_stop_line(road, planner):
    line = road.stop_lines[0].s
    ps = planner.plan(make_obs(road, line - 20.0, 0.0, 8.0, stop_s=line))
    f = ps.features[:, F["velocity"]]
    stop = ps.v[:, -1] < 0.1
    assert f[stop].min() < f[~stop].min()
