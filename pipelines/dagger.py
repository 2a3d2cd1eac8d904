"""``irlsim dagger``: N rounds of DAgger (drive -> label -> aggregate -> retrain) on top of a trained model.

The arguments become an :class:`irlsim.workflows.dagger.DaggerRun` (config:
:class:`irlsim.workflows.dagger.DaggerConfig`, ``configs/dagger/*.toml``);
:func:`irlsim.workflows.dagger.run_dagger` runs the rounds into ``OUT/round_<r>/{data,runs}`` (its module
docstring). Exits 1 when a round's collection left failed episodes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from irlsim.config import load_config, parse_overrides
from irlsim.workflows.dagger import DaggerConfig, DaggerRun, run_dagger

HELP = "DAgger: rounds of (learned driver drives, expert labels) -> aggregate -> retrain"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, default=None, help="TOML config (configs/dagger/*.toml)")
    p.add_argument(
        "--data",
        type=Path,
        nargs="+",
        action="extend",
        required=True,
        help="the expert's dataset the --runs model was trained on; several: the aggregate it was trained "
        "on, in the same order (the collect config is the first one's)",
    )
    p.add_argument("--runs", type=Path, required=True, help="runs folder of the model trained on --data")
    p.add_argument("--out", type=Path, required=True, help="DAgger folder: OUT/round_<r>/{data,runs}")
    p.add_argument("--rounds", type=int, default=None, help="rounds (overrides the config)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a config field, repeatable")
    p.add_argument(
        "--scenario",
        default=None,
        help="the road the learner drives (a shipped scenario or a scenario.toml path; default: the collect "
        "config's); DAgger on a road the reward was not trained on makes its data in-domain",
    )


def run(args: argparse.Namespace) -> int:
    overrides = parse_overrides(args.set)
    if args.rounds is not None:
        overrides["rounds"] = args.rounds
    if args.scenario is not None:
        overrides["scenario"] = str(args.scenario)
    cfg = load_config(DaggerConfig, args.config, overrides)
    return run_dagger(DaggerRun(cfg, args.data[0], args.runs, args.out, tuple(args.data[1:])))
