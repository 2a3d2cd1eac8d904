"""``irlsim demo`` (``make demo``): the whole chain on the small default configuration.

net -> collect (configs/collect/default.toml) -> train stage 1 -> train stage 2 -> evaluate -> drive.
Each step is the same command a user would type (printed before it runs); finished steps resume.
``--preset tiny`` runs the same chain on the smoke configs (configs/collect/tiny.toml,
configs/train/tiny_stage*.toml) with short drives: a check that every stage connects, in about a minute.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from irlsim.config import int_in
from irlsim.models.registry import STAGE1_MODELS, STAGE2_BASE
from pipelines.commands import main

HELP = "run the whole chain on the default config: net, collect, train (2 stages), evaluate, drive"

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, default=Path("data/default"), help="dataset folder")
    p.add_argument("--runs", type=Path, default=Path("runs/default"), help="runs folder")
    p.add_argument("--seed", type=int_in(0, 2147), default=0, help="base seed of collection and driving")
    p.add_argument(
        "--preset",
        default="default",
        choices=("default", "tiny"),
        help="config preset: default (~7 min on 2 cores) or tiny (a smoke run of the chain, ~1 min)",
    )
    p.add_argument("--skip-drive", action="store_true", help="stop after the evaluation")


#: who drives in the demo's closed loop: the demonstrator, its theta alone (argmax V, no selection), the
#: linear IRL baseline, and the attention models
DRIVE_MODELS = ("expert", "expert-theta", "LIRL", "PACNN+S", "PTACNN+S")


def steps(args: argparse.Namespace) -> list[list[str]]:
    preset = args.preset
    data, runs = str(args.data), str(args.runs)
    # tiny: a few planning cycles per model are enough to show that the checkpoints drive
    drive_args = (
        ["--episodes", "1", "--laps", "1", "--max-cycles", "30", "--frames", "3"]
        if preset == "tiny"
        else ["--episodes", "3", "--laps", "1"]
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
            ",".join(DRIVE_MODELS),
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


def outputs(args: argparse.Namespace) -> list[tuple[str, list[str]]]:
    """What the demo leaves behind, as printed at its end: (label, paths), a path's ``{a,b}`` standing
    for one path per name (shell brace notation). Every path exists after a successful run."""

    d, r = args.data, args.runs
    s1, s2 = ",".join(STAGE1_MODELS), ",".join(STAGE2_BASE)
    out = [
        ("dataset", [f"{d}/manifest.json"]),
        ("stage 1", [f"{r}/stage1/{{{s1}}}/{{checkpoint.pt,metrics.csv}}", f"{r}/stage1/summary.json"]),
        ("stage 2", [f"{r}/stage2/{{{s2}}}/{{checkpoint.pt,metrics.csv}}", f"{r}/stage2/summary.json"]),
        ("Table I", [f"{r}/eval/results.{{md,json}}", f"{r}/eval/{{convergence,opd_distribution}}.png"]),
    ]
    if not args.skip_drive:
        drivers = "{" + ",".join(DRIVE_MODELS) + "}"
        out += [
            ("closed loop", [f"{r}/drive/drive.{{md,json}}", f"{r}/drive/{drivers}/episode.gif"]),
            ("with --safety", [f"{r}/drive_safety/drive.{{md,json}}"]),
        ]
    return out


def expand(pattern: str) -> list[Path]:
    """'a/{x,y}/b.{md,json}' -> [a/x/b.md, a/x/b.json, a/y/b.md, a/y/b.json]."""
    head, brace, rest = pattern.partition("{")
    if not brace:
        return [Path(pattern)]
    options, _, tail = rest.partition("}")
    return [p for o in options.split(",") for p in expand(head + o + tail)]


def run(args: argparse.Namespace) -> int:

    t0 = time.perf_counter()
    for cmd in steps(args):
        print(f"\n$ irlsim {' '.join(cmd)}", flush=True)
        t_step = time.perf_counter()
        rc = main(cmd)
        if rc != 0:
            print(f"demo: step 'irlsim {cmd[0]}' failed (exit {rc}); fix it and re-run 'make demo' to resume")
            return rc
        print(f"(irlsim {cmd[0]}: {time.perf_counter() - t_step:.0f} s)", flush=True)
    print(f"\ndemo finished in {time.perf_counter() - t0:.0f} s. Outputs:")
    for label, paths in outputs(args):
        print(f"  {label:<15} {', '.join(paths)}")
    missing = [str(p) for _, paths in outputs(args) for pat in paths for p in expand(pat) if not p.exists()]
    if missing:  # a stage that exits 0 without writing its output is a bug, not a user error
        print(f"demo: expected outputs missing: {', '.join(missing)}")
        return 1
    print(
        f"inspect the data with: irlsim data info {args.data}; pictures of each drive in {args.runs}/drive/"
    )
    return 0
