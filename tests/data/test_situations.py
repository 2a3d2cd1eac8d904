"""Situation labels on constructed cycles."""

from __future__ import annotations

import numpy as np

from irlsim.data.situations import (
    EXIT,
    FOLLOWING,
    FREE,
    LANE_CHANGE,
    STOP_APPROACH,
    STOP_QUEUE,
    situation_label,
)
from irlsim.irl.stability import near_switch, situation_switches

L = 2000.0


def _label(**kw: object) -> int:
    base: dict[str, object] = dict(
        ego_s=500.0,
        ego_d=0.0,
        ego_v=15.0,
        ego_lane=1,
        lap_length=L,
        stop_lines_s=np.array([1000.0, 1900.0]),
        active_stop_s=float("inf"),
        target_s=1500.0,
        target_lane=1,
        exits_s=np.array([300.0]),
        vehicles_s=np.zeros(0),
        vehicles_d=np.zeros(0),
        vehicles_length=np.zeros(0),
    )
    base.update(kw)
    return situation_label(**base)  # type: ignore[arg-type]


def test_each_rule_on_a_constructed_cycle() -> None:
    assert _label() == FREE
    assert _label(ego_s=950.0, active_stop_s=1000.0) == STOP_APPROACH
    assert _label(ego_s=850.0, active_stop_s=1000.0) == FREE  # 150 m > 100 m reach
    assert _label(ego_s=960.0, ego_v=0.5) == STOP_QUEUE  # standing 40 m before a line
    assert _label(ego_s=2000.0 + 1880.0, ego_v=0.0) == STOP_QUEUE  # second lap, wraps
    assert _label(target_s=700.0, target_lane=2) == LANE_CHANGE
    assert _label(target_s=900.0, target_lane=2) == FREE  # 400 m away
    # a vehicle 20 m ahead (rear bumper 15.5 m ahead) at 15 m/s: 1.03 s time gap
    veh = dict(vehicles_s=np.array([520.0]), vehicles_d=np.array([0.3]), vehicles_length=np.array([4.5]))
    assert _label(**veh) == FOLLOWING
    assert _label(**{**veh, "vehicles_d": np.array([3.2])}) == FREE  # next lane
    assert _label(**{**veh, "ego_v": 5.0}) == FREE  # 3.1 s time gap
    assert _label(**{**veh, "vehicles_s": np.array([498.0])}) == FREE  # behind
    assert _label(ego_s=250.0, ego_lane=0, ego_d=-3.2) == EXIT
    assert _label(ego_s=250.0, ego_lane=1) == FREE  # not in the exit lane
    # priority: a queue at a stop line beats a lane change and a vehicle ahead
    assert (
        _label(
            ego_s=960.0, ego_v=0.5, target_s=1100.0, target_lane=2, **{**veh, "vehicles_s": np.array([975.0])}
        )
        == STOP_QUEUE
    )


def test_switches_stay_inside_episodes() -> None:
    sit = np.array([0, 0, 2, 2, 2, 1, 1])
    ep = np.array([0, 0, 0, 0, 1, 1, 1])
    assert situation_switches(sit, ep).tolist() == [False, False, True, False, False, True, False]
    assert near_switch(sit, ep, window=1).tolist() == [False, True, True, False, True, True, False]
