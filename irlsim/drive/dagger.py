"""DAgger's learned driver: a learned reward drives, the expert labels (``irlsim collect --driver``).

Every planning cycle one planner (the expert's) samples the policy set from the current state; the learned
model's decision is exactly ``irlsim drive``'s without ``--safety`` (argmax over the set of V = -theta^T f,
theta predicted by the model: the same :class:`~irlsim.reward.RewardDriver`), and that policy is
executed. On the same policy set and state the expert runs its own selection
(:meth:`~irlsim.planner.expert.ExpertDriver.select`); its index is the cycle's demonstration
(``demo_source`` 'expert', distance 0 by construction). The expert's lane hysteresis follows the executed
policy (:meth:`~irlsim.planner.expert.ExpertDriver.follow`): it labels from where the car is going.

Collection (the data layer) records a :class:`~irlsim.data.collection.LabelledDriver`; this module makes
one per episode, loading the model once per process.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from irlsim.data.collection import CollectConfig, LabelledDriver
from irlsim.planner.expert import ExpertDriver
from irlsim.planner.policy_set import PolicySet
from irlsim.reward import LearnedReward, RewardDriver, load_reward
from irlsim.road import Road
from irlsim.sim.types import Observation, Trajectory


class DaggerDriver:
    """A :class:`~irlsim.data.collection.LabelledDriver`: ``model`` drives, the expert labels."""

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

    def plan(self, obs: Observation) -> Trajectory:
        traj = self.decider.plan(obs)
        ps, idx = self.decider.last_policy_set, self.decider.last_index
        assert ps is not None
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
