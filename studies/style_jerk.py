r"""Where a SUMO driver's jerk comes from: its single full-deceleration steps with no leader near.

Drives a SUMO demonstrator's collection episodes (the ego driven by SUMO with the demonstrator's type,
as ``irlsim collect`` does) and, every 0.1 s step, reads SUMO's acceleration of the ego, its leader's gap
and its lane-change state to the left. The RMS jerk at the step (finite differences of the speed over
0.1 s, the style's figure until :mod:`irlsim.rollout.style` measured it over 1 s) is split into the
steps within 0.2 s of a step braking at the driver's full ``decel`` with no leader within 50 m
("spikes": single steps a car following model does not take on a free road) and the rest; for the
spikes, how often SUMO reports the change to the left blocked by a leader there (LC2013 slowing the ego
to fall in behind a car in the next lane):

    .venv/bin/python studies/style_jerk.py --config configs/collect/styles/assertive.toml --episodes 5
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.data.demonstrator import SUMO, SumoDemonstrator, demo_vtype, demonstrator_simulation
from irlsim.road import load_road
from irlsim.rollout.runner import EpisodeRunner

DEV_SEED = 2_000_000_000  # the style study's development episodes (studies/styles.py --eval-base 2000)
FREE_GAP = 50.0  # [m] no leader within this: a free road
BLOCKED_BY_LEFT_LEADER = 512  # SUMO's LCA_BLOCKED_BY_LEFT_LEADER


def episode_steps(cfg: CollectConfig, scenario: str, seed: int, max_cycles: int) -> dict[str, np.ndarray]:
    """Every step of one episode: t, v, SUMO's acceleration, the leader's gap, the left change's state."""
    road = load_road(scenario=scenario)
    rows: list[tuple[float, float, float, float, int]] = []

    def on_step(s: Any) -> None:
        api = s._api.vehicle
        if "ego" in api.getIDList():
            lead = api.getLeader("ego", FREE_GAP)
            gap = lead[1] if lead and lead[0] else np.inf
            state = int(api.getLaneChangeState("ego", 1)[0])
            rows.append((s.ego.t, s.ego.v, api.getAcceleration("ego"), gap, state))

    sim = demonstrator_simulation(road, cfg.scenario, cfg.demonstrator)
    sim.step_listeners.append(on_step)
    with sim:
        EpisodeRunner(sim, observers=[], max_cycles=max_cycles).run(
            SumoDemonstrator(road, cfg.planner, cfg.scenario), seed
        )
    cols = np.array(rows, dtype=np.float64).T
    return dict(zip(("t", "v", "a", "gap", "left"), cols, strict=True))


def split_jerk(steps: dict[str, np.ndarray], decel: float) -> dict[str, float]:
    """The RMS jerk, its spikes' share of the jerk energy, the RMS jerk without them, the spikes' count
    and the share of them with the change to the left blocked by a leader."""
    t, v = steps["t"], steps["v"]
    dt = np.diff(t)
    jerk = np.diff(np.diff(v) / dt) / dt[1:]
    spike = (steps["a"] <= -decel + 0.01) & (steps["gap"] > FREE_GAP)
    near = (np.convolve(spike.astype(float), np.ones(5), mode="same") > 0)[2:]
    energy = float((jerk**2).sum())
    blocked = (steps["left"][spike].astype(np.int64) & BLOCKED_BY_LEFT_LEADER) > 0
    return {
        "rms_jerk": float(np.sqrt(np.mean(jerk**2))),
        "spike_share": float((jerk[near] ** 2).sum() / energy) if energy else 0.0,
        "rms_jerk_without": float(np.sqrt(np.mean(jerk[~near] ** 2))) if (~near).any() else 0.0,
        "spikes": int(spike.sum()),
        "blocked_left": float(blocked.mean()) if blocked.size else 0.0,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", required=True, help="a SUMO demonstrator's collect config")
    p.add_argument("--scenario", default="oval", help="the road (default: oval)")
    p.add_argument("--episodes", type=int, default=5, help="development episodes 0..N-1")
    p.add_argument("--max-cycles", type=int, default=800)
    a = p.parse_args(argv)
    if not Path(a.config).is_file():
        sys.exit(f"style_jerk: {a.config} not found: give a SUMO demonstrator's collect config")
    cfg = load_config(CollectConfig, a.config)
    if cfg.demonstrator.kind != SUMO:
        sys.exit(f"style_jerk: {a.config} has no SUMO demonstrator ([demonstrator] kind = 'sumo')")
    if a.episodes < 1:
        sys.exit(f"style_jerk: --episodes must be at least 1, got {a.episodes}")
    decel = float((demo_vtype(cfg.demonstrator, cfg.scenario) or {})["decel"])
    print(f"{a.config} on {a.scenario}: spikes are steps braking at {decel:g} m/s^2, no leader within 50 m")
    for i in range(a.episodes):
        f = split_jerk(episode_steps(cfg, a.scenario, DEV_SEED + i, a.max_cycles), decel)
        print(
            f"episode {i}: RMS jerk {f['rms_jerk']:.2f} m/s^3, {f['spikes']} spikes carrying "
            f"{f['spike_share']:.0%} of its energy (the change to the left blocked by a leader in "
            f"{f['blocked_left']:.0%} of them); without them {f['rms_jerk_without']:.2f} m/s^3"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
