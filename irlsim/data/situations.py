"""Situation labels: what kind of driving a planning cycle is, one int8 per cycle.

Computed at collection time from the scene the expert sees (ego, other vehicles, the road's stop lines,
exits and the route's next checkpoint) and stored as the ``situation`` column of the cycles table. The
rule, first match wins (thresholds in :class:`SituationRule`):

====  ===============  ====================================================================================
code  name             rule
====  ===============  ====================================================================================
1     stop_queue       standing or queueing at a stop line: ego speed < ``queue_speed`` (2 m/s) and a stop
                       line (active or not) at most ``queue_reach`` (60 m) ahead
2     stop_approach    an active stop line (one the ego has not stopped at yet) at most ``stop_reach``
                       (100 m) ahead
3     lane_change      lane change towards a checkpoint: the ego's lane is not the target checkpoint's
                       required lane and the checkpoint is at most ``mission_reach`` (300 m, the planner's
                       mission distance) ahead
4     following        a vehicle within a 2 s time gap: a vehicle ahead whose rear bumper is at most
                       max(``time_gap`` x v, ``min_gap``) = max(2 s x v, 5 m) ahead of the ego's front bumper,
                       laterally within ``lateral_overlap`` (2.4 m, 3/4 of a lane) of the ego
5     exit             passing an exit: the ego is in the outer lane (0) within ``exit_before`` (80 m) before
                       to ``exit_after`` (20 m) after the point where an off-ramp leaves it
0     free             none of the above
====  ===============  ====================================================================================

``-1`` (``UNLABELLED``) marks cycles written without a label (``EpisodeWriter.add_cycle`` without
``situation``). A "situation switch" is a change of label between consecutive cycles of an episode
(``irlsim.irl.stability.situation_switches``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

SITUATION_NAMES: tuple[str, ...] = (
    "free",
    "stop_queue",
    "stop_approach",
    "lane_change",
    "following",
    "exit",
)
FREE, STOP_QUEUE, STOP_APPROACH, LANE_CHANGE, FOLLOWING, EXIT = range(6)
UNLABELLED = -1


@dataclass(frozen=True)
class SituationRule:
    """Thresholds of the situation rule (module docstring)."""

    queue_speed: float = 2.0  # [m/s]
    queue_reach: float = 60.0  # [m]
    stop_reach: float = 100.0  # [m]
    mission_reach: float = 300.0  # [m]
    time_gap: float = 2.0  # [s]
    min_gap: float = 5.0  # [m]
    lateral_overlap: float = 2.4  # [m]
    exit_before: float = 80.0  # [m]
    exit_after: float = 20.0  # [m]


RULE = SituationRule()


def situation_label(
    *,
    ego_s: float,
    ego_d: float,
    ego_v: float,
    ego_lane: int,
    lap_length: float,
    stop_lines_s: np.ndarray,
    active_stop_s: float,
    target_s: float,
    target_lane: int,
    exits_s: np.ndarray,
    vehicles_s: np.ndarray,
    vehicles_d: np.ndarray,
    vehicles_length: np.ndarray,
    rule: SituationRule = RULE,
) -> int:
    """The situation code of one cycle (module docstring). Positions in the route frame [m]:
    ``ego_s``, ``active_stop_s`` and ``target_s`` unwrapped (``active_stop_s`` = inf: none), the road's
    ``stop_lines_s`` / ``exits_s`` and the vehicles' ``vehicles_s`` in [0, lap_length); vehicle arrays
    [M], front-bumper positions."""
    s_w = ego_s % lap_length
    ahead_of = lambda s: (np.asarray(s, dtype=np.float64) - s_w) % lap_length  # noqa: E731
    lines = ahead_of(stop_lines_s)
    if ego_v < rule.queue_speed and (lines <= rule.queue_reach).any():
        return STOP_QUEUE
    if np.isfinite(active_stop_s) and 0.0 <= active_stop_s - ego_s <= rule.stop_reach:
        return STOP_APPROACH
    if ego_lane != target_lane and 0.0 <= target_s - ego_s <= rule.mission_reach:
        return LANE_CHANGE
    if len(vehicles_s):
        gap = ahead_of(np.asarray(vehicles_s) - np.asarray(vehicles_length))
        near = np.abs(np.asarray(vehicles_d, dtype=np.float64) - ego_d) <= rule.lateral_overlap
        # a gap of almost a lap is a vehicle just behind (its rear is behind the ego's front)
        gap = np.where(gap > lap_length / 2, np.inf, gap)
        if (near & (gap <= max(rule.time_gap * ego_v, rule.min_gap))).any():
            return FOLLOWING
    if ego_lane == 0 and len(exits_s):
        rel = ahead_of(exits_s)  # distance to each exit's start, in [0, L)
        rel = np.where(rel > lap_length / 2, rel - lap_length, rel)
        if ((rel <= rule.exit_before) & (rel >= -rule.exit_after)).any():
            return EXIT
    return FREE


def situation_of(obs: Any, road: Any, rule: SituationRule = RULE) -> int:
    """The situation code of an ``irlsim.sim.types.Observation`` on ``road`` (an ``irlsim.road.Road``)."""
    e, veh = obs.ego, obs.vehicles
    return situation_label(
        ego_s=e.s,
        ego_d=e.d,
        ego_v=e.v,
        ego_lane=e.lane,
        lap_length=road.lap_length,
        stop_lines_s=np.array([sl.s for sl in road.stop_lines]),
        active_stop_s=obs.stop_s,
        target_s=obs.target_s,
        target_lane=road.checkpoints[obs.target_checkpoint].lane,
        exits_s=np.array([ex.s_start for ex in road.exits]),
        vehicles_s=veh.s,
        vehicles_d=veh.d,
        vehicles_length=veh.length,
        rule=rule,
    )
