"""``irlsim sim``: headless SUMO episodes on the oval with a built-in driver; figures as JSON.

Per episode: laps, collisions, exits, stop lines passed / compliant, checkpoints passed / in the required
lane, mean speed, teleports, background traffic figures (``sim/bg_stuck``: vehicles that stood still
over 10 s outside a stop-line queue), timing; plus a summary over episodes. Timing: ``sim/steps_per_s``
is simulation steps per second of the simulator's own work (SUMO, reading and projecting the vehicles,
traffic upkeep, bookkeeping; without the driver), ``sim/sumo_steps_per_s`` the same for SUMO's step
alone, ``sim/plan_ms_mean`` the driver's mean planning time per cycle.
Episode i uses seed ``--seed + i``. The JSON is written atomically once all episodes are done.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from irlsim.config import float_in, int_in, load_config, to_dict
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.scenario import Scenarios
from irlsim.rollout import EpisodeRunner, make_driver
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import MAX_SEED, Simulation
from irlsim.utils import check_non_negative, check_output_file, write_json

HELP = "run headless SUMO episodes with a simple driver and report per-episode figures"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--episodes", type=int_in(1), default=1, help="number of episodes (>= 1)")
    parser.add_argument(
        "--seed",
        type=int_in(0, MAX_SEED),
        default=0,
        help="seed of the first episode (>= 0); episode i uses seed + i",
    )
    parser.add_argument(
        "--laps", type=int_in(1), default=None, help="laps per episode (default: the config's, 2)"
    )
    parser.add_argument(
        "--vehicles", type=int_in(0, 15), default=None, help="background vehicles, 0..15 (default 15)"
    )
    parser.add_argument(
        "--max-time", type=float_in(0), default=None, help="time-out per episode [s] (default 600)"
    )
    parser.add_argument(
        "--driver", default="simple", help="driver name (registered in irlsim.rollout.drivers.DRIVERS)"
    )
    parser.add_argument(
        "--config", type=Path, default=None, help="TOML with EpisodeConfig fields (see irlsim/sim/config.py)"
    )
    parser.add_argument(
        "--scenario",
        default=None,
        help="scenario: a shipped name (oval, motorway, ...) or the path of a scenario.toml (default oval)",
    )
    parser.add_argument(
        "--net",
        type=Path,
        default=None,
        help="the oval on this SUMO network file (default: built from sumo_net/oval/)",
    )
    parser.add_argument("--json", type=Path, default=None, help="write the figures to this JSON file")
    parser.add_argument(
        "--gui", action="store_true", help="watch in sumo-gui (needs a display; traci, slower)"
    )


def _scenario(args: argparse.Namespace, scenarios: Scenarios) -> EpisodeConfig:

    overrides: dict[str, Any] = {}
    if args.laps is not None:
        overrides["laps"] = args.laps
    if args.vehicles is not None:
        overrides["n_vehicles"] = args.vehicles
    if args.max_time is not None:
        overrides["max_time"] = args.max_time
    if args.scenario is not None:
        overrides["name"] = str(args.scenario)
    return load_config(EpisodeConfig, args.config, overrides, scenarios=scenarios)


def run(args: argparse.Namespace) -> int:

    # validate everything before any work, so a bad option never leaves a partial result
    if args.episodes < 1:
        raise IrlsimError(f"--episodes must be >= 1, got {args.episodes}")
    check_non_negative("seed", args.seed)
    if args.seed + args.episodes - 1 > MAX_SEED:
        raise IrlsimError(
            f"--seed + --episodes - 1 = {args.seed + args.episodes - 1} exceeds {MAX_SEED}, the largest "
            "SUMO seed: choose a smaller --seed"
        )
    if args.laps is not None and args.laps < 1:
        raise IrlsimError(f"--laps must be >= 1, got {args.laps}")
    if args.vehicles is not None and not 0 <= args.vehicles <= 15:
        raise IrlsimError(f"--vehicles must be in 0..15, got {args.vehicles}")
    if args.max_time is not None and args.max_time <= 0:
        raise IrlsimError(f"--max-time must be > 0 s, got {args.max_time}")
    if args.json is not None:
        check_output_file(args.json, "--json", "sim.json")
    scenarios = Scenarios()  # the road's file read once: for the config's [defaults] and the road
    cfg = _scenario(args, scenarios)
    road = load_road(args.net) if args.net is not None else load_road(scenario=scenarios(cfg.name))
    driver = make_driver(args.driver, road, cfg)

    episodes: list[dict[str, Any]] = []
    t_start = time.perf_counter()
    with Simulation(road, cfg, gui=args.gui) as sim:
        runner = EpisodeRunner(sim)
        for i in range(args.episodes):
            ended = runner.run(driver, args.seed + i)
            stats = dict(ended.stats)
            stats["sim/plan_ms_mean"] = round(
                1e3 * ended.decide_s / max(1, len(sim.odometry) // cfg.steps_per_cycle), 3
            )
            episodes.append({"episode": i, **stats, "events": sim.episode.events if sim.episode else []})
            _print_row(i, stats)
    summary = _summary(episodes)
    summary["wall_s"] = round(time.perf_counter() - t_start, 2)
    result = {
        "driver": args.driver,
        "seed": args.seed,
        "net": str(road.net_file),
        "config": to_dict(cfg),
        "summary": summary,
        "episodes": episodes,
    }
    print(
        f"summary: {args.episodes} episode(s), laps {summary['sim/laps']}, "
        f"collisions {summary['sim/collisions']}, "
        f"stop lines {summary['sim/stop_lines_compliant']}/{summary['sim/stop_lines_passed']}, "
        f"stuck vehicles {summary['sim/bg_stuck']}, "
        f"steps/s {summary['sim/steps_per_s']:.0f} without the driver "
        f"(SUMO alone {summary['sim/sumo_steps_per_s']:.0f}), "
        f"planning {summary['sim/plan_ms_mean']:.2f} ms a cycle"
    )
    if args.json is not None:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    return 0


_COLUMNS = (
    ("ep", "episode", "{:>3}"),
    ("seed", "seed", "{:>5}"),
    ("end", "end_reason", "{:>9}"),
    ("laps", "sim/laps", "{:>4}"),
    ("coll", "sim/collisions", "{:>4}"),
    ("exit", "sim/exits", "{:>4}"),
    ("stops", None, "{:>6}"),
    ("cps", None, "{:>5}"),
    ("km/h", "sim/mean_speed_kmh", "{:>6.1f}"),
    ("tele", "sim/teleports", "{:>4}"),
    ("steps/s", "sim/steps_per_s", "{:>8.0f}"),
)


def _print_row(i: int, st: dict[str, Any]) -> None:
    if i == 0:
        print(" ".join(f"{h:>{len(f.format(0) if 'f' not in f else f.format(0.0))}}" for h, _, f in _COLUMNS))
    vals = []
    for h, key, fmt in _COLUMNS:
        if h == "ep":
            vals.append(fmt.format(i))
        elif h == "stops":
            vals.append(fmt.format(f"{st['sim/stop_lines_compliant']}/{st['sim/stop_lines_passed']}"))
        elif h == "cps":
            vals.append(fmt.format(f"{st['sim/checkpoints_in_lane']}/{st['sim/checkpoints_passed']}"))
        else:
            vals.append(fmt.format(st[str(key)]))
    print(" ".join(vals))


def _summary(episodes: list[dict[str, Any]]) -> dict[str, Any]:
    """Totals of the count figures, means of the rates, and how often each end reason occurred."""
    out: dict[str, Any] = {"episodes": len(episodes)}
    means = ("sim/mean_speed_kmh", "sim/steps_per_s", "sim/sumo_steps_per_s", "sim/plan_ms_mean")
    for key, _value in episodes[0].items():
        if not key.startswith("sim/"):
            continue
        vals = [e[key] for e in episodes]
        total = sum(vals)
        if key in means:
            total = total / len(vals)
        out[key] = round(total, 3) if isinstance(total, float) else total
    reasons: dict[str, int] = {}
    for e in episodes:
        reasons[str(e["end_reason"])] = reasons.get(str(e["end_reason"]), 0) + 1
    out["end_reasons"] = reasons
    return out
