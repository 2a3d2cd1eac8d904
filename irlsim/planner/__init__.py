"""Reward-agnostic sampling planner, the 15 path-integral features, and the expert demonstrator.

``Planner(road, cfg).plan(obs) -> PolicySet``; ``ExpertDriver`` / ``ThetaDriver`` turn it into drivers.
"""

from irlsim.planner.config import PlannerConfig
from irlsim.planner.policy_set import LABEL_NAMES, PolicySet

__all__ = ["LABEL_NAMES", "PlannerConfig", "PolicySet"]
