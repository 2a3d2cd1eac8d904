"""irlsim.planner.choice: the 'expected' choice and its lane-change bias, against closed forms; the
commitment to a maneuver under way (irlsim.planner.expert.choose_index), the full-stop rule and the
following-distance rule."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from irlsim import FEATURE_NAMES
from irlsim.planner.choice import calibrate_lane_change_bias, change_ratio, expected_choice, maneuver_masses
from irlsim.planner.config import PlannerConfig
from irlsim.planner.expert import (
    SelectionConfig,
    ThetaDriver,
    choose_index,
    keeping_distance,
    within_braking_curve,
)
from irlsim.planner.following import braking_travel
from irlsim.planner.policy_set import PolicySet
from irlsim.sim.types import VehicleStates


def _points(lateral_end: list[float], progress_end: list[float], k: int = 4) -> np.ndarray:
    """[N, K, 3] control points: lateral offset and progress growing linearly to the given ends."""
    ramp = np.arange(1, k + 1) / k
    cp = np.zeros((len(lateral_end), k, 3), np.float32)
    cp[:, :, 0] = np.outer(lateral_end, ramp)
    cp[:, :, 2] = np.outer(progress_end, ramp)
    return cp


def test_the_maneuver_with_the_mass_wins_over_the_most_likely_policy():
    # one lane-keeping policy with V = 0, three lane changes with V = -0.5 each: keep mass 1, change mass
    # 3 exp(-0.5) = 1.82 (of 2.82): argmax keeps the lane, the expected choice changes it
    value = np.array([0.0, -0.5, -0.5, -0.5])
    cp = _points([0.0, 3.2, 3.2, 3.2], [40.0, 30.0, 40.0, 50.0])
    p, which, offsets, mass = maneuver_masses(value, cp)
    assert offsets.tolist() == pytest.approx([0.0, 3.2]) and mass.sum() == pytest.approx(1.0)
    assert mass[1] == pytest.approx(3 * math.exp(-0.5) / (1 + 3 * math.exp(-0.5)))
    assert int(np.argmax(value)) == 0
    # within the lane change (equal p), the expected progress profile is the middle one's: policy 2
    assert expected_choice(value, cp) == 2
    # a bias below the ratio keeps the lane; change_ratio says where it flips (keep mass / change mass)
    ratio, change_mass = change_ratio(value, cp)
    assert ratio == pytest.approx(1 / (3 * math.exp(-0.5))) and change_mass == pytest.approx(mass[1])
    value_keep = np.array([0.0, -2.0, -2.0, -2.0])
    r_keep, _ = change_ratio(value_keep, cp)
    assert r_keep == pytest.approx(math.exp(2.0) / 3)
    assert expected_choice(value_keep, cp, lane_change_bias=0.99 * r_keep) == 0
    assert expected_choice(value_keep, cp, lane_change_bias=1.01 * r_keep) in (1, 2, 3)


def test_the_maneuver_choice_takes_the_expected_maneuvers_most_likely_policy():
    # the same cycle: the lane change has the mass; within it the policies' values differ, so its most
    # likely policy (3) is chosen, where the expected choice takes the progress nearest the expectation
    value = np.array([0.0, -0.6, -0.5, -0.4])
    cp = _points([0.0, 3.2, 3.2, 3.2], [40.0, 30.0, 40.0, 50.0])
    assert expected_choice(value, cp, within="argmax") == 3 and expected_choice(value, cp) == 2
    # where the most likely policy's maneuver has the mass, it is the argmax
    value_keep = np.array([0.0, -2.0, -2.0, -1.9])
    assert expected_choice(value_keep, cp, within="argmax") == int(np.argmax(value_keep)) == 0
    # the bias moves the decision and nothing else: above the ratio, the lane change's best
    r_keep, _ = change_ratio(value_keep, cp)
    assert expected_choice(value_keep, cp, lane_change_bias=1.01 * r_keep, within="argmax") == 3


def test_within_the_maneuver_the_lateral_profile_is_the_most_likely_policys():
    # two lateral profiles to the same lane (ends equal, ramps differ): the progress choice stays on the
    # most likely policy's profile even where another profile's progress is nearer the expectation
    value = np.array([0.0, -0.1, -3.0, -3.0])
    cp = _points([3.2, 3.2, 3.2, 3.2], [40.0, 60.0, 50.0, 45.0])
    cp[2:, :2, 0] = 3.2  # a faster lateral ramp for policies 2 and 3
    k = expected_choice(value, cp)
    assert k in (0, 1) and np.array_equal(cp[k, :, 0], cp[0, :, 0])
    q = np.exp(value - value.max())
    q /= q.sum()
    expected_end = float(q @ cp[:, -1, 2])
    assert abs(cp[k, -1, 2] - expected_end) == min(abs(cp[i, -1, 2] - expected_end) for i in (0, 1))


def test_disallowed_policies_carry_no_mass_and_are_never_chosen():
    value = np.array([0.0, -0.5, -0.5, -0.5])
    cp = _points([0.0, 3.2, 3.2, 3.2], [40.0, 30.0, 40.0, 50.0])
    allowed = np.array([True, False, False, True])
    _, _, _, mass = maneuver_masses(value, cp, allowed)
    assert mass[1] == pytest.approx(math.exp(-0.5) / (1 + math.exp(-0.5)))
    assert expected_choice(value, cp, lane_change_bias=1.0, allowed=allowed) == 0
    assert expected_choice(value, cp, lane_change_bias=10.0, allowed=allowed) == 3


def test_the_calibrated_bias_changes_lanes_in_the_expected_share_of_cycles():
    ratios = np.array([0.5, 2.0, 3.0, 8.0, np.inf])  # the last cycle has no lane change to choose
    mass = np.array([0.6, 0.5, 0.4, 0.3, 0.2])  # mean 0.4: two of five cycles should change lanes
    bias = calibrate_lane_change_bias(ratios, mass)
    assert np.mean(bias > ratios) == pytest.approx(0.4) and bias == pytest.approx(2.0)
    # never below 1 (the bias does not hold lane changes back), 1 when no change is expected
    assert calibrate_lane_change_bias(np.array([0.1, 0.2]), np.array([0.5, 0.5])) == 1.0
    assert calibrate_lane_change_bias(np.array([5.0, 6.0]), np.array([0.1, 0.1])) == 1.0
    # more expected than possible: every cycle that has a lane change changes
    assert np.isfinite(calibrate_lane_change_bias(np.array([2.0, np.inf]), np.array([1.0, 1.0])))
    with pytest.raises(ValueError):
        calibrate_lane_change_bias(np.array([]), np.array([]))


def _lanes_set(start: int, ends: list[int], value: list[float], collision: list[bool]) -> PolicySet:
    """Policies from lane ``start`` to ``ends``, V = ``value`` under theta = e_0, labels as given."""
    n, t = len(ends), 3
    lane = np.array([[start, end, end] for end in ends], dtype=np.int8)
    features = np.zeros((n, len(FEATURE_NAMES)), np.float32)
    features[:, 0] = -np.asarray(value, np.float32)
    zeros = np.zeros((n, t))
    labels = np.zeros((n, 3), bool)
    labels[:, 0] = collision
    return PolicySet(
        t=0.0, x=zeros, y=zeros, yaw=zeros, v=zeros, s=zeros, d=lane.astype(float), lane=lane,
        progress=np.zeros(n, np.float32), features=features, control_points=np.zeros((n, 2, 3), np.float32),
        actions=np.zeros((n, 2, 2), np.float32), labels=labels,
    )  # fmt: skip


E0 = np.eye(len(FEATURE_NAMES))[0]


def test_a_lane_change_under_way_is_finished_unless_it_collides():
    # from lane 1: keep (V 0), left to 2 (V 1), right to 0 (V 2)
    ps = _lanes_set(1, [1, 2, 0], [0.0, 1.0, 2.0], [False, False, False])
    assert choose_index(ps, E0) == 2
    assert choose_index(ps, E0, heading=2) == 1  # heading left: the best policy that ends there
    hit = _lanes_set(1, [1, 2, 0], [0.0, 1.0, 2.0], [False, True, False])
    assert choose_index(hit, E0, heading=2) == 2  # every policy to the left collides: chosen afresh
    # with the label filter, the commitment keeps within what it allows
    off = _lanes_set(1, [1, 2, 2, 0], [0.0, 1.0, 0.5, 2.0], [False, False, False, False])
    off.labels[1, 1] = True  # policy 1 leaves the road
    assert choose_index(off, E0, safety=True, heading=2) == 2


def test_any_value_is_chosen_under_the_same_rules():
    # the values given replace -theta^T f (theta unused): the best of them, within the rules
    ps = _lanes_set(1, [1, 2, 0], [0.0, 1.0, 2.0], [False, False, False])
    assert choose_index(ps, E0, value=np.array([5.0, 1.0, 2.0])) == 0
    assert choose_index(ps, -E0, value=np.array([5.0, 1.0, 2.0])) == 0  # theta is not read
    assert choose_index(ps, E0, heading=2, value=np.array([5.0, 1.0, 2.0])) == 1


def test_the_driver_dispatches_the_maneuver_choice():
    # one keeping policy (V 0) and three changes to lane 2 (V -0.6, -0.5, -0.4, their own progress): the
    # change has the mass; the maneuver choice drives its best, the expected one its middle progress
    ps = _lanes_set(1, [1, 2, 2, 2], [0.0, -0.6, -0.5, -0.4], [False] * 4)
    ps = replace(ps, control_points=_points([0.0, 3.2, 3.2, 3.2], [40.0, 30.0, 40.0, 50.0], k=2))
    assert choose_index(ps, E0) == 0
    assert choose_index(ps, E0, choice="maneuver") == 3 and choose_index(ps, E0, choice="expected") == 2


class _Planner:
    """Hands out prepared policy sets in turn (the commitment's bookkeeping is pure logic)."""

    cfg = PlannerConfig()

    def __init__(self, sets: list[PolicySet]):
        self.sets = iter(sets)

    def plan(self, obs):
        return next(self.sets)

    def trajectory(self, index):
        return index


def test_the_driver_keeps_its_lane_change_until_it_is_in_the_lane():
    sets = [
        _lanes_set(1, [1, 2, 0], [0.0, 2.0, 1.0], [False] * 3),  # chooses left
        _lanes_set(1, [1, 2, 0], [0.0, 1.0, 2.0], [False] * 3),  # now right looks better: still left
        _lanes_set(2, [2, 1], [0.0, 1.0], [False] * 2),  # in lane 2: chosen afresh (back to 1)
    ]
    committed = ThetaDriver(_Planner(sets), lambda ps, obs: E0, commit=True)  # type: ignore[arg-type]
    assert [committed.plan(None) for _ in range(3)] == [1, 1, 1]  # type: ignore[arg-type]
    assert committed.heading == 1  # the lane change back is under way
    committed.reset()
    assert committed.heading is None
    free = ThetaDriver(_Planner(sets), lambda ps, obs: E0)  # type: ignore[arg-type]
    assert [free.plan(None) for _ in range(3)] == [1, 2, 1]  # type: ignore[arg-type]


def _stop_set(value: list[float], runs: list[bool], moving: list[bool]) -> PolicySet:
    """Policies in one lane; ``runs``: crossing an active stop line without a full stop (the stop_line
    feature > 0); ``moving``: never below the planner's standstill speed (else they come to a stand)."""
    ps = _lanes_set(1, [1] * len(value), value, [False] * len(value))
    ps.features[:, FEATURE_NAMES.index("stop_line")] = np.where(runs, 1.5, 0.0)
    ps.v[:] = np.where(moving, 1.0, 0.0)[:, None]
    return ps


def test_a_stop_under_way_does_not_end_by_running_the_line():
    ps = _stop_set([0.0, 1.0, 0.5], runs=[False, True, False], moving=[False, True, True])
    assert choose_index(ps, E0) == 1  # the reward prefers running the line
    assert choose_index(ps, E0, stopping=True) == 2  # a stop under way: the best policy that does not
    every = _stop_set([0.0, 1.0], runs=[True, True], moving=[True, True])
    assert choose_index(every, E0, stopping=True) == 1  # none stops: chosen afresh
    # a stop outranks a lane change: the lane headed to only has a policy that runs the line
    both = _stop_set([0.0, 1.0, 0.5], runs=[False, True, False], moving=[False, True, True])
    both.lane[1, 1:] = 2
    assert choose_index(both, E0, heading=2) == 1 and choose_index(both, E0, heading=2, stopping=True) == 2
    sets = [
        _stop_set([1.0, 0.0], runs=[False, True], moving=[False, True]),  # chooses to stand
        _stop_set([0.0, 1.0], runs=[False, True], moving=[False, True]),  # then running looks better
        _stop_set([0.0, 1.0], runs=[False, False], moving=[False, True]),  # stood: moving on is free
    ]
    committed = ThetaDriver(_Planner(sets), lambda ps, obs: E0, commit=True)  # type: ignore[arg-type]
    assert [committed.plan(None) for _ in range(3)] == [0, 0, 1]  # type: ignore[arg-type]
    free = ThetaDriver(_Planner(sets), lambda ps, obs: E0)  # type: ignore[arg-type]
    assert [free.plan(None) for _ in range(3)] == [0, 1, 1]  # type: ignore[arg-type]


def test_the_full_stop_rule_never_runs_a_line_while_a_policy_stops():
    sets = [
        _stop_set([0.0, 1.0], runs=[False, True], moving=[True, True]),  # no stop chosen yet: still held
        _stop_set([0.0, 1.0, 2.0], runs=[False, True, True], moving=[True, True, True]),
        _stop_set([0.0, 1.0], runs=[True, True], moving=[True, True]),  # none can stop: the reward's
    ]
    ruled = ThetaDriver(_Planner(sets), lambda ps, obs: E0, full_stop=True)  # type: ignore[arg-type]
    no_line = SimpleNamespace(stop_s=math.inf)  # the braking curve is tested below
    assert [ruled.plan(no_line) for _ in range(3)] == [0, 0, 1]  # type: ignore[arg-type]
    free = ThetaDriver(_Planner(sets), lambda ps, obs: E0, commit=True)  # type: ignore[arg-type]
    assert [free.plan(None) for _ in range(3)] == [1, 2, 1]  # type: ignore[arg-type]


def _motion_set(v: np.ndarray, s: np.ndarray) -> PolicySet:
    """Policies in one lane with the given speeds and route positions [N, T]."""
    ps = _lanes_set(1, [1] * len(v), [0.0] * len(v), [False] * len(v))
    lane = np.ones(v.shape, np.int8)
    return replace(
        ps, x=np.zeros(v.shape), y=np.zeros(v.shape), yaw=np.zeros(v.shape), v=v, s=s, d=lane * 1.0, lane=lane
    )


def test_the_braking_curve_keeps_a_stop_that_the_next_cycle_can_still_make():
    cfg = PlannerConfig()
    t = np.arange(26) * cfg.dt
    line = 100.0 + cfg.stop_margin  # the stop point 100 m ahead: the curve allows sqrt(2 b 100) m/s now
    allowed = math.sqrt(2 * 4.0 * 100.0)
    v = np.array([np.full_like(t, allowed - 1.0), np.full_like(t, allowed + 1.0), np.full_like(t, 1.0)])
    v[0] = np.maximum(allowed - 1.0 - 4.0 * t, 0.0)  # braking at 4 m/s^2 from below the curve
    v[2, 3:] = 0.0  # policy 2 stands at step 3, then drives on fast: it has stood, so it may
    v[2, 10:] = 30.0
    s = np.concatenate([np.zeros((3, 1)), np.cumsum(v[:, 1:] * cfg.dt, axis=1)], axis=1)
    ps = _motion_set(v, s)
    assert within_braking_curve(ps, line, cfg, decel=4.0).tolist() == [True, False, True]
    v[0] = allowed - 1.0  # below the curve now, but driving on at constant speed crosses it later
    ps = _motion_set(v, np.concatenate([np.zeros((3, 1)), np.cumsum(v[:, 1:] * cfg.dt, axis=1)], axis=1))
    assert within_braking_curve(ps, line, cfg, decel=4.0).tolist() == [False, False, True]
    assert within_braking_curve(ps, math.inf, cfg).all()  # no active line: every policy
    assert within_braking_curve(ps, cfg.stop_reach + 1.0, cfg).all()  # out of reach: every policy
    # the driver narrows to the curve first, then to the reward's best
    ps = replace(ps, features=ps.features.copy())
    ps.features[:, 0] = [0.0, -5.0, 0.0]  # the reward prefers policy 1, above the curve
    ruled = ThetaDriver(_Planner([ps]), lambda p, obs: E0, full_stop=True)  # type: ignore[arg-type]
    assert ruled.plan(SimpleNamespace(stop_s=line)) == 2  # type: ignore[arg-type]


def _following(speeds: list[float], rear: float, lane_d: float = 0.0) -> tuple[SimpleNamespace, ...]:
    """Planner internals of policies at constant ``speeds`` in the ego's lane (d = 0), and an observation
    with one 5 m car at 20 m/s whose rear bumper is ``rear`` metres ahead of the ego's front, at d =
    ``lane_d``."""
    cfg = PlannerConfig()
    t = np.arange(cfg.n_steps) * cfg.dt
    n = len(speeds)
    lon = SimpleNamespace(s=np.outer(speeds, t), v=np.outer(speeds, np.ones_like(t)))
    lat = SimpleNamespace(d=np.zeros((1, len(t))))
    internals = SimpleNamespace(lon=lon, lat=lat, lon_idx=np.arange(n), lat_idx=np.zeros(n, np.int64))
    one = np.ones(1)
    xy_yaw = (0 * one, 0 * one, 0 * one)
    car = VehicleStates(("car",), *xy_yaw, 20 * one, (rear + 5.0) * one, lane_d * one, 5 * one, 2 * one)
    ego = SimpleNamespace(s=0.0)
    return internals, SimpleNamespace(ego=ego, vehicles=car, stop_s=math.inf, lap_length=1000.0)


def test_the_following_rule_keeps_the_experts_distance_or_falls_short_least():
    cfg = PlannerConfig()
    # the car 20 m ahead at 20 m/s: at 20 m/s the gap stays 20 m >= 0.8 s * 20 + 2 = 18 m; at 22 and 25 m/s
    # the ego closes in and needs room to brake back to 20 m/s at 3 m/s^2 besides: both fall short
    internals, obs = _following([20.0, 22.0, 25.0], rear=20.0)
    assert keeping_distance(internals, obs, cfg, ()).tolist() == [True, False, False]
    # the same car in the next lane is no leader: every policy keeps its distance
    internals, side = _following([20.0, 22.0, 25.0], rear=20.0, lane_d=3.2)
    assert keeping_distance(internals, side, cfg, ()).all()
    # cut in 10 m ahead: every policy falls short at 1 s, least the slowest: at 16 m/s the gap is 14 m
    # against 0.8 * 16 + 2 = 14.8 m (0.8 m short), at 18 m/s 12 against 16.4 (4.4), at 20 m/s 10 against
    # 18 (8): only the policy within 1 m of the least shortfall is kept
    internals, cut = _following([20.0, 18.0, 16.0], rear=10.0)
    assert keeping_distance(internals, cut, cfg, ()).tolist() == [False, False, True]
    # a headway of its own: 15 m behind the car, at its 20 m/s the gap stays 15 m, 3 m short of 0.8 s + 2 m
    # (18 m); at 19 m/s it is 16 m at 1 s against 17.2 (1.2 m short, the least) and opens: only that one
    # is kept. With 0.5 s + 2 m (12 and 11.5 m) both keep their distance
    internals, obs = _following([20.0, 19.0], rear=15.0)
    assert keeping_distance(internals, obs, cfg, ()).tolist() == [False, True]
    half = SelectionConfig(follow_headway=0.5)
    assert keeping_distance(internals, obs, cfg, (), half).tolist() == [True, True]
    # choose_index narrows to them, after the other rules and unless none is left
    ps = _lanes_set(1, [1, 1, 1], [2.0, 1.0, 0.0], [False] * 3)
    assert choose_index(ps, E0) == 0
    assert choose_index(ps, E0, distance=np.array([False, False, True])) == 2
    assert choose_index(ps, E0, distance=np.zeros(3, bool)) == 0


def test_the_following_rule_in_lane_keeps_the_rewards_lane_and_picks_the_speed():
    # from lane 2: keep it fast (V 3, short of the distance), keep it slower (V 1, keeps it), change to
    # lane 1 (V 2, keeps it; the rule alone would change lanes), keep it slowest (V 0, keeps it)
    ps = _lanes_set(2, [2, 2, 1, 2], [3.0, 1.0, 2.0, 0.0], [False] * 4)
    keeps = np.array([False, True, True, True])
    assert choose_index(ps, E0, distance=keeps) == 2  # any policy that keeps the distance: the lane change
    assert choose_index(ps, E0, distance=keeps, in_lane=True) == 1  # the reward's lane 2, slower
    # no policy in the reward's lane keeps the distance: the rule as without in_lane
    none_there = np.array([False, False, True, False])
    assert choose_index(ps, E0, distance=none_there, in_lane=True) == 2
    assert choose_index(ps, E0, in_lane=True) == 0  # no distance given: in_lane changes nothing


def test_the_following_rule_keeps_a_vehicle_ahead_that_a_policy_would_drive_through():
    cfg = PlannerConfig()
    # a car standing with its rear 3 m ahead of the ego's front: at 7 m/s the ego is 4 m past its rear
    # at 1 s (through it); braking to a stand within 1 m falls short of 2 m less than driving on does.
    # The car stays ahead of a policy that drives into it, so driving on is not "keeping the distance"
    internals, obs = _following([7.0, 0.0], rear=3.0)
    car = obs.vehicles
    obs.vehicles = replace(car, v=np.zeros(1))
    assert keeping_distance(internals, obs, cfg, ()).tolist() == [False, True]
    # a car the ego passes in the next lane and then drives in front of is behind it, not run into
    lat_d = np.zeros((1, cfg.n_steps))
    lat_d[0, : int(2.0 / cfg.dt)] = 3.2  # beside the car's lane for 2 s, then in it, 11-17 m ahead of it
    internals.lat.d = lat_d
    obs.vehicles = replace(car, v=np.full(1, 5.0))
    t = np.arange(cfg.n_steps) * cfg.dt
    internals.lon.s[:] = np.outer([12.0, 15.0], t)
    internals.lon.v[:] = np.array([[12.0], [15.0]])
    assert keeping_distance(internals, obs, cfg, ()).tolist() == [True, True]


def test_the_following_rule_sees_a_leader_braking_on():
    cfg = PlannerConfig()
    # the car 20 m ahead at 20 m/s, braking at 4 m/s^2: at constant speed a policy at 20 m/s keeps its
    # 0.8 s + 2 m = 18 m; braking on, the car stands after 5 s and 50 m, so the gap at 5 s is
    # 20 + 50 - 100 < 0: short. A policy that brakes as the car does keeps it
    internals, obs = _following([20.0, 20.0], rear=20.0)
    t = np.arange(cfg.n_steps) * cfg.dt
    v = np.maximum(20.0 - 4.0 * t, 0.0)
    internals.lon.v[1], internals.lon.s[1] = v, np.concatenate([[0.0], np.cumsum(v[1:] * cfg.dt)])
    assert keeping_distance(internals, obs, cfg, ()).tolist() == [True, True]
    braking = np.full(1, -4.0)
    assert keeping_distance(internals, obs, cfg, (), accel=braking).tolist() == [False, True]
    assert keeping_distance(internals, obs, cfg, (), accel=np.full(1, -0.5)).tolist() == [True, True]
    # the prediction in closed form: 20 m/s braking at 4 m/s^2 stands after 5 s, 50 m on
    travel, speed = braking_travel(
        np.array([[20.0], [20.0]]), np.array([[-4.0], [0.0]]), np.array([1.0, 5.0, 6.0])
    )
    assert travel.tolist() == [[18.0, 50.0, 50.0], [20.0, 100.0, 120.0]]
    assert speed.tolist() == [[16.0, 0.0, 0.0], [20.0, 20.0, 20.0]]


def test_the_driver_reads_each_vehicles_acceleration_from_its_last_cycle():
    driver = ThetaDriver(_Planner([]), lambda ps, obs: E0)  # type: ignore[arg-type]

    def seen(t: float, ids: tuple[str, ...], v: list[float]) -> SimpleNamespace:
        veh = SimpleNamespace(ids=ids, v=np.array(v))
        return SimpleNamespace(ego=SimpleNamespace(t=t), vehicles=veh)

    assert driver._accelerations(seen(10.0, ("a", "b"), [20.0, 8.0])).tolist() == [0.0, 0.0]  # first seen
    got = driver._accelerations(seen(10.2, ("b", "c"), [7.0, 3.0]))  # b braked 1 m/s in 0.2 s; c is new
    assert got.tolist() == pytest.approx([-5.0, 0.0])
    driver.reset()
    assert driver._accelerations(seen(10.4, ("b",), [6.0])).tolist() == [0.0]  # a new episode: none seen
