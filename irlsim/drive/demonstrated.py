"""``irlsim drive --model demonstrator``: the collect config's own demonstrator drives the ego, on the same
seeds and scenario as the rewards beside it, so that ``drive`` compares a learned reward's style with its
driver's (three drivings or more give a style distance).

- a SUMO demonstrator: SUMO's car-following and lane-change models drive the ego with the demonstrator's
  vehicle type (as in collection, :class:`~irlsim.data.demonstrator.SumoDemonstrator`);
- a recording: episode i's recorded ego drives as it was recorded, the others replayed or, with
  ``--reactive``, driven by SUMO (:class:`~irlsim.data.recorded.RecordingDemonstrator`).

The expert has no such row: ``--model expert`` drives it. No reward is inferred and no policy of the set
is executed (the planner still samples it every cycle, as in collection), so the rules of the choice
(``--choice``, ``--commit``, ...) do not apply and the drive has no pictures.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.data.collection import CollectConfig
from irlsim.data.demonstrator import (
    EXPERT,
    RECORDING,
    SumoDemonstrator,
    demonstrator_simulation,
)
from irlsim.data.recorded import recorded_episode
from irlsim.errors import IrlsimError
from irlsim.planner.config import PlannerConfig
from irlsim.planner.expert import expert_theta
from irlsim.planner.policy_set import PolicySet
from irlsim.reward import LearnedReward, check_features, load_reward
from irlsim.road import Road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
from irlsim.sim.types import Observation, Trajectory

DEMONSTRATOR = "demonstrator"


class DemonstratorModel:
    """What ``--model demonstrator`` resolves to: no reward; the attributes of
    :class:`~irlsim.reward.LearnedReward` that ``irlsim drive`` reads (no checkpoint, no training seeds)."""

    name = DEMONSTRATOR
    checkpoint: Path | None = None
    trained: dict[str, Any] | None = None
    is_expert = False


def resolve_model(spec: str, runs: str | Path | None, planner: PlannerConfig, threads: int) -> Any:
    """``--model``'s entry: the demonstrator, or :func:`irlsim.reward.load_reward`'s reward for a planner
    ``planner`` (refused in one line when built for another policy count or feature set)."""
    if spec == DEMONSTRATOR:
        return DemonstratorModel()
    reward = load_reward(spec, runs, n_policies=planner.n_policies, threads=threads)
    check_features(reward, planner.feature_names)
    return reward


def check_demonstrator(cfg: CollectConfig) -> None:
    """One line, before any work, when the config's demonstrator is the expert."""
    if cfg.demonstrator.kind == EXPERT:
        raise IrlsimError(
            "--model demonstrator drives the config's [demonstrator], and this config's is the expert: "
            "--model expert drives it (or give a --config with SUMO's driver or a recording)"
        )


class DemonstratorDecider:
    """A demonstrator behind :class:`~irlsim.reward.RewardDriver`'s interface: ``plan(obs)``,
    ``last_policy_set``, ``last_index`` (-1: no policy executed), ``theta`` and ``info`` (none inferred),
    ``plan_ms`` (the cycle: the planner's sampling and the demonstrator's own), ``inference_ms`` (0)."""

    def __init__(self, driver: Any):
        self.driver = driver
        planner = getattr(driver, "planner", None)  # the weights pictures show: the expert's, none inferred
        self.theta: np.ndarray = expert_theta(
            planner.cfg.feature_names if planner is not None else FEATURE_NAMES
        )
        self.info: dict[str, Any] = {}
        self.plan_ms = 0.0
        self.inference_ms = 0.0

    @property
    def last_policy_set(self) -> PolicySet | None:
        ps: PolicySet | None = self.driver.last_policy_set
        return ps

    @property
    def last_index(self) -> int:
        return -1

    def reset(self) -> None:
        """Nothing carries over between episodes."""

    def plan(self, obs: Observation) -> Trajectory:
        t0 = time.perf_counter()
        trajectory: Trajectory = self.driver.plan(obs)
        self.plan_ms = (time.perf_counter() - t0) * 1e3
        return trajectory


def demonstrator_episode(
    cfg: CollectConfig, road: Road, scenario: EpisodeConfig, episode: int, reactive: bool
) -> tuple[DemonstratorDecider, Road, EpisodeConfig, Simulation]:
    """The decider, road, settings and simulation of episode ``episode`` driven by ``cfg``'s demonstrator:
    a recording's ego number ``episode`` (its egos resolved into ``cfg.demonstrator.ego``) as recorded,
    or SUMO's driver with the demonstrator's type on ``scenario``."""
    check_demonstrator(cfg)
    if cfg.demonstrator.kind == RECORDING:
        driver, road, scenario, replay = recorded_ego_episode(cfg, road, scenario, episode, reactive, False)
        return DemonstratorDecider(driver), road, scenario, replay
    sim = demonstrator_simulation(road, scenario, cfg.demonstrator)
    return DemonstratorDecider(SumoDemonstrator(road, cfg.planner, scenario)), road, scenario, sim


def recorded_ego_episode(
    cfg: CollectConfig,
    road: Road,
    scenario: EpisodeConfig,
    episode: int,
    reactive: bool,
    end_on_collision: bool = True,
) -> tuple[Any, Road, EpisodeConfig, Simulation]:
    """Episode ``episode`` of ``cfg``'s recording (its egos resolved into ``cfg.demonstrator.ego``): the
    recorded ego's driver, its road, settings and the replay (:func:`irlsim.data.recorded.recorded_episode`),
    whoever then drives it (``end_on_collision`` False: the recorded ego itself, which drives on through a
    collision, as recorded)."""
    d = cfg.demonstrator
    ego = d.ego.split(",")[episode]
    return recorded_episode(
        d.file, road, scenario, cfg.planner, ego, reactive, d.rate_window, end_on_collision, d.read_as()
    )


def is_demonstrator(model: LearnedReward | DemonstratorModel | str | Path) -> bool:
    """Whether ``model`` (an object or a spec) is the demonstrator."""
    return isinstance(model, DemonstratorModel) or str(model) == DEMONSTRATOR
