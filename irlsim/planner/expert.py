"""The expert demonstrator and a generic theta driver.

``ExpertDriver`` = hand-tuned ``THETA_EXPERT`` + model-based selection in the spirit of the paper:

1. drop policies labelled predicted collision, off-road or exit, those that cross an active stop line
   without a full stop (stop_line > 0) when others do not, and those that enter the safety zone of
   a predicted vehicle (headway ``safety_headway`` ahead, ``safety_rear_headway`` behind; the planner's
   ``risk``); when nothing is left, keep the least risky of the non-off-road, non-exit ones;
2. cluster the rest topologically by lane sequence: (lane at the horizon, number of lane changes);
3. score each cluster by its best progress [m], minus ``lc_cost`` per lane change, minus a mission
   penalty ``|lane - required lane| * min(mission_cap, mission_scale / remaining distance)`` [m], plus
   ``keep_bonus`` for the lane the expert is already heading to (hysteresis);
4. inside the best cluster execute argmax V = -theta^T f.
When every policy is off-road or takes an exit (never seen), it falls back to the strongest braking.

``ThetaDriver(planner, theta_fn)`` executes argmax V for any theta (the learned models use it), with an
optional model-based safety filter (the labels). Both expose ``last_policy_set`` and ``last_index``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.planner.config import PlannerConfig
from irlsim.planner.planner import Planner
from irlsim.planner.policy_set import PolicySet
from irlsim.road import Road
from irlsim.sim.types import Observation, Trajectory

#: the expert's hand-tuned weights, one per feature (FEATURE_NAMES order); V = -theta^T f
THETA_EXPERT_DICT: dict[str, float] = {
    "acc_lon": 1.0,  # 1 m/s^2 held over the horizon costs ~3
    "jerk_lon": 0.3,
    "acc_lat": 0.5,
    "jerk_lat": 0.2,
    "velocity": 1.0,  # 5 m/s below target over the horizon costs ~77
    "creep": 5.0,
    "end_heading": 50.0,
    "centerline": 10.0,  # hovering 0.8 m off a lane centre over the horizon costs ~20
    "road_edge": 100.0,
    "mission_lane": 3.0,
    "progress": 0.05,
    "stop_line": 100.0,
    "lc_delay": 1.0,
    "lat_overshoot": 10.0,
    "proximity": 10.0,
}
THETA_EXPERT = np.array([THETA_EXPERT_DICT[n] for n in FEATURE_NAMES], dtype=np.float64)


@dataclass(frozen=True)
class SelectionConfig:
    """The expert's model-based selection (units: metres of progress over the horizon)."""

    lc_cost: float = 2.0
    """[m] cluster score cost per lane change"""
    keep_bonus: float = 3.0
    """[m] cluster score bonus for the lane the expert already heads to (no dithering)"""
    mission_scale: float = 20000.0
    """[m^2] mission penalty per lane away from the required lane = min(cap, scale / remaining distance)"""
    mission_cap: float = 400.0
    """[m] cap of the mission penalty per lane"""
    progress_tol: float = 1.0
    """[m] cluster scores within this of the best count as equal (the fewest lane changes wins)"""


def lane_clusters(ps: PolicySet) -> tuple[np.ndarray, np.ndarray]:
    """(final lane [N] int, number of lane changes [N] int) of every policy."""
    lane = ps.lane.astype(np.int16)
    changes = (np.diff(lane, axis=1) != 0).sum(axis=1)
    return lane[:, -1].astype(np.int64), changes.astype(np.int64)


class ExpertDriver:
    """The demonstrator: ``plan(obs) -> Trajectory``; ``last_policy_set`` / ``last_index`` keep the
    executed cycle's PolicySet and the index of the executed policy in it."""

    def __init__(self, road: Road, cfg: PlannerConfig | None = None, theta: np.ndarray | None = None,
                 selection: SelectionConfig | None = None):
        self.road = road
        self.planner = Planner(road, cfg)
        self.theta = THETA_EXPERT.copy() if theta is None else np.asarray(theta, dtype=np.float64)
        assert self.theta.shape == (len(FEATURE_NAMES),), self.theta.shape
        self.sel = selection or SelectionConfig()
        self.last_policy_set: PolicySet | None = None
        self.last_index: int = -1
        self._heading_lane: int | None = None

    def select(self, ps: PolicySet, obs: Observation) -> int:
        """Index of the policy the expert executes (see the module docstring)."""
        internals = self.planner.last
        assert internals is not None
        lab = ps.labels
        allowed = ~lab[:, 1] & ~lab[:, 2]
        # a full stop at every active stop line is a hard rule, like the labels
        stops = ps.features[:, FEATURE_NAMES.index("stop_line")] <= 0
        if (allowed & stops).any():
            allowed &= stops
        if not allowed.any():
            return int(np.argmin(ps.progress))  # sorted by progress: the hardest braking comes first
        risk = np.where(allowed & ~lab[:, 0], internals.risk, np.inf)
        if np.isinf(risk).all():
            risk = np.where(allowed, internals.risk, np.inf)
        ok = risk <= risk.min() + 1e-6
        value = ps.value(self.theta)
        final_lane, n_lc = lane_clusters(ps)
        req = self.road.checkpoints[obs.target_checkpoint].lane
        rem = max(obs.target_s - obs.ego.s, 1.0)
        mission = np.minimum(self.sel.mission_cap, self.sel.mission_scale / rem)
        keys = final_lane * 16 + np.minimum(n_lc, 15)
        best_key, best_score = None, -np.inf
        for key in np.unique(keys[ok]):  # a handful of clusters
            members = ok & (keys == key)
            lane_k, lc_k = int(key // 16), int(key % 16)
            score = float(ps.progress[members].max()) - self.sel.lc_cost * lc_k - mission * abs(lane_k - req)
            if self._heading_lane is not None and lane_k == self._heading_lane:
                score += self.sel.keep_bonus
            if score > best_score + self.sel.progress_tol or (
                abs(score - best_score) <= self.sel.progress_tol and best_key is not None and lc_k < best_key % 16
            ):
                best_key, best_score = key, score
        members = ok & (keys == best_key)
        idx = int(np.argmax(np.where(members, value, -np.inf)))
        self._heading_lane = int(final_lane[idx])
        return idx

    def plan(self, obs: Observation) -> Trajectory:
        ps = self.planner.plan(obs)
        idx = self.select(ps, obs)
        self.last_policy_set, self.last_index = ps, idx
        return self.planner.trajectory(idx)


class ThetaDriver:
    """Executes argmax V = -theta^T f under ``theta_fn(policy_set, obs) -> theta [15]`` each cycle.

    ``safe=True`` first drops policies labelled collision / off-road / exit (model-based safety, as the
    paper's planner does around a learned reward); when that drops all of them it uses all.
    """

    def __init__(self, planner: Planner, theta_fn: Callable[[PolicySet, Observation], Any], safe: bool = False):
        self.planner = planner
        self.theta_fn = theta_fn
        self.safe = safe
        self.last_policy_set: PolicySet | None = None
        self.last_index: int = -1
        self.last_theta: np.ndarray | None = None

    def plan(self, obs: Observation) -> Trajectory:
        ps = self.planner.plan(obs)
        theta = np.asarray(self.theta_fn(ps, obs), dtype=np.float64).reshape(-1)
        assert theta.shape == (len(FEATURE_NAMES),), theta.shape
        value = ps.value(theta)
        if self.safe:
            bad = ps.labels.any(axis=1)
            if not bad.all():
                value = np.where(bad, -np.inf, value)
        idx = int(np.argmax(value))
        self.last_policy_set, self.last_index, self.last_theta = ps, idx, theta
        return self.planner.trajectory(idx)


def planner_config_for(scenario_cfg: Any) -> PlannerConfig:
    """A PlannerConfig whose clocks, target speed and ego size match a ScenarioConfig."""
    return PlannerConfig(
        horizon=float(scenario_cfg.horizon), dt=float(scenario_cfg.step), cycle=float(scenario_cfg.cycle),
        v_target=float(scenario_cfg.ego_target_speed), ego_length=float(scenario_cfg.ego_length),
        ego_width=float(scenario_cfg.ego_width),
    )


def make_expert_driver(road: Road, scenario_cfg: Any) -> ExpertDriver:
    """Factory for the sim's driver registry: ``DRIVERS['expert'] = make_expert_driver``."""
    return ExpertDriver(road, planner_config_for(scenario_cfg))

