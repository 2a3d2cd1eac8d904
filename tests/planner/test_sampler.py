"""The policy set: size, order, determinism, the behaviours it must contain, feasibility, continuity."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from irlsim import FEATURE_NAMES
from irlsim.errors import IrlsimError
from irlsim.planner.config import PlannerConfig
from irlsim.planner.expert import lane_clusters
from irlsim.planner.planner import Planner
from irlsim.planner.sampler import stop_distances
from irlsim.road import LANE_WIDTH

from .conftest import make_obs, make_vehicles

STRAIGHT_S = 250.0  # [m] a straight stretch of lane 1, no exit or stop line within the horizon


def test_exact_count_sorted_deterministic(road, planner):
    obs = make_obs(road, STRAIGHT_S, 0.0, 15.0, vehicles=make_vehicles(road, [(300.0, 0.0, 8.0)]))
    a = planner.plan(obs)
    b = planner.plan(obs)
    assert a.n_policies == 2500 and a.n_steps == 51
    assert np.all(np.diff(a.progress) >= 0)
    for name in ("x", "y", "yaw", "v", "s", "d", "features", "control_points", "actions", "labels"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.features.dtype == np.float32 and a.control_points.shape == (2500, 10, 3)


@pytest.mark.parametrize("n", [1, 300, 4000])
def test_other_counts_exact(road, n):
    ps = Planner(road, PlannerConfig(n_policies=n)).plan(make_obs(road, STRAIGHT_S, 0.0, 19.0))
    assert ps.n_policies == n


def test_standing_ego_still_gets_exact_count(road, planner):
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 0.0))
    assert ps.n_policies == 2500
    assert np.all(ps.v >= 0)


def test_lane_keeping_at_several_speeds(road, planner):
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0))
    keep = np.all(np.abs(ps.d) < 1e-6, axis=1)
    end_speeds = np.unique(np.round(ps.v[keep, -1], 1))
    assert len(end_speeds) >= 10
    assert end_speeds.min() < 5.0 and end_speeds.max() > 19.0


def test_a_driver_above_v_max_and_speeding_up_still_gets_its_policies(road, planner):
    # a recorded driver at 26 m/s (above v_max = 25) still accelerating: no profile can stay under v_max,
    # so the policies are those that add no speed beyond what the initial acceleration adds
    v0, a0 = 26.0, 0.4
    assert v0 > planner.cfg.v_max
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, v0, a=a0))
    assert ps.n_policies == 2500
    assert ps.v.max() <= v0 + a0 * planner.cfg.horizon
    assert ps.v[:, -1].min() < v0 - 5.0  # braking profiles among them


@pytest.mark.parametrize("d0, finals", [(0.0, (0, 2)), (-LANE_WIDTH, (1, 2)), (LANE_WIDTH, (1, 0))])
def test_single_and_double_lane_changes_both_ways(road, planner, d0, finals):
    ps = planner.plan(make_obs(road, STRAIGHT_S, d0, 15.0))
    final, _ = lane_clusters(ps)
    for lane in finals:
        assert np.any(final == lane), f"no policy from d={d0} ends in lane {lane}"
    # each lane change ends on the target lane centre
    changed = final != ps.lane[:, 0]
    assert np.any(np.abs(ps.d[changed, -1] - (final[changed] - 1) * LANE_WIDTH) < 0.01)


def test_swerves(road, planner):
    ps = planner.plan(make_obs(road, STRAIGHT_S, 0.0, 15.0))
    dev = np.abs(ps.d).max(axis=1)
    back = np.abs(ps.d[:, -1]) < 0.01
    assert np.any(back & (dev > 0.6) & (dev < 1.7)), "no swerve that goes out and comes back"


def test_full_stop_at_an_active_stop_line(road, planner):
    line = road.stop_lines[0].s
    ps = planner.plan(make_obs(road, line - 40.0, 0.0, 12.0, stop_s=line))
    stopped = ps.v[:, -1] < 0.1
    front = ps.s[:, -1]
    exact = stopped & (front <= line) & (front > line - 1.5)
    assert exact.any(), "no policy stands just before the stop line"


def test_stop_distances_add_the_line_once_the_stop_point_is_out_of_comfortable_reach(road):
    cfg = PlannerConfig()  # stop_margin 1.0 m, stop_line_gap 0.2 m, stop_decel_comfort 2.5 m/s^2
    line = road.stop_lines[0].s
    # 40 m before the line at 12 m/s: the stop point (39 m) needs 12^2 / 5 = 28.8 m, reachable
    assert stop_distances(make_obs(road, line - 40.0, 0.0, 12.0, stop_s=line), cfg, road) == (39.0,)
    # 3 m before at 4 m/s: the stop point (2 m) needs 16 / 5 = 3.2 m -> also stand 0.2 m before the line
    far, near = stop_distances(make_obs(road, line - 3.0, 0.0, 4.0, stop_s=line), cfg, road)
    assert far == pytest.approx(2.0) and near == pytest.approx(2.8)
    # past the stop point, 0.7 m before the line, rolling at 1.2 m/s
    far, near = stop_distances(make_obs(road, line - 0.7, 0.0, 1.2, stop_s=line), cfg, road)
    assert far == pytest.approx(-0.3) and near == pytest.approx(0.5)
    # closer to the line than the gap: nothing to add; and stop_line_gap = 0 switches it off
    assert len(stop_distances(make_obs(road, line - 0.1, 0.0, 1.2, stop_s=line), cfg, road)) == 1
    off = dataclasses.replace(cfg, stop_line_gap=0.0)
    assert len(stop_distances(make_obs(road, line - 0.7, 0.0, 1.2, stop_s=line), off, road)) == 1


def test_a_smooth_stop_before_the_line_in_the_last_metre(road, planner):
    # rolling at 1.2 m/s, braking at 1 m/s^2, 0.7 m before the line: standing there needs ~1 m/s^2, so a
    # policy that stands before the line must exist without braking at the limit (peak |jerk| << 19 m/s^3,
    # the only standing profile before the line target existed)
    line = road.stop_lines[0].s
    ps = planner.plan(make_obs(road, line - 0.7, 0.0, 1.2, a=-1.0, stop_s=line))
    stands = (ps.v.min(axis=1) < planner.cfg.v_stopped) & (ps.s.max(axis=1) < line)
    assert stands.any()
    dt = planner.cfg.dt
    jerk = np.abs(np.diff(ps.v, n=2, axis=1)).max(axis=1) / dt**2
    assert jerk[stands].min() < 5.0
    # and the stop_line feature does not charge it
    assert ps.features[stands, FEATURE_NAMES.index("stop_line")].min() == 0.0


def test_merges_behind_and_ahead_of_a_slower_vehicle(road, planner):
    # a slower vehicle in lane 0 just ahead of the ego (lane 1)
    veh_s, veh_v = STRAIGHT_S + 8.0, 10.0
    obs = make_obs(road, STRAIGHT_S, 0.0, 15.0, vehicles=make_vehicles(road, [(veh_s, -LANE_WIDTH, veh_v)]))
    ps = planner.plan(obs)
    final, _ = lane_clusters(ps)
    ok = (final == 0) & ~ps.labels[:, 0]
    veh_end = veh_s + veh_v * 5.0
    behind = ok & (ps.s[:, -1] < veh_end - 4.5 - 2.0)
    ahead = ok & (ps.s[:, -1] - 4.5 > veh_end + 2.0)
    assert behind.any() and ahead.any()


def test_exit_taking_policies_near_an_exit(road, planner):
    ex = road.exits[0]
    ps = planner.plan(make_obs(road, ex.s_start - 40.0, -LANE_WIDTH, 15.0))
    assert ps.labels[:, 2].any(), "no exit-taking policy 40 m before an exit in lane 0"
    assert np.all(ps.lane[ps.labels[:, 2], -1] == -1)
    # far from any exit (or not in lane 0): none
    assert not planner.plan(make_obs(road, ex.s_start - 40.0, 0.0, 15.0)).labels[:, 2].any()


def test_feasibility_limits(road, planner):
    cfg = planner.cfg
    for s, d, v in [(STRAIGHT_S, 0.0, 19.0), (700.0, LANE_WIDTH, 19.0), (900.0, -LANE_WIDTH, 3.0)]:
        ps = planner.plan(make_obs(road, s, d, v))
        inner = planner.last
        assert np.all(ps.v >= 0) and np.all(ps.v <= cfg.v_max + 1e-6)
        assert np.all(inner.a >= cfg.a_min - 1e-5) and np.all(inner.a <= cfg.a_max + 1e-5)
        kappa = road.curvature(ps.s)
        a_lat = inner.d_ddot + ps.v**2 * kappa
        assert np.abs(a_lat).max() <= cfg.a_lat_max + 1e-3
        assert np.all(np.abs(inner.d_dot) <= np.tan(cfg.max_slip) * ps.v + 0.05 + 1e-6)


def test_continuity_from_cycle_to_cycle(road, planner):
    obs = make_obs(road, STRAIGHT_S, 0.0, 15.0, a=0.5, vehicles=make_vehicles(road, [(290.0, 0.0, 8.0)]))
    ps = planner.plan(obs)
    i = int(np.flatnonzero(planner.last.lat_idx != planner.last.lat_idx[0])[0])  # some lateral motion
    traj = planner.trajectory(i)
    np.testing.assert_allclose([traj.x[0], traj.y[0], traj.v[0]], [ps.x[i, 0], ps.y[i, 0], ps.v[i, 0]])
    state = traj.state(planner.cfg.cycle_steps)
    obs2 = make_obs(road, state.s, state.d, state.v, a=state.a, d_dot=state.d_dot, t=state.t)
    obs2 = type(obs2)(
        ego=state,
        vehicles=obs2.vehicles,
        target_checkpoint=obs2.target_checkpoint,
        target_s=obs2.target_s,
        stop_s=obs2.stop_s,
        lap_length=obs2.lap_length,
    )
    ps2 = planner.plan(obs2)
    inner = planner.last
    for arr, want in [
        (ps2.x, state.x),
        (ps2.y, state.y),
        (ps2.v, state.v),
        (ps2.s, state.s),
        (ps2.d, state.d),
        (inner.a, state.a),
        (inner.d_dot, state.d_dot),
        (inner.d_ddot, state.d_ddot),
    ]:
        np.testing.assert_allclose(arr[:, 0], want, atol=1e-4)
    np.testing.assert_allclose(ps2.yaw[:, 0], state.yaw, atol=1e-4)
    assert ps2.t == pytest.approx(state.t)


def test_config_rejects_bad_values():
    with pytest.raises(IrlsimError, match="n_policies"):
        PlannerConfig(n_policies=0).validate()
    with pytest.raises(IrlsimError, match="n_control_points"):
        PlannerConfig(n_control_points=7).validate()
    with pytest.raises(IrlsimError, match="lon_split"):
        PlannerConfig(lon_split=5.0).validate()


def test_the_longitudinal_split_at_its_default_is_the_lateral_one(road, planner):
    obs = make_obs(road, STRAIGHT_S, 0.0, 15.0, a=-0.7, vehicles=make_vehicles(road, [(290.0, 0.0, 9.0)]))
    same = Planner(road, PlannerConfig(lon_split=planner.cfg.stage_split)).plan(obs)
    default = planner.plan(obs)
    for name in ("v", "d", "features", "actions"):
        np.testing.assert_array_equal(getattr(same, name), getattr(default, name))


@pytest.mark.parametrize("split", [1.0, 2.5])
def test_a_first_longitudinal_action_that_ends_at_the_split_then_holds(road, split):
    # a(t) ramps to a1 over accel_ramp, to a2 at the split over accel_ramp: with a2 = 0 the speed from
    # split + ramp on is v0 + a1 * split exactly (the ramps' integrals cancel), whatever the lateral split
    cfg = PlannerConfig(lon_split=split, accel_ramp=0.5)
    bank = Planner(road, cfg).sampler.lon_bank(15.0, 0.0)
    held = bank.v[:, cfg.n_steps - 1]
    after = int(round((split + cfg.accel_ramp) / cfg.dt))
    for a1 in cfg.accels_stage1:
        want = max(15.0 + a1 * split, 0.0)
        hit = np.flatnonzero(np.all(np.abs(bank.v[:, after:] - want) < 1e-3, axis=1))
        assert len(hit) >= 1, (a1, want, np.unique(np.round(held, 2)))
