"""The learned reward as a library: load a trained model and ask it about one real planning cycle.

    python examples/reward_quickstart.py [RUNS] [--model PACNN+S] [--config configs/collect/tiny.toml]

RUNS (default runs/tiny, what 'make demo PRESET=tiny' writes) holds the trained models; the collect
config gives the planner and scenario they were trained with. Nothing is trained here: SUMO starts one
episode, the planner samples the first cycle's policy set, and the reward scores it.
"""

from __future__ import annotations

import argparse

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.planner.planner import Planner
from irlsim.reward import load_reward
from irlsim.road import load_road
from irlsim.rollout import EpisodeRunner
from irlsim.sim.simulation import Simulation

p = argparse.ArgumentParser(description="theta, policy values and the chosen policy of one real cycle")
p.add_argument("runs", nargs="?", default="runs/tiny", help="runs folder (default: runs/tiny)")
p.add_argument("--model", default="PACNN+S", help="a model name in RUNS, a checkpoint path, or expert-theta")
p.add_argument("--config", default="configs/collect/tiny.toml", help="the collect config it was trained on")
p.add_argument("--seed", type=int, default=100, help="the SUMO episode's seed")
args = p.parse_args()

cfg = load_config(CollectConfig, args.config)
reward = load_reward(args.model, runs=args.runs, n_policies=cfg.planner.n_policies)
road = load_road(scenario=cfg.scenario.name)
with Simulation(road, cfg.scenario) as sim:
    runner = EpisodeRunner(sim, planner=Planner(road, cfg.planner))
    obs, policy_set = runner.reset(args.seed)  # one real cycle: the ego's state and its sampled policies
assert policy_set is not None

reward.reset()  # a new episode (a temporal model's history starts empty)
theta = reward.theta(policy_set)  # [15]: one weight per feature
values = reward.values(policy_set)  # [N]: V = -theta^T f of every policy
index = reward.choose(policy_set)  # argmax V: the policy this reward drives

print(f"{reward.name}: {policy_set.n_policies} policies at {obs.ego.v * 3.6:.0f} km/h, seed {args.seed}")
print("theta:", ", ".join(f"{name} {w:.3g}" for name, w in zip(FEATURE_NAMES, theta, strict=True)))
top = np.argsort(values)[::-1][:5]
print("best values:", ", ".join(f"#{i} {values[i]:.3f}" for i in top))
print(f"chosen policy: #{index} (value {values[index]:.3f}, ends in lane {policy_set.lane[index, -1]})")
