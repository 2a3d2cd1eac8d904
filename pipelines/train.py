"""``irlsim train``: stage 1 (LIRL, 1DCNN, Bi1DCNN, PACNN, PACNN+S) or stage 2 (PTACNN, PTACNN+S).

Each stage has its own config (``configs/train/stage1.toml``, ``stage2.toml``) and its own output folder
inside the runs folder ``--out RUNS``: stage 1 writes ``RUNS/stage1/<model>/``, stage 2 writes
``RUNS/stage2/<model>/`` and reads its frozen PACNN / PACNN+S from ``--base`` (default ``RUNS/stage1``).
Each model folder holds ``checkpoint.pt`` (atomic, resumable), ``metrics.csv`` and ``tensorboard/``;
``RUNS/stage<N>/summary.json`` records the config, the data and each model's summary.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, cast

from irlsim import devices
from irlsim.config import load_config, parse_overrides, to_dict
from irlsim.data.aggregate import open_datasets
from irlsim.errors import IrlsimError
from irlsim.models.registry import STAGE1_MODELS, STAGE2_BASE, format_parameters
from irlsim.outputs import check_output_dir
from irlsim.train import config as tc
from irlsim.train.checkpoint import dataset_identity
from irlsim.train.layout import SUMMARY_NAME, find_checkpoint, stage_dir
from irlsim.train.preflight import check_trainable
from irlsim.train.stage1 import train_stage1
from irlsim.train.stage2 import train_stage2
from irlsim.utils import LockBusy, exclusive_lock, write_json

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
    devices.add_arguments(p, "training")


#: the lock file of a runs folder while 'irlsim train' writes it (as collect's in a dataset folder)
LOCK_NAME = ".lock"
#: [bytes] disk a model's folder may take (checkpoint with latest + best weights and optimizer state,
#: metrics.csv): an upper estimate for the default sizes (PACNN's checkpoint is ~1 MB)
CHECKPOINT_BYTES = 16 << 20


def _stage_models(stage: int) -> tuple[str, ...]:
    return STAGE1_MODELS if stage == 1 else tuple(STAGE2_BASE)


def parameter_lines(summary: dict[str, dict[str, Any]]) -> list[str]:
    """One line per trained model: its trainable parameters (and the frozen base's, for stage 2)."""

    lines = []
    for name, s in summary.items():
        n = int(s["parameters"])
        line = f"  {name:<9} {format_parameters(n):>8} trainable parameters ({n:,})"
        if "base_parameters" in s:
            line += f" on a frozen base of {format_parameters(int(s['base_parameters']))}"
        lines.append(line + f", selected epoch {s['selected_epoch'] or s['epochs']} of {s['epochs']}")
    return lines


def run(args: argparse.Namespace) -> int:
    device = devices.resolve_device(args.device)  # a missing device is one line, before any work
    with devices.use(device, args.precision):
        return _run(args)


def _run(args: argparse.Namespace) -> int:

    if args.base is not None and args.stage != 2:
        raise IrlsimError("--base names the stage-1 folder stage 2 builds on: use it only with --stage 2")
    overrides = parse_overrides(args.set)
    cfg = load_config(tc.Stage1Config if args.stage == 1 else tc.Stage2Config, args.config, overrides)
    base = args.base if args.base is not None else stage_dir(args.out, 1)
    if args.stage == 2 and not base.is_dir():
        hint = "pass --base" if args.base is not None else f"run 'irlsim train --stage 1 --out {args.out}'"
        raise IrlsimError(f"stage 2 needs the stage-1 folder {base}, which does not exist: {hint} first")
    dataset = open_datasets(args.data)
    check_trainable(dataset, cfg)  # empty splits, sizes beyond the memory: before anything is written
    check_output_dir(args.out, "--out", CHECKPOINT_BYTES * len(cfg.models))
    out = stage_dir(args.out, args.stage)
    try:  # one training at a time per runs folder (both stages: stage 2 reads stage 1's checkpoints)
        with exclusive_lock(args.out / LOCK_NAME):
            out.mkdir(parents=True, exist_ok=True)
            if args.stage == 1:
                summary = train_stage1(dataset, cast(tc.Stage1Config, cfg), out)
                extra: dict[str, Any] = {}
            else:
                summary = train_stage2(dataset, cast(tc.Stage2Config, cfg), out, base)
                extra = {"base": str(base)}
            # models trained into this stage folder earlier and not by this call stay as they were: named
            # here, so summary.json does not pass for the whole folder
            others = [m for m in _stage_models(args.stage) if m not in summary and find_checkpoint(out, m)]
            if others:
                extra["other_models"] = others
            write_json(
                out / SUMMARY_NAME,
                {
                    "config": to_dict(cfg),
                    "data": str(args.data[0]) if len(args.data) == 1 else [str(p) for p in args.data],
                    "dataset": dataset_identity(dataset),
                    **extra,
                    "models": summary,
                },
            )
    except LockBusy as busy:
        raise IrlsimError(
            f"another 'irlsim train' is writing {args.out} (pid {busy.holder}): wait for it, or train into "
            "another --out"
        ) from None
    print(f"stage {args.stage}: trained {', '.join(summary)}; checkpoints and metrics in {out}/<model>/")
    print("\n".join(parameter_lines(summary)))
    return 0
