"""``irlsim dagger``: N rounds of DAgger (drive -> label -> aggregate -> retrain) on top of a trained model.

Round r (1..N), into ``OUT/round_<r>/``:

1. **drive + label**: ``irlsim collect --driver <model> --round r`` into ``OUT/round_<r>/data``: the model
   of the previous round (round 1: the one in ``--runs``, trained on ``--data``) drives, the expert labels
   every cycle (``demo_source`` 'expert'); seeds in round r's window, disjoint from ``--data``'s;
2. **aggregate**: the folders stay as they are: training reads ``--data`` and every round's data folder so
   far (``irlsim train --data D R1 .. Rr``, :mod:`irlsim.data.aggregate`: their splits concatenated into a
   memory-mapped cache in ``--data``'s ``.cache``);
3. **retrain** from scratch: ``irlsim train --stage 1`` (and ``--stage 2`` for a temporal driver) into
   ``OUT/round_<r>/runs``.

Each step is the same command a user would type (printed before it runs) and resumes like it; a round
is finished once ``OUT/round_<r>/round.json`` exists and is then skipped. Config:
:class:`DaggerConfig` (``configs/dagger/*.toml``).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim.config import load_config, parse_overrides, require
from irlsim.errors import IrlsimError
from irlsim.models.registry import MODEL_NAMES, STAGE2_BASE
from irlsim.train.layout import find_checkpoint, stage_dir
from irlsim.utils import write_json
from pipelines.commands import main

HELP = "DAgger: rounds of (learned driver drives, expert labels) -> aggregate -> retrain"

#: written last in a round's folder: the round is finished (skipped when the command runs again)
ROUND_DONE = "round.json"


@dataclass(frozen=True)
class DaggerConfig:
    """``irlsim dagger`` (``configs/dagger/*.toml``)."""

    rounds: int = 2
    """DAgger rounds"""
    model: str = "PACNN+S"
    """the learned driver of every round (a stage-2 model also retrains its stage-1 base)"""
    episodes: int = 4
    """learner-driven, expert-labelled train episodes per round"""
    validation_episodes: int = 0
    """learner-driven validation episodes per round (0: model choices stay on --data's validation split)"""
    workers: int = 2
    """collection worker processes"""
    collect_config: str = "configs/collect/default.toml"
    """the collect config of --data (its planner, scenario and base seed; episode counts are replaced)"""
    stage1_config: str = "configs/train/stage1.toml"
    """stage-1 training config (only the driver's stage-1 model is trained)"""
    stage2_config: str = "configs/train/stage2.toml"
    """stage-2 training config (used when ``model`` is a stage-2 model)"""

    def validate(self) -> None:
        require(1 <= self.rounds <= 23, f"rounds must be in 1..23, got {self.rounds}")
        require(
            self.model in MODEL_NAMES, f"model must be one of {', '.join(MODEL_NAMES)}, got {self.model!r}"
        )
        require(1 <= self.episodes <= 10_000, f"episodes must be in 1..10000, got {self.episodes}")
        require(
            0 <= self.validation_episodes <= 10_000,
            f"validation_episodes must be in 0..10000, got {self.validation_episodes}",
        )
        require(self.workers >= 1, f"workers must be >= 1, got {self.workers}")

    @property
    def stage1_model(self) -> str:
        return STAGE2_BASE.get(self.model, self.model)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, default=None, help="TOML config (configs/dagger/*.toml)")
    p.add_argument(
        "--data", type=Path, required=True, help="the expert's dataset the --runs model was trained on"
    )
    p.add_argument("--runs", type=Path, required=True, help="runs folder of the model trained on --data")
    p.add_argument("--out", type=Path, required=True, help="DAgger folder: OUT/round_<r>/{data,runs}")
    p.add_argument("--rounds", type=int, default=None, help="rounds (overrides the config)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a config field, repeatable")


def round_dir(out: Path, r: int) -> Path:
    return out / f"round_{r}"


def round_commands(cfg: DaggerConfig, args: argparse.Namespace, r: int) -> list[list[str]]:
    """The commands of round r: collect (driver from round r - 1), then the training stages."""
    prev_runs = args.runs if r == 1 else round_dir(args.out, r - 1) / "runs"
    here = round_dir(args.out, r)
    data = [str(args.data), *(str(round_dir(args.out, k) / "data") for k in range(1, r + 1))]
    cmds = [
        [
            "collect",
            "--config",
            cfg.collect_config,
            "--out",
            str(here / "data"),
            "--workers",
            str(cfg.workers),
        ]
        + ["--driver", cfg.model, "--runs", str(prev_runs), "--round", str(r)]
        + [
            "--set",
            f"train_episodes={cfg.episodes}",
            "--set",
            f"validation_episodes={cfg.validation_episodes}",
        ]
        + ["--set", "test_episodes=0"],
        ["train", "--stage", "1", "--config", cfg.stage1_config, "--data", *data, "--out", str(here / "runs")]
        + ["--set", f"models=['{cfg.stage1_model}']"],
    ]
    if cfg.model in STAGE2_BASE:
        cmds.append(
            [
                "train",
                "--stage",
                "2",
                "--config",
                cfg.stage2_config,
                "--data",
                *data,
                "--out",
                str(here / "runs"),
            ]
            + ["--set", f"models=['{cfg.model}']"]
        )
    return cmds


def run(args: argparse.Namespace) -> int:
    overrides = parse_overrides(args.set)
    if args.rounds is not None:
        overrides["rounds"] = args.rounds
    cfg = load_config(DaggerConfig, args.config, overrides)
    for name in ("collect_config", "stage1_config", "stage2_config"):
        if not Path(getattr(cfg, name)).is_file():
            raise IrlsimError(f"config: {name} {getattr(cfg, name)} not found: pass an existing TOML file")
    if find_checkpoint(args.runs, cfg.model) is None:
        raise IrlsimError(
            f"{cfg.model} has no checkpoint in {args.runs}: train it on {args.data} first ('irlsim train "
            f"--data {args.data} --out {args.runs}'), or set model to a trained one"
        )
    if args.out.exists() and not args.out.is_dir():
        raise IrlsimError(f"--out {args.out} is a file: choose a folder for the DAgger rounds")
    for r in range(1, cfg.rounds + 1):
        here = round_dir(args.out, r)
        if (here / ROUND_DONE).is_file():
            print(f"dagger: round {r} finished before: {here}/data, {here}/runs (skipped)", flush=True)
            continue
        t0 = time.perf_counter()
        cmds = round_commands(cfg, args, r)
        for cmd in cmds:
            print(f"\n$ irlsim {' '.join(cmd)}", flush=True)
            rc = main(cmd)
            if rc != 0:
                print(f"dagger: round {r} step 'irlsim {cmd[0]}' failed (exit {rc}); re-run to resume")
                return rc
        record: dict[str, Any] = {
            "round": r,
            "model": cfg.model,
            "data": str(here / "data"),
            "runs": str(here / "runs"),
            "driver_runs": str(args.runs if r == 1 else round_dir(args.out, r - 1) / "runs"),
            "trained_on": [str(args.data), *(str(round_dir(args.out, k) / "data") for k in range(1, r + 1))],
            "commands": [["irlsim", *c] for c in cmds],
            "wall_s": round(time.perf_counter() - t0, 1),
        }
        write_json(here / ROUND_DONE, record)
        print(
            f"dagger: round {r} wrote {here}/data (expert-labelled) and {here}/runs ({cfg.model})", flush=True
        )
    last = round_dir(args.out, cfg.rounds) / "runs"
    final = stage_dir(last, 2 if cfg.model in STAGE2_BASE else 1) / cfg.model
    print(f"dagger: {cfg.rounds} round(s) in {args.out}; the last round's {cfg.model}: {final}")
    return 0
