"""irlsim.planner.choice: the 'expected' choice and its lane-change bias, against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from irlsim.planner.choice import calibrate_lane_change_bias, change_ratio, expected_choice, maneuver_masses


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
