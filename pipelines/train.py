"""``irlsim train``: stage 1 (LIRL, 1DCNN, Bi1DCNN, PACNN, PACNN+S) or stage 2 (PTACNN, PTACNN+S).

The arguments become a :class:`irlsim.workflows.train.TrainRun`; :func:`irlsim.workflows.train.train_models`
trains into ``--out RUNS`` (``RUNS/stage<N>/<model>/``, ``summary.json``; its module docstring).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from irlsim import devices
from irlsim.config import load_config, parse_overrides
from irlsim.data.roads import parse_selection
from irlsim.errors import IrlsimError
from irlsim.train import config as tc
from irlsim.workflows.train import TrainRun, train_models

HELP = "train the reward models: --stage 1 (PACNN & baselines) or --stage 2 (PTACNN on frozen PACNN)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--stage", type=int, choices=(1, 2), required=True, help="1: per-cycle models, 2: temporal"
    )
    p.add_argument("--config", type=Path, default=None, help="TOML config (default: built-in defaults)")
    p.add_argument(
        "--data",
        type=Path,
        nargs="+",
        action="extend",
        required=True,
        help="dataset folder written by 'irlsim collect'; several folders are aggregated (DAgger: the "
        "expert's data and the rounds' expert-labelled data; irlsim.data.aggregate)",
    )
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        help="runs folder: stage N writes OUT/stage<N>/<model>/ (checkpoint.pt, metrics.csv)",
    )
    p.add_argument(
        "--base",
        type=Path,
        default=None,
        help="stage 2 only: folder with the frozen stage-1 PACNN/ and PACNN+S/ (default: OUT/stage1)",
    )
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a config field, repeatable")
    p.add_argument(
        "--scenario-select",
        default=None,
        metavar="A,B",
        help="train on the episodes of these scenarios only (a dataset over several scenarios; the "
        "checkpoint records the selection: resuming needs the same one)",
    )
    p.add_argument(
        "--demonstrator-select",
        default=None,
        metavar="A,B",
        help="train on the folders of these demonstrators only (identities as irlsim data info "
        "names them, e.g. expert, or a kind: expert, sumo, recording; the checkpoint records the "
        "selection)",
    )
    devices.add_arguments(p, "training")


def request(args: argparse.Namespace) -> TrainRun:
    """The parsed arguments as the library's request (one-line errors for arguments that do not fit)."""
    if args.base is not None and args.stage != 2:
        raise IrlsimError("--base names the stage-1 folder stage 2 builds on: use it only with --stage 2")
    overrides = parse_overrides(args.set)
    cfg: tc.Stage1Config | tc.Stage2Config
    if args.stage == 1:
        cfg = load_config(tc.Stage1Config, args.config, overrides)
    else:
        cfg = load_config(tc.Stage2Config, args.config, overrides)
    scenarios = parse_selection(args.scenario_select)
    who = parse_selection(args.demonstrator_select, "--demonstrator-select", "demonstrators")
    return TrainRun(cfg, tuple(args.data), args.out, args.base, args.device, args.precision, scenarios, who)


def run(args: argparse.Namespace) -> int:
    devices.resolve(args.device, args.precision)  # a missing device or precision: one line, before any work
    train_models(request(args))
    return 0
