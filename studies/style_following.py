r"""What the style's headway measures: while following, is the ego closing on its leader, keeping pace or
falling back?

A learned reward (``--runs``, PACNN+S, the expected choice with its lane-change bias calibrated on
``--calibrate-on``, ``--commit --full-stop`` as in the style study's judgements) and the config's SUMO
demonstrator each drive ``--episodes`` episodes of ``--config`` on the same seeds (``--seed`` + i). At every
simulation step where the style counts the ego as following (a leader in its lane within
:data:`~irlsim.rollout.style.FOLLOW_RANGE`, speed above :data:`~irlsim.rollout.style.MIN_FOLLOW_SPEED`), the
time headway, the ego's and the leader's speed; then the share of the following time spent closing (the
leader slower by more than 0.5 m/s), keeping pace and falling back, and the median headway in each:

    .venv/bin/python studies/style_following.py --runs runs/styles-dev/runs/assertive-seed0 \
        --config configs/collect/styles/assertive.toml --calibrate-on runs/styles-dev/data/assertive/oval \
        runs/styles-dev/data/assertive/motorway --episodes 6
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.data.demonstrator import SUMO, SumoDemonstrator, demonstrator_simulation
from irlsim.reward import RewardDriver, load_reward
from irlsim.reward.choice import lane_change_bias
from irlsim.road import load_road
from irlsim.rollout import EpisodeRunner
from irlsim.rollout.runner import StepListener
from irlsim.rollout.style import FOLLOW_RANGE, MIN_FOLLOW_SPEED, leader_ahead
from irlsim.sim.simulation import Simulation
from irlsim.utils import seed_everything

PACE = 0.5  # [m/s] a leader within this of the ego's speed keeps pace


class Following(StepListener):
    """(time headway [s], ego speed, leader speed) at every step the style counts as following."""

    def __init__(self) -> None:
        self.rows: list[tuple[float, float, float]] = []

    def on_step(self, sim: Any) -> None:
        e = sim.ego
        gap, k = leader_ahead(sim)  # the style's leader
        if k >= 0 and gap <= FOLLOW_RANGE and e.v > MIN_FOLLOW_SPEED:
            self.rows.append((gap / e.v, float(e.v), float(sim.vehicles.v[k])))


def summary(name: str, rows: list[tuple[float, float, float]], step: float) -> str:
    if not rows:
        return f"| {name} | 0 | - | - | - | - | - |"
    h, v, lead = (np.array(c) for c in zip(*rows, strict=True))
    parts = {
        "closing": lead < v - PACE,
        "keeping pace": np.abs(lead - v) <= PACE,
        "falling back": lead > v + PACE,
    }
    cells = [
        f"{m.mean():.2f} ({np.median(h[m]):.2f} s)" if m.any() else f"{m.mean():.2f} (-)"
        for m in parts.values()
    ]
    return (
        f"| {name} | {len(rows) * step:.0f} | {np.median(h):.2f} | {' | '.join(cells)} "
        f"| {np.median(v):.1f} / {np.median(lead):.1f} |"
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", required=True, help="a runs folder with PACNN+S (stage1)")
    p.add_argument("--config", required=True, help="a collect config with a SUMO demonstrator")
    p.add_argument("--calibrate-on", nargs="+", required=True, help="the reward's training datasets")
    p.add_argument("--scenario", default=None, help="the road (default: the config's)")
    p.add_argument("--episodes", type=int, default=6)
    p.add_argument("--seed", type=int, default=2_000_000_000, help="episode i has seed SEED + i")
    p.add_argument("--cycles", type=int, default=800)
    a = p.parse_args(argv)
    cfg = load_config(CollectConfig, a.config, {"scenario.name": a.scenario} if a.scenario else None)
    if cfg.demonstrator.kind != SUMO:
        sys.exit(f"style_following: {a.config} has no SUMO demonstrator")
    road = load_road(scenario=cfg.scenario.name)
    reward = load_reward("PACNN+S", a.runs, n_policies=cfg.planner.n_policies)
    bias = lane_change_bias(reward, a.calibrate_on)
    print(f"PACNN+S of {a.runs}: the expected choice, lane-change bias {bias:.3f}", flush=True)
    got = {"the learned reward": Following(), "its SUMO driver": Following()}
    for i in range(a.episodes):
        seed = a.seed + i
        seed_everything(seed)
        decider = RewardDriver(reward, road, cfg.planner, False, None, "expected", bias, True, True)
        lane_change_duration = cfg.demonstrator.lane_change_duration  # as irlsim drive: the driver's traffic
        with Simulation(road, cfg.scenario, lane_change_duration=lane_change_duration) as sim:
            EpisodeRunner(sim, observers=[got["the learned reward"]], max_cycles=a.cycles).run(decider, seed)
        seed_everything(seed)
        driver = SumoDemonstrator(road, cfg.planner, cfg.scenario)
        with demonstrator_simulation(road, cfg.scenario, cfg.demonstrator) as sim:
            EpisodeRunner(sim, observers=[got["its SUMO driver"]], max_cycles=a.cycles).run(driver, seed)
        print(f"episode {i} (seed {seed}) driven by both", flush=True)
    print(
        "| driving | following [s] | headway median [s] | closing: share (headway median) "
        "| keeping pace | falling back | ego / leader speed median [m/s] |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, f in got.items():
        print(summary(name, f.rows, cfg.scenario.step))
    return 0


if __name__ == "__main__":
    sys.exit(main())
