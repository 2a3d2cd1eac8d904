"""``irlsim demo`` (``make demo``): the whole chain on the small default configuration.

net -> collect (configs/collect/default.toml) -> train stage 1 -> train stage 2 -> evaluate -> drive.
Each step is the same command a user would type (printed before it runs); finished steps resume.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

HELP = "run the whole chain on the default config: net, collect, train (2 stages), evaluate, drive"

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, default=Path("data/default"), help="dataset folder")
    p.add_argument("--runs", type=Path, default=Path("runs/default"), help="runs folder")
    p.add_argument("--seed", type=int, default=0, help="base seed of collection and driving")
    p.add_argument(
        "--preset",
        default="default",
        choices=("default", "tiny"),
        help="config preset: default (~15 min here) or tiny (a smoke run of the chain)",
    )
    p.add_argument("--skip-drive", action="store_true", help="stop after the evaluation")


def steps(args: argparse.Namespace) -> list[list[str]]:
    preset = args.preset
    data, runs = str(args.data), str(args.runs)
    drive_args = (
        ["--episodes", "1", "--laps", "1"] if preset == "tiny" else ["--episodes", "2", "--laps", "1"]
    )
    out = [
        ["net"],
        [
            "collect",
            "--config",
            str(CONFIGS / "collect" / f"{preset}.toml"),
            "--out",
            data,
            "--seed",
            str(args.seed),
        ],
        [
            "train",
            "--stage",
            "1",
            "--config",
            str(CONFIGS / "train" / f"{_train(preset)}stage1.toml"),
            "--data",
            data,
            "--out",
            runs,
        ],
        [
            "train",
            "--stage",
            "2",
            "--config",
            str(CONFIGS / "train" / f"{_train(preset)}stage2.toml"),
            "--data",
            data,
            "--out",
            runs,
        ],
        ["evaluate", "--data", data, "--runs", runs, "--out", f"{runs}/eval"],
    ]
    if not args.skip_drive:
        drive = [
            "drive",
            "--runs",
            runs,
            "--model",
            "expert,PACNN+S,PTACNN+S",
            *drive_args,
            "--seed",
            str(100 + args.seed),
            "--config",
            str(CONFIGS / "collect" / f"{preset}.toml"),
        ]
        # as in the paper: the learned reward alone, no model-based collision check ...
        out.append([*drive, "--out", f"{runs}/drive"])
        # ... and with the expert's model-based filter (collision / off-road / exit labels) added
        out.append([*drive, "--safety", "--frames", "0", "--out", f"{runs}/drive_safety"])
    return out


def _train(preset: str) -> str:
    return "tiny_" if preset == "tiny" else ""


def run(args: argparse.Namespace) -> int:
    from irlsim.cli import main

    t0 = time.perf_counter()
    for cmd in steps(args):
        print(f"\n$ irlsim {' '.join(cmd)}", flush=True)
        rc = main(cmd)
        if rc != 0:
            print(f"demo: step 'irlsim {cmd[0]}' failed (exit {rc}); fix it and re-run 'make demo' to resume")
            return rc
    print(f"\ndemo finished in {time.perf_counter() - t0:.0f} s. Outputs:")
    print(f"  dataset          {args.data}/ (irlsim data info {args.data})")
    print(f"  checkpoints      {args.runs}/<model>/checkpoint.pt, metrics.csv")
    print(f"  Table I          {args.runs}/eval/results.md (.json), convergence.png, opd_distribution.png")
    if not args.skip_drive:
        print(
            f"  closed loop      {args.runs}/drive/drive.md (.json), pictures in {args.runs}/drive/<model>/"
        )
        print(f"  with --safety    {args.runs}/drive_safety/drive.md (.json)")
    return 0
