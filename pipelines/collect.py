"""``irlsim collect``: drive the expert in SUMO and write a Parquet dataset of policy sets and demonstrations.

The arguments become a :class:`irlsim.workflows.collect.CollectRun` and
:func:`irlsim.workflows.collect.collect_dataset` does the work (workers, resume, failure handling: its
module docstring); the command exits 1 when an episode failed twice.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from irlsim.config import MAX_SEED, float_in, int_in, load_config, parse_overrides
from irlsim.data.collection import CollectConfig
from irlsim.errors import IrlsimError
from irlsim.road.scenario import Scenarios
from irlsim.utils import check_non_negative
from irlsim.workflows.collect import EPISODE_SIM_FACTOR, EPISODE_START_S, CollectRun, collect_dataset

HELP = "drive the expert and record policy sets + demonstrations to a Parquet dataset"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, default=None, help="TOML config (configs/collect/*.toml)")
    p.add_argument("--out", type=Path, required=True, help="dataset folder, e.g. data/default")
    p.add_argument(
        "--workers", type=int_in(1, 256), default=None, help="worker processes (overrides the config)"
    )
    p.add_argument("--seed", type=int_in(0, MAX_SEED), default=None, help="base seed (overrides the config)")
    add_executor_arguments(p)
    p.add_argument(
        "--driver",
        default=None,
        metavar="MODEL|CHECKPOINT",
        help="DAgger: this learned reward drives (a model name found in --runs, or a checkpoint path; "
        "argmax of its reward, as 'irlsim drive' without --safety) and the expert labels every cycle with "
        "its own choice on the same policy set (demo_source 'expert'); with a [demonstrator] kind = 'sumo' "
        "SUMO's driver labels instead, from the cycle's state over the horizon (a look ahead, its odometry "
        "projected: demo_source 'odometry'); default: the expert drives",
    )
    p.add_argument("--runs", type=Path, default=None, help="with --driver MODEL: the runs folder holding it")
    p.add_argument(
        "--round",
        type=int,
        default=None,
        help="with --driver: the DAgger round r >= 1 (default 1); its episode seeds are seed * 1e6 + "
        "300,000 + 30,000 (r - 1) + 10,000 x split index + i, disjoint from every expert dataset's",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a config field, e.g. --set planner.n_policies=500 (repeatable)",
    )
    p.add_argument(
        "--scenario",
        default=None,
        help="the road: a shipped scenario (irlsim scenario list) or a scenario.toml path (default: the "
        "config's [scenario] name, the oval)",
    )


def add_executor_arguments(p: argparse.ArgumentParser) -> None:
    """``--executor``, ``--address`` and ``--episode-timeout`` (collect and drive)."""
    p.add_argument(
        "--executor",
        choices=("local", "ray"),
        default="local",
        help="where episodes run: 'local' spawned worker processes (default) or 'ray' tasks (needs the "
        "ray extra: pip install -e '.[ray]'); the outputs are the same bytes either way",
    )
    p.add_argument(
        "--address",
        default=None,
        help="with --executor ray: 'auto' or host:port joins a running Ray cluster (default: start a "
        "local Ray of --workers CPUs); every node must be able to write --out (a shared folder)",
    )
    p.add_argument(
        "--episode-timeout",
        type=float_in(0, above=True),
        default=None,
        metavar="SECONDS",
        help="wall-clock limit of one episode in a worker process (> 0): a worker that has not returned "
        "by then (stopped, deadlocked) is killed and the episode tried once more, then listed as failed "
        f"(exit 1) like a dead worker's. Default: {EPISODE_START_S:g} s + {EPISODE_SIM_FACTOR:g} x the "
        "episode's simulated time limit (scenario.max_time, or max_cycles x scenario.cycle when shorter: "
        "920 s for configs/collect/default.toml); with Ray counted from the task's submission. The local "
        "executor's --workers 1 runs in this process, which cannot be timed out: there a limit applies "
        "only when given, and then the episodes run in one worker process",
    )


#: the config keys options set, as a bad value's line names them (other overrides are --set KEY)
OPTION_KEYS = {
    "workers": "--workers",
    "seed": "--seed",
    "dagger_round": "--round",
    "scenario.name": "--scenario",
}


def request(args: argparse.Namespace) -> CollectRun:
    """The parsed arguments as the library's request (one-line errors for arguments that do not fit)."""
    overrides = parse_overrides(args.set)
    if args.workers is not None:
        if args.workers < 1:
            raise IrlsimError(f"--workers must be >= 1, got {args.workers}")
        overrides["workers"] = args.workers
    if args.seed is not None:
        check_non_negative("seed", args.seed)
        overrides["seed"] = args.seed
    if args.driver is None and (args.round is not None or args.runs is not None):
        raise IrlsimError("--round and --runs belong to a DAgger collection: add --driver MODEL|CHECKPOINT")
    if args.driver is not None:
        if args.round is not None and args.round < 1:
            raise IrlsimError(f"--round must be >= 1 (the DAgger round), got {args.round}")
        overrides["dagger_round"] = args.round if args.round is not None else 1
    if args.scenario is not None:
        overrides["scenario.name"] = str(args.scenario)
    scenarios = Scenarios()  # each road's file read once: for the config's [defaults] and the episodes
    cfg = load_config(CollectConfig, args.config, overrides, OPTION_KEYS, scenarios)
    return CollectRun(
        cfg, args.out, args.executor, args.address, args.episode_timeout, args.driver, args.runs, scenarios
    )


def run(args: argparse.Namespace) -> int:
    return 0 if collect_dataset(request(args)).ok else 1
