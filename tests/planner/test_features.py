"""The 15 features: non-negative, named, and hand-computed cases."""

from __future__ import annotations

import numpy as np
import pytest

from irlsim import FEATURE_NAMES
from irlsim.planner.config import PlannerConfig
from irlsim.planner.features import Context, lon_features
from irlsim.planner.planner import Planner
from irlsim.planner.sampler import LonBank
from irlsim.road import HALF_ROAD, LANE_WIDTH

from .conftest import make_obs, make_vehicles

F32 = np.float32

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


def test_no_feature_but_the_missions_prefers_a_side(road, planner):
    """The reward family prices no lane for its own sake: in the middle lane of the oval's straight,
    without traffic, every policy and its mirror image (the lateral profile negated, the same
    longitudinal one) have the same 14 features; only the mission's lane differs (the next checkpoint
    requires a lane). So a driver's habit of keeping left or right is no weight a reward can learn (the
    style study's lane shares, docs/results/styles.md)."""
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0))
    d, v = np.round(ps.d.astype(np.float64), 4), np.round(ps.v.astype(np.float64), 4)
    key = {(di.tobytes(), vi.tobytes()): i for i, (di, vi) in enumerate(zip(d, v, strict=True))}
    mirror = [((-d[i] + 0.0).tobytes(), v[i].tobytes()) for i in range(len(d))]  # + 0.0: no -0.0
    pairs = np.array([(i, key[k]) for i, k in enumerate(mirror) if k in key])
    sideways = np.abs(d[pairs[:, 0], -1]) > LANE_WIDTH / 2
    assert len(pairs) > len(d) / 2 and sideways.sum() > 100  # lane changes to both sides among them
    a, b = ps.features[pairs[:, 0]], ps.features[pairs[:, 1]]
    others = [i for i in range(len(FEATURE_NAMES)) if i != F["mission_lane"]]
    np.testing.assert_array_equal(a[:, others], b[:, others])
    assert np.any(a[sideways, F["mission_lane"]] != b[sideways, F["mission_lane"]])


def test_the_lane_pair_counts_the_lanes_beside_the_ego_and_leaves_the_15_as_they_are(road, planner):
    """``planner.feature_set = "lanes"``: the same 15 columns, bit for bit, and two more: the lanes to the
    ego's right and to its left at each step, whole lanes at a lane's centre. Cruising in the middle lane
    of three: one lane each side at every step, sum_t w_t each; a policy and its mirror image swap them."""
    lanes = Planner(road, PlannerConfig(feature_set="lanes"))
    obs = make_obs(road, STRAIGHT_S, 0.0, 15.0)
    ps, pl = planner.plan(obs), lanes.plan(obs)
    assert pl.features.shape == (ps.n_policies, 17)
    np.testing.assert_array_equal(pl.features[:, :15], ps.features)
    right, left = pl.features[:, 15], pl.features[:, 16]
    i = _cruise(lanes, pl, 15.0)
    w = float(lanes.w.astype(np.float64).sum())
    assert right[i] == pytest.approx(w, rel=1e-5) and left[i] == pytest.approx(w, rel=1e-5)
    d, v = np.round(pl.d.astype(np.float64), 4), np.round(pl.v.astype(np.float64), 4)
    key = {(di.tobytes(), vi.tobytes()): j for j, (di, vi) in enumerate(zip(d, v, strict=True))}
    mirror = [((-d[j] + 0.0).tobytes(), v[j].tobytes()) for j in range(len(d))]
    pairs = np.array([(j, key[k]) for j, k in enumerate(mirror) if k in key])
    np.testing.assert_allclose(right[pairs[:, 0]], left[pairs[:, 1]], rtol=1e-5, atol=1e-6)
    # straight lane changes to the left (no swerve to the right first): more lanes to the right, fewer left
    to_left = (np.abs(pl.d[:, -1] - LANE_WIDTH) < 1e-6) & np.all(np.diff(pl.d, axis=1) >= -1e-9, axis=1)
    assert to_left.any() and (right[to_left] > right[i]).all() and (left[to_left] < left[i]).all()


def _expected_proximity(planner, ps, i, s_front, d_veh, v_veh, length=4.5):
    """The documented proximity of policy ``i`` against one vehicle at constant speed, computed here
    from the policy's own arrays: sum_t w_t (exp(-(gap / D)^2) exp(-(dd / sigma_d)^2) + K [overlap])."""
    cfg = planner.cfg
    w = planner.w.astype(np.float64)
    t = np.arange(cfg.n_steps) * cfg.dt
    dS = (ps.s[i] - cfg.ego_length / 2) - (s_front + v_veh * t - length / 2)
    half_l = (cfg.ego_length + length) / 2
    gap = np.maximum(np.abs(dS) - half_l, 0.0)
    v = ps.v[i].astype(np.float64)
    behind = cfg.proximity_headway * v + np.maximum(v**2 - v_veh**2, 0.0) / (2 * cfg.proximity_decel)
    ahead = cfg.proximity_rear_headway * v_veh + np.maximum(v_veh**2 - v**2, 0.0) / (2 * cfg.proximity_decel)
    D = cfg.proximity_sigma_s + np.where(dS < 0, behind, ahead)
    dd = ps.d[i] - d_veh
    near = np.exp(-((gap / D) ** 2)) * np.exp(-((dd / cfg.proximity_sigma_d) ** 2))
    overlap = (np.abs(dS) < half_l + cfg.collision_margin_lon) & (
        np.abs(dd) < (cfg.ego_width + 1.8) / 2 + cfg.collision_margin_lat
    )
    return float(near @ w), float(overlap @ w)


def test_proximity_of_following_at_equal_speed_is_the_closed_form(road, planner):
    """15 m/s behind a 15 m/s vehicle, bumper gap 25.5 m, same lane: the gap stays, D = sigma_0 + h v,
    so proximity = exp(-(25.5 / D)^2) sum_t w_t, and no overlap."""
    cfg = planner.cfg
    veh = make_vehicles(road, [(STRAIGHT_S + 30.0, 0.0, 15.0)])
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0, vehicles=veh))
    i = _cruise(planner, ps, 15.0)
    D = cfg.proximity_sigma_s + cfg.proximity_headway * 15.0
    closed = np.exp(-((25.5 / D) ** 2)) * planner.w.astype(np.float64).sum()
    assert np.isclose(ps.features[i, F["proximity"]], closed, rtol=1e-4)
    assert not ps.labels[i, 0]
    near, overlap = _expected_proximity(planner, ps, i, STRAIGHT_S + 30.0, 0.0, 15.0)
    assert overlap == 0 and np.isclose(near, closed, rtol=1e-9)


def test_a_policy_through_a_predicted_vehicle_pays_for_the_overlap(road, planner):
    """Cruising at 15 m/s into a vehicle standing 40 m ahead: the boxes overlap for t in (2.33, 3.0) s;
    proximity = the Gaussian part + proximity_overlap x the discounted overlap time, as documented."""
    cfg = planner.cfg
    veh = make_vehicles(road, [(STRAIGHT_S + 40.0, 0.0, 0.0)])
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0, vehicles=veh))
    prox = ps.features[:, F["proximity"]]
    i = _cruise(planner, ps, 15.0)
    near, overlap = _expected_proximity(planner, ps, i, STRAIGHT_S + 40.0, 0.0, 0.0)
    t = np.arange(cfg.n_steps) * cfg.dt
    assert np.isclose(overlap, planner.w[(t > 35 / 15) & (t < 45 / 15)].sum(), rtol=1e-6)
    assert np.isclose(prox[i], near + cfg.proximity_overlap * overlap, rtol=1e-4)
    assert ps.labels[i, 0], "driving through a standing vehicle is a predicted collision"
    # every predicted collision pays more than every policy that brakes in time behind it in its lane
    hit = ps.labels[:, 0]
    stays = np.all(np.abs(ps.d) < 0.5, axis=1)
    assert (stays & ~hit).any() and prox[hit & stays].min() > prox[stays & ~hit].max()
    # the same vehicle two lanes away costs almost nothing (lateral factor exp(-(6.4 / 1.6)^2) ~ 1e-7)
    veh = make_vehicles(road, [(STRAIGHT_S + 40.0, LANE_WIDTH, 0.0)])
    ps = planner.plan(make_obs(road, STRAIGHT_S, -LANE_WIDTH, 15.0, vehicles=veh))
    assert ps.features[_cruise(planner, ps, 15.0), F["proximity"]] < 1e-5


def test_proximity_scale_grows_with_closing_speed(road, planner):
    """The same 30 m gap costs more when closing in fast (D includes the braking distance)."""
    out = []
    for v_ego in (10.0, 19.0):
        veh = make_vehicles(road, [(STRAIGHT_S + 30.0, 0.0, 10.0)])
        ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, v_ego, vehicles=veh))
        # the same initial gap for both; D differs (and the faster ego closes in)
        out.append(ps.features[_cruise(planner, ps, v_ego), F["proximity"]])
    assert out[1] > 2 * out[0]


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


def test_stop_line_counts_a_stand_only_strictly_before_the_crossing_step():
    """The stand must come before the step that crosses the line, as the episode's stop-line compliance
    counts it (the pass is counted before the stop at a step). Found in closed loop by a learned
    reward: 0.033 m before the line at 0.164 m/s a policy reached 0.0999 m/s at exactly the step that
    crossed the line and then accelerated; counted as having stood, it cost nothing and the ego crossed
    without a full stop.
    Hand-made profiles, T = 4 steps of 0.1 s, gamma from the default config."""
    cfg = PlannerConfig()
    rel = 0.033
    lon = LonBank(
        s=np.array([[0.0, 0.015, 0.026, 0.036], [0.0, 0.012, 0.020, 0.034], [0.0, 0.01, 0.02, 0.03]], F32),
        v=np.array(
            [[0.164, 0.127, 0.102, 0.0999], [0.164, 0.12, 0.09, 0.11], [0.164, 0.12, 0.09, 0.05]], F32
        ),
        a=np.zeros((3, 4), F32),
        kind=np.zeros(3, np.int8),
    )
    ctx = Context(s_ego=0.0, d0=0.0, goal=100.0, target_rel=50.0, req_d=0.0, stop_rel=rel, lap_length=2000.0)
    w = (cfg.gamma ** np.arange(4) * cfg.dt).astype(F32)
    w[0] = 0.0
    f, _ = lon_features(lon, np.zeros((3, 4), F32), ctx, cfg, w)
    sl = f[:, FEATURE_NAMES.index("stop_line")]
    # 0: first below 0.1 m/s at the crossing step 3 -> the event gamma^3 (1 + 0.0999)
    assert sl[0] == pytest.approx(cfg.gamma**3 * (1 + 0.0999), rel=1e-5)
    # 1: stood at step 2 (0.09 m/s, 0.020 m < 0.033 m), crosses at step 3 -> no event
    # 2: never reaches the line -> no event
    assert sl[1] == 0.0 and sl[2] == 0.0


def test_taking_an_exit_costs_progress(road, planner):
    ex = road.exits[0]
    ps = planner.plan(make_obs(road, ex.s_start - 30.0, -LANE_WIDTH, 15.0))
    inner = planner.last
    exits = np.flatnonzero(ps.labels[:, 2])
    assert len(exits)
    keep = np.all(np.abs(ps.d + LANE_WIDTH) < 1e-6, axis=1)
    obs = inner.obs
    goal = obs.target_s - obs.ego.s + planner.cfg.progress_lookahead
    w = planner.w.astype(np.float64)
    for i in exits[:20]:
        same_lon = np.flatnonzero(keep & (inner.lon_idx == inner.lon_idx[i]))
        assert len(same_lon)
        # on the ramp the target is unreachable: the remaining distance is one lap instead of goal - s
        off = ps.d[i] < -HALF_ROAD
        prog = np.maximum(goal - (ps.s[i] - obs.ego.s), 0.0)
        extra = float((off * (road.lap_length - prog)) @ w)
        assert extra > 0
        diff = ps.features[i, F["progress"]] - ps.features[same_lon[0], F["progress"]]
        assert np.isclose(diff, extra, rtol=1e-4)


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


def test_vehicles_queue_before_a_stop_line(road):
    """A vehicle heading for a stop line stands 0.3 m before it, or QUEUE_GAP behind the rear of each
    vehicle queued ahead of it in its lane; vehicles of other lanes or beyond reach do not count."""
    from irlsim.planner.prediction import QUEUE_GAP, predicted_stop_distance

    line = road.stop_lines[0].s
    lap = road.lap_length
    s = np.array([line - 10.0, line - 30.0, line - 20.0, line - 200.0]) % lap
    d = np.array([0.0, 0.0, LANE_WIDTH, 0.0])
    size = np.array([4.5, 4.5, 4.5, 4.5]), np.full(4, 1.8)
    out = predicted_stop_distance(s, d, *size, tuple(sl.s for sl in road.stop_lines), lap)
    assert out[0] == pytest.approx(10.0 - 0.3)  # first in its lane
    assert out[1] == pytest.approx(30.0 - 0.3 - (4.5 + QUEUE_GAP))  # behind vehicle 0
    assert out[2] == pytest.approx(20.0 - 0.3)  # alone in the left lane
    assert np.isinf(out[3])  # the line is beyond reach
    assert np.all(np.isinf(predicted_stop_distance(s, d, *size, (), lap)))


def test_mission_event_adds_the_lanes_away_where_the_policy_passes_the_checkpoint(road):
    """planner.mission_event E: a policy that passes its target checkpoint at step tc gains exactly
    gamma^tc * u_max * E * |d_tc - d_req| / LW in mission_lane (hand-computed from its own states);
    with E = 0 the feature is the path integral alone."""
    import dataclasses

    from irlsim.planner.planner import Planner

    cp = road.checkpoints[1]  # requires lane 0
    obs = make_obs(road, cp.s - 40.0, LANE_WIDTH, 15.0)
    default = Planner(road).cfg
    base = Planner(road, dataclasses.replace(default, mission_event=0.0))
    cfg = dataclasses.replace(default, mission_event=2.0)
    ev = Planner(road, cfg)
    ps0, ps1 = base.plan(obs), ev.plan(obs)
    np.testing.assert_array_equal(ps0.s, ps1.s)
    np.testing.assert_array_equal(ps0.d, ps1.d)
    assert obs.target_checkpoint == 1
    rem = obs.target_s - ps0.s  # ps.s is the unwrapped route position
    passing = (rem <= 0) & (np.arange(rem.shape[1]) >= 1)
    tc = np.argmax(passing, axis=1)
    hit = passing[np.arange(len(tc)), tc]
    assert hit.any() and (~hit).any()  # some policies pass it within the horizon, some (braking) do not
    away = np.abs(ps0.d[np.arange(len(tc)), tc] - road.lane_center(cp.lane)) / LANE_WIDTH
    expected = np.where(hit, cfg.gamma**tc * cfg.mission_urgency_max * 2.0 * away, 0.0)
    diff = ps1.features[:, F["mission_lane"]].astype(np.float64) - ps0.features[:, F["mission_lane"]]
    # a policy whose front is at the checkpoint to float precision may pass it one step later in float32
    exact = np.abs(rem[np.arange(len(tc)), tc]) > 1e-3
    assert exact.mean() > 0.95
    np.testing.assert_allclose(diff[exact], expected[exact], rtol=1e-4, atol=1e-3)
    # a policy still one lane away when it passes pays more than one that is back in the lane
    assert diff[hit & (away > 0.9)].min() > diff[hit & (away < 0.1)].max()
