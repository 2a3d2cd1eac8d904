r"""Which recorded cars a reactive replay does not hand to SUMO: per episode of a recording's drive
config, the cars replayed (moved to their recorded poses, blind to the ego) instead of driven by SUMO.

In a reactive drive (``irlsim drive --reactive``) every other car is meant to see and yield to the ego; a
car SUMO cannot take over (its positions on no route of its recorded edges) is replayed instead, and can
run into the ego. Drives the expert on each episode of ``--config`` (a studies/style_recording.py sample's
``drive.toml``, e.g. ``runs/styles/recording-s3/drive.toml``) and prints the cars that were on the
network and not driven by SUMO:

    .venv/bin/python studies/style_replay_blind.py --config runs/styles/recording-s3/drive.toml \
        --episodes 20
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.drive.closed_loop import _simulation
from irlsim.reward import RewardDriver, load_reward
from irlsim.road import load_road
from irlsim.rollout.runner import EpisodeRunner
from irlsim.sim.replay import PREFIX

EVAL_SEED = 1_000_000_000  # studies/styles.py's evaluation base: episode i has seed EVAL_SEED + i


def blind_cars(config: Path, episode: int, max_cycles: int = 800) -> list[str]:
    """The recorded cars of ``episode`` that were on the network and not driven by SUMO."""
    cfg = load_config(CollectConfig, config)
    road, _, sim = _simulation(cfg, load_road(scenario=cfg.scenario.name), 2, episode, True)
    seen: set[str] = set()

    def on_step(s: Any) -> None:
        seen.update(v for v in s._api.vehicle.getIDList() if v.startswith(PREFIX) and v not in s._driven)

    sim.step_listeners.append(on_step)
    driver = RewardDriver(load_reward("expert"), road, cfg.planner)
    with sim:
        EpisodeRunner(sim, observers=[], max_cycles=max_cycles).run(driver, EVAL_SEED + episode)
    return sorted(v.removeprefix(PREFIX) for v in seen)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", required=True, help="a recording sample's drive.toml")
    p.add_argument("--episodes", type=int, default=20, help="episodes 0..N-1 (one held-out car each)")
    a = p.parse_args(argv)
    config = Path(a.config)
    if not config.is_file():
        sys.exit(f"style_replay_blind: {config} not found: run studies/style_recording.py for it first")
    cfg = load_config(CollectConfig, config)
    egos = cfg.demonstrator.ego.split(",") if cfg.demonstrator.kind == "recording" else []
    if not 0 < a.episodes <= len(egos):
        sys.exit(f"style_replay_blind: --episodes must be 1..{len(egos)}, the egos of {config}")
    total = 0
    for ep in range(a.episodes):
        cars = blind_cars(config, ep)
        total += len(cars)
        print(f"episode {ep}: {len(cars)} car(s) replayed blind{': ' + ', '.join(cars) if cars else ''}")
    print(f"{total} car(s) replayed blind in {a.episodes} episodes of {config}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
