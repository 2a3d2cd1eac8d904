"""Reward stability metrics on known sequences."""

from __future__ import annotations

import numpy as np

from irlsim.irl.stability import plan_change, stability_summary, theta_change


def test_theta_change_on_a_known_sequence() -> None:
    thetas = np.array([[1.0, 0.0], [1.0, 1.0], [2.0, 2.0], [5.0, 0.0], [5.0, 0.0]])
    episode = np.array([0, 0, 0, 1, 1])
    ch = theta_change(thetas, episode)
    assert np.isnan(ch[0]) and np.isnan(ch[3])  # no predecessor in the episode
    np.testing.assert_allclose(ch[[1, 2, 4]], [1.0, np.sqrt(2) / np.sqrt(2), 0.0])
    s = stability_summary(ch, np.zeros(5), np.array([0, 0, 1, 1, 1]), episode, window=1)
    assert np.isclose(s["theta_change"], 2 / 3)
    # the switch at row 2: window 1 covers rows 1 and 2 -> pairs (0,1) and (1,2): changes 1 and 1
    assert np.isclose(s["theta_change_switch"], 1.0)


def test_plan_change_is_zero_for_a_consistent_plan_and_measures_an_offset() -> None:
    # K = 5 control points over a 5 s horizon, cycles 1 s apart, ego drives 10 m/s straight
    k, horizon, c = 5, 5.0, 3
    tau = np.arange(1, k + 1) * 1.0
    cp = np.zeros((c, 2, k, 3))
    cp[:, 0, :, 2] = 10 * tau  # policy 0: keep 10 m/s in lane
    cp[:, 1, :, 2] = 10 * tau
    cp[:, 1, :, 0] = 1.5  # policy 1: the same, 1.5 m to the left throughout
    ego_s = np.array([0.0, 10.0, 20.0])
    ego_d = np.zeros(c)
    t = np.array([0.0, 1.0, 2.0])
    ep = np.zeros(c, int)
    same = plan_change(np.array([0, 0, 0]), cp, ego_s, ego_d, t, ep, horizon)
    assert np.isnan(same[0])
    np.testing.assert_allclose(same[1:], 0.0, atol=1e-12)
    jump = plan_change(np.array([0, 1, 1]), cp, ego_s, ego_d, t, ep, horizon)
    # at t+1 the new plan starts at the ego (offset 0) and is 1.5 m left from its first point on: the old
    # plan's points at tau - 1 = 0 (excluded), 1, 2, 3, 4 s on the new clock all lie 1.5 m apart
    np.testing.assert_allclose(jump[1], 1.5)
    np.testing.assert_allclose(jump[2], 0.0, atol=1e-12)
