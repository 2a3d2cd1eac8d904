"""DAgger's learned driver: a learned reward drives, the expert (or SUMO's driver) labels (``irlsim collect
--driver``).

Every planning cycle one planner (the expert's) samples the policy set from the current state; the learned
model's decision is exactly ``irlsim drive``'s without ``--safety`` (argmax over the set of V = -theta^T f,
theta predicted by the model: the same :class:`~irlsim.reward.RewardDriver`), and that policy is
executed. On the same policy set and state the expert runs its own selection
(:meth:`~irlsim.planner.expert.ExpertDriver.select`); its index is the cycle's demonstration
(``demo_source`` 'expert', distance 0 by construction). The expert's lane hysteresis follows the executed
policy (:meth:`~irlsim.planner.expert.ExpertDriver.follow`): it labels from where the car is going.

With a SUMO demonstrator (a collect config's ``[demonstrator] kind = 'sumo'``) SUMO's driver labels
instead: before the learner's policy runs, the simulation looks ahead with SUMO's driver at the wheel for
the horizon and comes back (:meth:`irlsim.sim.branch.BranchingSimulation.branch`), and that odometry,
projected onto the cycle's policy set as a SUMO demonstrator's own (``demo_source`` 'odometry', its
distance and rules), is the demonstration: what that driver would have done in the learner's state.

Collection (the data layer) records a :class:`~irlsim.data.collection.LabelledDriver`; this module makes
one per episode, loading the model once per process.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from irlsim.data.collection import CollectConfig, LabelledDriver
from irlsim.data.demos import look_ahead_odometry
from irlsim.planner.expert import ExpertDriver
from irlsim.planner.policy_set import PolicySet
from irlsim.reward import LearnedReward, RewardDriver, load_reward
from irlsim.road import Road
from irlsim.sim.types import EgoState, Observation, Trajectory


class DaggerDriver:
    """A :class:`~irlsim.data.collection.LabelledDriver`: ``model`` drives, the expert labels; or, once
    collection sets ``look_ahead_by`` (a SUMO demonstrator:
    :meth:`irlsim.sim.branch.BranchingSimulation.look_ahead`), SUMO's driver labels from each cycle's
    state."""

    #: the simulation's look ahead with SUMO's driver at its lanes' centres (steps -> states driven,
    #: :meth:`irlsim.sim.branch.BranchingSimulation.look_ahead`); None: the expert labels
    look_ahead_by: Callable[[int], list[EgoState]] | None = None
    #: what the last look ahead keeps from SUMO's lanes' centres (set with it: the placed ego's offset,
    #: :meth:`irlsim.sim.branch.BranchingSimulation.look_ahead_offset`)
    lane_offset_by: Callable[[], float] | None = None

    def __init__(self, model: LearnedReward, road: Road, cfg: CollectConfig):
        if model.is_expert:
            raise ValueError("DAgger needs a learned driver: the expert labels, it does not drive")
        self.expert = ExpertDriver(road, cfg.planner)
        # the learner samples with the expert's planner: the expert's select() reads that planner's
        # internals of this very policy set
        self.decider = RewardDriver(model, road, cfg.planner, safety=False, planner=self.expert.planner)
        self.decider.reset()  # a new episode: the online history of a temporal model starts empty
        self.last_policy_set: PolicySet | None = None
        self.last_index = -1
        self.expert_index = -1
        self.look_ahead: list[tuple[float, float, float, float]] | None = None
        self.look_ahead_offset = 0.0
        self.horizon_steps = cfg.scenario.horizon_steps  # the look ahead: the planner's horizon

    def plan(self, obs: Observation) -> Trajectory:
        traj = self.decider.plan(obs)
        ps, idx = self.decider.last_policy_set, self.decider.last_index
        assert ps is not None
        if self.look_ahead_by is not None:  # from this very state, before the learner's policy runs
            # SUMO's driver at the centres of its lanes: the offset it keeps is the placement's, not its
            ahead = self.look_ahead_by(self.horizon_steps)
            self.look_ahead_offset = self.lane_offset_by() if self.lane_offset_by is not None else 0.0
            self.look_ahead = look_ahead_odometry(obs.ego, ahead)
        else:
            self.expert_index = self.expert.select(ps, obs)
        self.expert.follow(ps, idx)
        self.last_policy_set, self.last_index = ps, idx
        return traj


#: per process: the learned models, loaded once by the first episode that needs them
_MODELS: dict[tuple[str, int], LearnedReward] = {}


def dagger_driver_factory(checkpoint: str | Path, n_policies: int) -> Any:
    """A factory (road, cfg) -> :class:`DaggerDriver` for ``collect_episode``; the checkpoint is loaded
    once per process."""
    key = (str(checkpoint), int(n_policies))
    if key not in _MODELS:
        _MODELS[key] = load_reward(str(checkpoint), None, n_policies=n_policies)
    model = _MODELS[key]

    def make(road: Road, cfg: CollectConfig) -> LabelledDriver:
        return DaggerDriver(model, road, cfg)

    return make
