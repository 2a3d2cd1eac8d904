"""Every feature but proximity against a value computed here, independently of the planner, from the
documented formula (module docstring of ``irlsim.planner.features``) and a trajectory known in closed form
(constant speed, constant acceleration, a smoothstep ramp, a quintic lane change, a stop) or, where the
trajectory is not closed form (a stop profile, an exit profile), the policy's own arrays.

The weights are recomputed here, w_t = gamma^t dt for t >= 1 and 0 at t = 0; quintics are solved here as
the 6 x 6 boundary-value system (position, velocity, acceleration at both ends), held at the target
afterwards. Features are float32: relative tolerance 1e-4.
"""

from __future__ import annotations

import numpy as np
import pytest

from irlsim import FEATURE_NAMES
from irlsim.planner.planner import stop_distances
from irlsim.road import HALF_ROAD, LANE_WIDTH

from .conftest import make_obs

F = {n: i for i, n in enumerate(FEATURE_NAMES)}
RTOL = 1e-4
STRAIGHT_S = 250.0  # curvature 0 on [0, 540] m
CURVE_S = 800.0  # inside the first bend (curvature ~ 7e-3 1/m)


@pytest.fixture(scope="module")
def grid(planner):
    """(t [T] s, w [T]) of the planner's configuration."""
    cfg = planner.cfg
    t = np.arange(cfg.n_steps) * cfg.dt
    w = cfg.gamma ** np.arange(cfg.n_steps) * cfg.dt
    w[0] = 0.0
    return t, w


def quintic(p0: float, v0: float, a0: float, p1: float, dur: float, t: np.ndarray):
    """Position, velocity, acceleration, jerk [T] of the quintic from (p0, v0, a0) at t = 0 to (p1, 0, 0)
    at t = dur, held at p1 from dur on (so the jerk is 0 from t = dur)."""
    T = dur
    A = np.array(
        [
            [1, 0, 0, 0, 0, 0],
            [0, 1, 0, 0, 0, 0],
            [0, 0, 2, 0, 0, 0],
            [1, T, T**2, T**3, T**4, T**5],
            [0, 1, 2 * T, 3 * T**2, 4 * T**3, 5 * T**4],
            [0, 0, 2, 6 * T, 12 * T**2, 20 * T**3],
        ],
        dtype=float,
    )
    c = np.linalg.solve(A, [p0, v0, a0, p1, 0.0, 0.0])
    inside = t < T
    tt = np.minimum(t, T)
    p = sum(c[k] * tt**k for k in range(6))
    v = np.where(inside, sum(k * c[k] * tt ** (k - 1) for k in range(1, 6)), 0.0)
    a = np.where(inside, sum(k * (k - 1) * c[k] * tt ** (k - 2) for k in range(2, 6)), 0.0)
    j = np.where(inside, sum(k * (k - 1) * (k - 2) * c[k] * tt ** (k - 3) for k in range(3, 6)), 0.0)
    return p, v, a, j


def backward_diff(x: np.ndarray, dt: float) -> np.ndarray:
    """(x_t - x_{t-1}) / dt, 0 at t = 0 (the documented j = (a_t - a_{t-1}) / dt)."""
    return np.concatenate([[0.0], np.diff(x) / dt])


def find(ps, inner, d=None, v=None, a=None, tol=1e-6, extra=None) -> int:
    """Index of the first policy whose lateral offset, speed and acceleration [T] equal the given
    closed-form arrays (None: any)."""
    ok = np.ones(ps.n_policies, bool)
    for have, want in ((ps.d, d), (ps.v, v), (inner.a, a)):
        if want is not None:
            ok &= np.all(np.abs(have - np.asarray(want)[None, :]) < tol, axis=1)
    if extra is not None:
        ok &= extra
    idx = np.flatnonzero(ok)
    assert len(idx), "no policy with the closed-form trajectory"
    return int(idx[0])


def check(ps, i: int, name: str, expected: float, atol: float = 0.0) -> None:
    got = float(ps.features[i, F[name]])
    assert got == pytest.approx(expected, rel=RTOL, abs=atol), f"{name}: planner {got}, by hand {expected}"


# ------------------------------------------------------------------------------------ longitudinal


def test_acc_lon_of_a_constant_acceleration(road, planner, grid):
    """a = 1 m/s^2 from the start (ego's a and both stages 1): acc_lon = 1^2 sum_t w_t, jerk 0."""
    t, w = grid
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 10.0, a=1.0))
    i = find(ps, planner.last, d=np.zeros_like(t), a=np.ones_like(t), v=10.0 + t, tol=1e-5)
    cfg = planner.cfg
    closed = cfg.dt * sum(cfg.gamma**k for k in range(1, cfg.n_steps))
    assert np.isclose(w.sum(), closed)
    check(ps, i, "acc_lon", 1.0 * closed)
    check(ps, i, "jerk_lon", 0.0, atol=1e-6)
    check(ps, i, "velocity", float(((10.0 + t - cfg.v_target) ** 2) @ w))


def test_jerk_lon_of_a_smoothstep_ramp(road, planner, grid):
    """From a = 0 to 2 m/s^2 over accel_ramp = 1 s by the cubic smoothstep, held through stage 2:
    a(t) = 2 (3 x^2 - 2 x^3), x = min(t / 1 s, 1); jerk_lon = sum_t w_t ((a_t - a_{t-1}) / dt)^2."""
    t, w = grid
    cfg = planner.cfg
    x = np.clip(t / cfg.accel_ramp, 0.0, 1.0)
    a = 2.0 * (3 * x**2 - 2 * x**3)
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 10.0))
    i = find(ps, planner.last, d=np.zeros_like(t), a=a)
    check(ps, i, "jerk_lon", float(backward_diff(a, cfg.dt) ** 2 @ w))
    check(ps, i, "acc_lon", float(a**2 @ w))
    # the jerk of the smoothstep peaks at 2 * 1.5 / (1 s) = 3 m/s^3 at t = 0.5 s
    assert np.isclose(np.abs(backward_diff(a, cfg.dt)).max(), 3.0, rtol=0.02)


def test_velocity_towards_an_active_stop_line(road, planner, grid):
    """8 m/s constant, 30 m before an active line: v_ref = min(v_target, sqrt(2 b (29 m - s))) until the
    line (0 between the stop point 1 m before it and the line), v_target once past it."""
    t, w = grid
    cfg = planner.cfg
    line = road.stop_lines[0].s
    ps = planner.plan(make_obs(road, line - 30.0, 0.0, 8.0, stop_s=line))
    i = find(ps, planner.last, d=np.zeros_like(t), v=np.full_like(t, 8.0), a=np.zeros_like(t))
    s = 8.0 * t  # relative to the ego's front bumper
    dist = np.maximum(30.0 - cfg.stop_margin - s, 0.0)
    vref = np.where(
        s <= 30.0, np.minimum(cfg.v_target, np.sqrt(2 * cfg.stop_decel_comfort * dist)), cfg.v_target
    )
    assert (vref == 0).any() and (vref == cfg.v_target).any() and ((vref > 0) & (vref < 8)).any()
    check(ps, i, "velocity", float((8.0 - vref) ** 2 @ w))


def test_creep_at_constant_speed_inside_the_zone(road, planner, grid):
    """1.5 m/s constant from 10 m before the line: 7.5 m travelled, inside the 12 m zone all along:
    creep = min(1.5, creep_speed) sum_t w_t."""
    t, w = grid
    line = road.stop_lines[0].s
    ps = planner.plan(make_obs(road, line - 10.0, 0.0, 1.5, stop_s=line))
    i = find(ps, planner.last, d=np.zeros_like(t), v=np.full_like(t, 1.5), a=np.zeros_like(t))
    check(ps, i, "creep", min(1.5, planner.cfg.creep_speed) * float(w.sum()))
    # the same approach without an active line costs no creep
    ps = planner.plan(make_obs(road, line - 10.0, 0.0, 1.5))
    assert np.all(ps.features[:, F["creep"]] == 0)


def test_creep_of_a_stop_profile(road, planner, grid):
    """A stop profile from 6 m/s, 20 m before the line, on its own arrays: sum_t w_t min(v, creep_speed)
    [0 <= line - s <= creep_zone]."""
    t, w = grid
    cfg = planner.cfg
    line = road.stop_lines[0].s
    ego_s = line - 20.0
    ps = planner.plan(make_obs(road, ego_s, 0.0, 6.0, stop_s=line))
    inner = planner.last
    stops = np.flatnonzero((inner.kind == 2) & np.all(ps.d == 0.0, axis=1))
    assert len(stops)
    for i in stops:
        to_line = line - ps.s[i]
        zone = (to_line >= 0) & (to_line <= cfg.creep_zone)
        check(ps, int(i), "creep", float((zone * np.minimum(ps.v[i], cfg.creep_speed)) @ w))
    assert ps.features[stops, F["creep"]].max() > 0.1


def test_stop_line_event_when_crossing_at_speed(road, planner, grid):
    """8 m/s constant from 30 m before an active line: s_k = 0.8 k m first reaches 30 m at step 38, so
    stop_line = gamma^38 (1 + 8). And for every policy, on its own arrays: gamma^tc (1 + v_tc) at the
    first step tc >= 1 with s >= line, unless it stood (v < v_stopped) before; 0 if it never crosses."""
    t, w = grid
    cfg = planner.cfg
    line = road.stop_lines[1].s
    ego_s = line - 30.0
    ps = planner.plan(make_obs(road, ego_s, 0.0, 8.0, stop_s=line))
    i = find(ps, planner.last, d=np.zeros_like(t), v=np.full_like(t, 8.0), a=np.zeros_like(t))
    check(ps, i, "stop_line", cfg.gamma**38 * (1.0 + 8.0))
    expected = np.zeros(ps.n_policies)
    for k in range(ps.n_policies):
        crossed = np.flatnonzero(ps.s[k, 1:] - ego_s >= 30.0)
        if len(crossed):
            tc = int(crossed[0]) + 1
            if ps.v[k, :tc].min() >= cfg.v_stopped:
                expected[k] = cfg.gamma**tc * (1.0 + ps.v[k, tc])
    assert (expected > 0).any() and (expected == 0).any()
    np.testing.assert_allclose(ps.features[:, F["stop_line"]], expected, rtol=RTOL)


def test_progress_at_constant_speed(road, planner, grid):
    """15 m/s, lane keeping: progress = sum_t w_t max(0, goal - 15 t), goal = target checkpoint +
    progress_lookahead ahead of the ego."""
    t, w = grid
    obs = make_obs(road, STRAIGHT_S, 0.0, 15.0)
    ps = planner.plan(obs)
    i = find(ps, planner.last, d=np.zeros_like(t), v=np.full_like(t, 15.0), a=np.zeros_like(t))
    goal = obs.target_s - obs.ego.s + planner.cfg.progress_lookahead
    assert goal > 15.0 * t[-1]
    check(ps, i, "progress", float((goal - 15.0 * t) @ w))


def test_progress_of_exit_profiles_is_the_lap_length_on_the_ramp(road, planner, grid):
    """Exit profiles, on their own arrays: lap_length per second on the ramp (d < -HALF_ROAD), the route
    distance to the goal before it."""
    t, w = grid
    ex = road.exits[0]
    obs = make_obs(road, ex.s_start - 30.0, -LANE_WIDTH, 15.0)
    ps = planner.plan(obs)
    exits = np.flatnonzero(planner.last.exit_profile)
    assert len(exits)
    goal = obs.target_s + planner.cfg.progress_lookahead
    for i in exits:
        step = np.where(ps.d[i] < -HALF_ROAD, road.lap_length, np.maximum(goal - ps.s[i], 0.0))
        check(ps, int(i), "progress", float(step @ w))


# ------------------------------------------------------------------------------------ lateral


def test_acc_and_jerk_lat_of_lane_keeping_on_a_curve(road, planner, grid):
    """Lane keeping at 15 m/s in the bend: acc_lat = sum_t w_t (v^2 kappa(s_t))^2 and jerk_lat =
    sum_t w_t (d/dt (v^2 kappa))^2 (backward difference), kappa the reference curvature at the policy's s."""
    t, w = grid
    ps = planner.plan(make_obs(road, CURVE_S, 0.0, 15.0))
    i = find(ps, planner.last, d=np.zeros_like(t), v=np.full_like(t, 15.0), a=np.zeros_like(t))
    kappa = road.curvature(ps.s[i])
    c = 15.0**2 * kappa
    assert c.min() > 1.0, "the case is meant to be in a bend"
    check(ps, i, "acc_lat", float(c**2 @ w))
    check(ps, i, "jerk_lat", float(backward_diff(c, planner.cfg.dt) ** 2 @ w))


def test_acc_and_jerk_lat_of_a_lane_change_on_a_curve(road, planner, grid):
    """Lane change 0 -> 3.2 m in 2.5 s (quintic) at 15 m/s in the bend, then the lane centre: the mixed
    terms count, acc_lat = sum_t w_t (d_ddot + v^2 kappa)^2 and
    jerk_lat = sum_t w_t (d_dddot + d/dt(v^2 kappa))^2."""
    t, w = grid
    d, _, dd2, dd3 = quintic(0.0, 0.0, 0.0, LANE_WIDTH, 2.5, t)
    ps = planner.plan(make_obs(road, CURVE_S, 0.0, 15.0))
    i = find(ps, planner.last, d=d, v=np.full_like(t, 15.0), a=np.zeros_like(t))
    c = 15.0**2 * road.curvature(ps.s[i])
    check(ps, i, "acc_lat", float((dd2 + c) ** 2 @ w))
    check(ps, i, "jerk_lat", float((dd3 + backward_diff(c, planner.cfg.dt)) ** 2 @ w))


def test_lateral_features_of_a_lane_change_on_a_straight(road, planner, grid):
    """Lane change 0 -> 3.2 m in 2.5 s (quintic) at 15 m/s on a straight (kappa = 0), in closed form:
    acc_lat = sum w d_ddot^2, jerk_lat = sum w d_dddot^2, lc_delay = sum w t |d_dot|, centerline =
    sum w min(|d|, |d - 3.2|)^2; it ends at rest on the target: end_heading = lat_overshoot = 0."""
    t, w = grid
    d, dd1, dd2, dd3 = quintic(0.0, 0.0, 0.0, LANE_WIDTH, 2.5, t)
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0))
    i = find(ps, planner.last, d=d, v=np.full_like(t, 15.0), a=np.zeros_like(t))
    check(ps, i, "acc_lat", float(dd2**2 @ w))
    check(ps, i, "jerk_lat", float(dd3**2 @ w))
    check(ps, i, "lc_delay", float((t * np.abs(dd1)) @ w))
    check(ps, i, "centerline", float(np.minimum(np.abs(d), np.abs(d - LANE_WIDTH)) ** 2 @ w))
    check(ps, i, "end_heading", 0.0, atol=1e-9)
    check(ps, i, "lat_overshoot", 0.0, atol=1e-9)


def test_lc_delay_of_a_lane_change_in_stage_two(road, planner, grid):
    """Keep the lane for 2.5 s, then change 0 -> 3.2 m over the remaining 2.5 s: lc_delay = sum_t w_t t
    |d_dot(t)| with d_dot the quintic's, shifted by 2.5 s (it weights the late motion by t >= 2.5 s)."""
    t, w = grid
    split = planner.cfg.stage_split
    d2, dd2, _, _ = quintic(
        0.0, 0.0, 0.0, LANE_WIDTH, planner.cfg.horizon - split, np.maximum(t - split, 0.0)
    )
    d = np.where(t > split, d2, 0.0)
    ddot = np.where(t > split, dd2, 0.0)
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0))
    i = find(ps, planner.last, d=d, v=np.full_like(t, 15.0), a=np.zeros_like(t))
    check(ps, i, "lc_delay", float((t * np.abs(ddot)) @ w))


def test_centerline_of_an_off_centre_lane_keep(road, planner, grid):
    """0.5 m left of the centre: the lane-keeping profile returns by a 2.5 s quintic; centerline =
    sum_t w_t d^2 (the nearest centre is 0 throughout)."""
    t, w = grid
    d, _, _, _ = quintic(0.5, 0.0, 0.0, 0.0, 2.5, t)
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.5, 15.0))
    inner = planner.last
    i = find(ps, inner, d=d, v=np.full_like(t, 15.0), a=np.zeros_like(t), extra=inner.lat.keep[inner.lat_idx])
    check(ps, i, "centerline", float(d**2 @ w))


def test_road_edge_near_the_left_edge(road, planner, grid):
    """Ego 4.0 m left (its side 0.1 m beyond the 4.8 m edge), lane keeping back to 3.2 m by a 2.5 s
    quintic: road_edge = sum_t w_t relu(m - (4.8 - (d + W/2)))^2 (the right gap is large)."""
    t, w = grid
    cfg = planner.cfg
    d, _, _, _ = quintic(4.0, 0.0, 0.0, LANE_WIDTH, 2.5, t)
    ps = planner.plan(make_obs(road, STRAIGHT_S, 4.0, 15.0))
    inner = planner.last
    i = find(ps, inner, d=d, v=np.full_like(t, 15.0), a=np.zeros_like(t), extra=inner.lat.keep[inner.lat_idx])
    gap_left = HALF_ROAD - (d + cfg.ego_width / 2)
    gap_right = (d - cfg.ego_width / 2) + HALF_ROAD
    expected = (
        np.maximum(cfg.edge_margin - gap_left, 0) ** 2 + np.maximum(cfg.edge_margin - gap_right, 0) ** 2
    ) @ w
    assert expected > 0.01
    check(ps, i, "road_edge", float(expected))


def test_mission_lane_in_the_wrong_lane(road, planner, grid):
    """Two lanes left of the lane checkpoint 1 requires, 150 m before it at 15 m/s: mission_lane =
    sum_t w_t min(u_max, D / (150 - 15 t)) * 2 lanes."""
    t, w = grid
    cfg = planner.cfg
    cp = road.checkpoints[1]
    assert cp.lane == 0
    obs = make_obs(road, cp.s - 150.0, LANE_WIDTH, 15.0)
    assert obs.target_checkpoint == 1
    ps = planner.plan(obs)
    i = find(ps, planner.last, d=np.full_like(t, LANE_WIDTH), v=np.full_like(t, 15.0), a=np.zeros_like(t))
    u = np.minimum(cfg.mission_urgency_max, cfg.mission_distance / (150.0 - 15.0 * t))
    check(ps, i, "mission_lane", float((u * 2.0) @ w))


def test_mission_lane_is_capped_and_ends_at_the_checkpoint(road, planner, grid):
    """20 m before the checkpoint at 15 m/s in the middle lane (1 lane off): the urgency reaches its cap
    u_max as the remaining distance goes below D / u_max = 30 m ... 0 and is 0 once past (t > 4/3 s); the
    step that passes it adds the event gamma^tc u_max E (planner.mission_event E, 1 lane off)."""
    t, w = grid
    cfg = planner.cfg
    cp = road.checkpoints[1]
    ps = planner.plan(make_obs(road, cp.s - 20.0, 0.0, 15.0))
    i = find(ps, planner.last, d=np.zeros_like(t), v=np.full_like(t, 15.0), a=np.zeros_like(t))
    rem = 20.0 - 15.0 * t
    u = np.where(
        rem > 0, np.minimum(cfg.mission_urgency_max, cfg.mission_distance / np.maximum(rem, 1e-9)), 0.0
    )
    assert (u == cfg.mission_urgency_max).any() and (u == 0).any()
    # the event where it passes the checkpoint, one lane off: gamma^tc u_max mission_event * 1 lane
    tc = int(np.argmax((rem <= 0) & (np.arange(len(t)) >= 1)))
    assert tc == 14  # rem(1.3 s) = 0.5 m, rem(1.4 s) = -1 m
    event = cfg.gamma**tc * cfg.mission_urgency_max * cfg.mission_event * 1.0
    assert cfg.mission_event > 0
    check(ps, i, "mission_lane", float((u * 1.0) @ w) + event)


def test_lat_overshoot_of_a_lane_change_entered_fast(road, planner, grid):
    """From d = 2 m moving left at 2 m/s, the quintic to the 3.2 m centre in 2.5 s overshoots it:
    lat_overshoot = sum_t w_t relu(d - 3.2)^2 (the target lies left: sgn = +1)."""
    t, w = grid
    d, _, _, _ = quintic(2.0, 2.0, 0.0, LANE_WIDTH, 2.5, t)
    assert d.max() > LANE_WIDTH + 0.1
    ps = planner.plan(make_obs(road, STRAIGHT_S, 2.0, 15.0, d_dot=2.0))
    i = find(ps, planner.last, d=d, v=np.full_like(t, 15.0), a=np.zeros_like(t))
    check(ps, i, "lat_overshoot", float(np.maximum(d - LANE_WIDTH, 0.0) ** 2 @ w))


def test_end_heading_of_exit_profiles(road, planner, grid):
    """Exit profiles still move sideways at the horizon (they follow the ramp): end_heading =
    atan2(d_dot_T, max(v_T, v_f))^2 with d_dot_T = (d_T - d_{T-1}) / dt from the policy's own arrays;
    every other profile ends at rest in the lane (0)."""
    t, w = grid
    cfg = planner.cfg
    ex = road.exits[0]
    ps = planner.plan(make_obs(road, ex.s_start - 30.0, -LANE_WIDTH, 15.0))
    exits = planner.last.exit_profile
    assert exits.any()
    dd_end = (ps.d[:, -1] - ps.d[:, -2]) / cfg.dt
    expected = np.arctan2(dd_end, np.maximum(ps.v[:, -1], cfg.yaw_speed_floor)) ** 2
    assert expected[exits].max() > 1e-3
    np.testing.assert_allclose(ps.features[exits, F["end_heading"]], expected[exits], rtol=RTOL)
    # the free profiles' quintics reach their targets at rest exactly at the horizon: d_dot_T = 0
    assert np.all(ps.features[~exits, F["end_heading"]] < 1e-9)


# ------------------------------------------------------------------------------------ trajectories
# Sampler defects, each fixed, pinned by the trajectory property it broke (the features agreed with their
# formulas on the wrong trajectories): two found while building the cases above, and exit profiles that
# started off the ego inside a ramp zone, found in a closed-loop drive that was moved onto the ramp.


def test_exit_profiles_start_at_the_ego(road, planner):
    ex = road.exits[0]
    ps = planner.plan(make_obs(road, ex.s_start - 30.0, -LANE_WIDTH, 15.0))
    exits = planner.last.exit_profile
    assert exits.any()
    np.testing.assert_allclose(ps.d[exits, 0], -LANE_WIDTH, atol=1e-6)


@pytest.mark.parametrize("past", [3.0, 15.0])
def test_exit_profiles_start_at_the_ego_inside_the_ramp_zone(road, planner, past):
    """Inside an exit's ramp zone, still in lane 0, where the ramp's centre has already left the lane's:
    the exit profiles start at the ego too, and end on the ramp's centre (they were laid from the ego's
    offset to the lane instead of to the ramp, so they started metres off the ego, and a drive executed
    that jump as an exit)."""
    ex = road.exits[0]
    s0, d0 = ex.s_start + past, -LANE_WIDTH + 0.3
    ramp0 = float(np.interp(s0, ex.ramp_s, ex.ramp_d))
    assert ramp0 < -LANE_WIDTH  # the ramp has diverged from lane 0 here
    obs = make_obs(road, s0, d0, 11.0)
    e = obs.ego
    lon = planner.sampler.lon_bank(e.v, e.a, stop_distances(obs, planner.cfg, road), None)
    bank = planner.sampler.exit_bank(e.d, e.d_dot, e.d_ddot, e.s, lon)
    assert bank is not None and len(bank.d)
    np.testing.assert_allclose(bank.d[:, 0], d0, atol=1e-6)
    s_end = s0 + lon.s[bank.bound_lon, -1]
    np.testing.assert_allclose(bank.d[:, -1], np.interp(s_end, ex.ramp_s, ex.ramp_d), atol=1e-6)


def test_stop_profiles_never_roll_back(road, planner):
    from .conftest import make_vehicles

    s = STRAIGHT_S
    obs = make_obs(road, s, 0.0, 2.9, a=-2.6, vehicles=make_vehicles(road, [(s + 4.5 + 2.0, 0.0, 0.0)]))
    ps = planner.plan(obs)
    stops = planner.last.kind == 2
    assert stops.any()
    assert np.all(np.diff(ps.s[stops], axis=1) >= -1e-9)
    # once standing, a stop profile stays put: v = 0 and a = 0 from then on
    standing = np.maximum.accumulate((ps.v[stops] <= 0.0) & (np.arange(ps.n_steps) > 0), axis=1)
    assert standing.any()
    assert np.all(ps.v[stops][standing] == 0) and np.all(planner.last.a[stops][standing] == 0)
