"""The lane-change bias of a reward's ``expected`` choice, calibrated on the states it was trained on.

    from irlsim.reward import load_reward
    from irlsim.reward.choice import lane_change_bias
    reward = load_reward("PACNN+S", runs="runs/styles/runs/assertive-seed0/stage1")
    bias = lane_change_bias(reward, ["runs/styles/data/assertive/oval"])   # then drive with
    # irlsim drive --choice expected --lane-change-bias <bias>

The bias makes the ``expected`` choice (:mod:`irlsim.planner.choice`) change lanes in the share of a
dataset's cycles that the reward's own distribution expects: :func:`irlsim.planner.choice.
calibrate_lane_change_bias` over every cycle of the split (those without a demonstration too: what is
calibrated is the reward's decision, not a fit to the demonstrator).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from irlsim.data.aggregate import open_datasets
from irlsim.planner.choice import calibrate_lane_change_bias, change_ratio
from irlsim.reward.learned import LearnedReward


def cycle_values(
    reward: LearnedReward, data: list[str | Path], split: str = "train"
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(V [N], control points [N, K, 3]) of every cycle of split ``split`` of the datasets ``data``, in
    order, one prediction per cycle as the planner makes them (a temporal model's history starts with
    each episode; reset again at the end)."""
    tensors = open_datasets(list(data)).split_tensors(split)
    episode = None
    for c in range(len(tensors.demo_index)):
        if tensors.episode[c] != episode:
            reward.reset()
            episode = tensors.episode[c]
        features, points = np.asarray(tensors.features[c]), np.asarray(tensors.control_points[c])
        theta = reward.predict(features, points, np.asarray(tensors.actions[c]))
        yield -(features.astype(np.float64) @ theta), points
    reward.reset()


def lane_change_bias(reward: LearnedReward, data: list[str | Path], split: str = "train") -> float:
    """The calibrated lane-change bias of ``reward`` on split ``split`` of the datasets ``data``."""
    got = [change_ratio(value, points) for value, points in cycle_values(reward, data, split)]
    ratios, mass = np.asarray(got, dtype=np.float64).reshape(-1, 2).T
    return calibrate_lane_change_bias(ratios, mass)
