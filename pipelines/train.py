"""``irlsim train``: stage 1 (LIRL, 1DCNN, Bi1DCNN, PACNN, PACNN+S) or stage 2 (PTACNN, PTACNN+S).

Each stage has its own config (``configs/train/stage1.toml``, ``stage2.toml``) and writes one folder per
model under ``--out``: ``checkpoint.pt`` (atomic, resumable), ``metrics.csv`` and ``tensorboard/``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "train the reward models: --stage 1 (PACNN & baselines) or --stage 2 (PTACNN on frozen PACNN)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--stage", type=int, choices=(1, 2), required=True, help="1: per-cycle models, 2: temporal"
    )
    p.add_argument("--config", type=Path, default=None, help="TOML config (default: built-in defaults)")
    p.add_argument("--data", type=Path, required=True, help="dataset folder written by 'irlsim collect'")
    p.add_argument("--out", type=Path, required=True, help="runs folder (one sub-folder per model)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a config field, repeatable")


def run(args: argparse.Namespace) -> int:
    from irlsim.config import load_config, parse_overrides, to_dict
    from irlsim.data.reader import open_dataset
    from irlsim.train import config as tc
    from irlsim.train.stage1 import train_stage1
    from irlsim.train.stage2 import train_stage2
    from irlsim.utils import write_json

    overrides = parse_overrides(args.set)
    dataset = open_dataset(args.data)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.stage == 1:
        cfg1 = load_config(tc.Stage1Config, args.config, overrides)
        summary = train_stage1(dataset, cfg1, args.out)
        cfg_dict = to_dict(cfg1)
    else:
        cfg2 = load_config(tc.Stage2Config, args.config, overrides)
        summary = train_stage2(dataset, cfg2, args.out)
        cfg_dict = to_dict(cfg2)
    write_json(
        args.out / f"stage{args.stage}.json", {"config": cfg_dict, "data": str(args.data), "models": summary}
    )
    print(f"stage {args.stage}: trained {', '.join(summary)}; checkpoints and metrics in {args.out}/<model>/")
    return 0
