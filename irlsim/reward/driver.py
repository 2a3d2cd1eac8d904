"""A learned reward (or the expert) driving a planner: :class:`RewardDriver`, one decision per cycle.

The closed loop of ``irlsim drive`` and the learner of DAgger (``irlsim collect --driver``) both drive
with it, so a learned model decides exactly alike in both.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from irlsim.planner.config import PlannerConfig
from irlsim.planner.expert import ExpertDriver, ThetaDriver, expert_theta
from irlsim.planner.planner import Planner
from irlsim.planner.policy_set import PolicySet
from irlsim.reward.learned import LearnedReward, check_features
from irlsim.road import Road
from irlsim.sim.types import Observation, Trajectory


class RewardDriver:
    """The driver of one reward plus per-cycle timing (a :class:`~irlsim.rollout.PolicyDriver`):
    ``plan(obs)`` returns the trajectory; afterwards ``last_policy_set``, ``last_index``, ``theta``,
    ``info``, ``plan_ms`` and ``inference_ms`` describe the cycle.

    A learned reward executes argmax V = -theta^T f over the planner's set (behind the label filter with
    ``safety``); 'expert' (``reward.is_expert``) drives the demonstrator itself, whose 'inference' is its
    model-based selection. Call :meth:`reset` at the start of every episode.
    """

    def __init__(
        self,
        reward: LearnedReward,
        road: Road,
        planner_cfg: PlannerConfig,
        safety: bool = False,
        planner: Planner | None = None,
        choice: str = "argmax",
        lane_change_bias: float = 1.0,
        commit: bool = False,
        full_stop: bool = False,
        keep_distance: float = 0.0,
        in_lane: bool = False,
    ):
        """``planner``: the learned driver samples its policy sets with this one (DAgger shares the
        expert's, so the expert labels the very set the learner chose from); default: its own.
        ``choice``, ``lane_change_bias``, ``commit``, ``full_stop``, ``keep_distance``, ``in_lane``: how a
        learned reward picks its policy
        (:mod:`irlsim.planner.choice`, :class:`~irlsim.planner.expert.ThetaDriver`; the expert keeps its
        own selection)."""
        check_features(reward, planner_cfg.feature_names)
        self.reward = reward
        self.info: dict[str, Any] = {}
        self.inference_ms = 0.0
        self.plan_ms = 0.0
        self.theta: np.ndarray = expert_theta(planner_cfg.feature_names)
        self.last_policy_set: PolicySet | None = None
        self.last_index = -1
        self.driver: ExpertDriver | ThetaDriver
        if reward.is_expert:
            self.driver = ExpertDriver(road, planner_cfg)
            self.planner = self.driver.planner
        else:
            self.planner = planner if planner is not None else Planner(road, planner_cfg)
            self.driver = ThetaDriver(
                self.planner, self._theta, safety, choice, lane_change_bias,
                commit=commit, full_stop=full_stop, keep_distance=keep_distance, in_lane=in_lane,
            )  # fmt: skip

    def _theta(self, ps: PolicySet, obs: Observation) -> np.ndarray:
        t0 = time.perf_counter()
        theta = self.reward.theta(ps)
        self.inference_ms = 1e3 * (time.perf_counter() - t0)
        self.info = self.reward.info
        return theta

    def reset(self) -> None:
        """A new episode: the reward's online history starts empty, no maneuver under way."""
        self.reward.reset()
        if isinstance(self.driver, ThetaDriver):
            self.driver.reset()

    def plan(self, obs: Observation) -> Trajectory:
        t0 = time.perf_counter()
        traj = self.driver.plan(obs)
        total_ms = 1e3 * (time.perf_counter() - t0)
        self.plan_ms = float(self.planner.last_ms)
        if isinstance(self.driver, ExpertDriver):  # its 'inference' is the model-based selection
            self.inference_ms = max(total_ms - self.plan_ms, 0.0)
            self.theta, self.info = self.driver.theta, {}
        else:
            assert self.driver.last_theta is not None
            self.theta = self.driver.last_theta
        self.last_policy_set, self.last_index = self.driver.last_policy_set, self.driver.last_index
        return traj
