"""The learned reward as a library: load any trained model (or the expert's theta) and ask it, per
planning cycle, for theta, the policy values and its chosen policy.

    from irlsim.reward import load_reward
    reward = load_reward("runs/tiny/stage1/PACNN+S/checkpoint.pt")   # a checkpoint path, or
    reward = load_reward("PACNN+S", runs="runs/tiny")                 # a model name found in runs
    reward.reset()                      # a new episode (PTACNN's history)
    theta = reward.theta(policy_set)    # np.ndarray [F]: one weight per feature (15: the paper's set)
    values = reward.values(policy_set)  # np.ndarray [N] (the policy values the planner ranks)
    index = reward.choose(policy_set)   # int, the chosen policy

:mod:`irlsim.reward.learned`: :func:`load_reward`, :class:`LearnedReward`; :mod:`irlsim.reward.driver`:
:class:`RewardDriver` (a reward driving a planner, closed loop and DAgger); :mod:`irlsim.reward.predictor`:
:class:`~irlsim.reward.predictor.RewardPredictor` (the networks' online inference; imports torch, so it is
not imported here).
"""

from irlsim.planner.expert import choose_index
from irlsim.reward.driver import RewardDriver
from irlsim.reward.learned import (
    EXPERT,
    EXPERT_THETA,
    FixedTheta,
    LearnedReward,
    ThetaPredictor,
    check_features,
    load_reward,
    model_names,
)

__all__ = [
    "EXPERT",
    "EXPERT_THETA",
    "FixedTheta",
    "LearnedReward",
    "RewardDriver",
    "ThetaPredictor",
    "check_features",
    "choose_index",
    "load_reward",
    "model_names",
]
