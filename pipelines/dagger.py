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
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim.config import MAX_SEED, load_config, parse_overrides, require
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
    episodes: int | list[int] = 4
    """learner-driven, expert-labelled train episodes per round: one count for every round, or a list
    with one count per round (``[6, 20]``; ``--rounds 1`` with it runs round 1 only)"""
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
    stage2_models: list[str] = dataclasses.field(default_factory=list)
    """stage-2 models trained on each round's aggregate beside the driver, on its stage-1 base
    (``["PTACNN+S"]`` next to a PACNN+S driver); they do not drive"""
    epochs: list[int] = dataclasses.field(default_factory=list)
    """stage-1 epochs of each round's retraining, one per round (empty: the stage-1 config's ``epochs``
    in every round)"""
    seed: int | None = None
    """training seed of every round's retraining, stage 1 and 2 (None: the stage configs' ``seed``); the
    learner's episodes keep the collect config's seeds, so two training seeds drive the same scenarios"""

    def validate(self) -> None:
        require(1 <= self.rounds <= 23, f"rounds must be in 1..23, got {self.rounds}")
        require(
            self.model in MODEL_NAMES, f"model must be one of {', '.join(MODEL_NAMES)}, got {self.model!r}"
        )
        counts = self.episodes if isinstance(self.episodes, list) else [self.episodes]
        if isinstance(self.episodes, list):
            require(
                len(self.episodes) >= self.rounds,
                f"episodes has {len(self.episodes)} entries for {self.rounds} round(s): give one count per "
                "round, or a single number for every round",
            )
        for n in counts:
            require(1 <= n <= 10_000, f"episodes must be in 1..10000, got {n}")
        if self.epochs:
            require(
                len(self.epochs) >= self.rounds,
                f"epochs has {len(self.epochs)} entries for {self.rounds} round(s): give one per round, or "
                "leave it empty to use the stage-1 config's epochs",
            )
        for n in self.epochs:
            require(1 <= n <= 100_000, f"epochs must be in 1..100000, got {n}")
        on_base = [k for k, v in STAGE2_BASE.items() if v == self.stage1_model]
        for m in self.stage2_models:
            require(
                m in on_base,
                f"stage2_models entry {m!r} must be a stage-2 model on the driver's stage-1 base "
                f"{self.stage1_model} ({', '.join(on_base) or 'none'})",
            )
        if self.seed is not None:
            require(0 <= self.seed <= MAX_SEED, f"seed must be in 0..{MAX_SEED}, got {self.seed}")
        require(
            0 <= self.validation_episodes <= 10_000,
            f"validation_episodes must be in 0..10000, got {self.validation_episodes}",
        )
        require(self.workers >= 1, f"workers must be >= 1, got {self.workers}")

    @property
    def stage1_model(self) -> str:
        return STAGE2_BASE.get(self.model, self.model)

    @property
    def trained_stage2(self) -> list[str]:
        """The stage-2 models each round trains: the driver if it is one, then ``stage2_models``."""
        first = [self.model] if self.model in STAGE2_BASE else []
        return first + [m for m in self.stage2_models if m not in first]

    def round_episodes(self, r: int) -> int:
        """Learner-driven train episodes of round ``r`` (1-based)."""
        return self.episodes[r - 1] if isinstance(self.episodes, list) else self.episodes

    def round_train_sets(self, r: int, stage: int) -> list[str]:
        """The ``--set`` arguments of round ``r``'s stage-``stage`` training beyond the model name."""
        out = []
        if stage == 1 and self.epochs:
            out += ["--set", f"epochs={self.epochs[r - 1]}"]
        if self.seed is not None:
            out += ["--set", f"seed={self.seed}"]
        return out


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
            f"train_episodes={cfg.round_episodes(r)}",
            "--set",
            f"validation_episodes={cfg.validation_episodes}",
        ]
        + ["--set", "test_episodes=0"],
        ["train", "--stage", "1", "--config", cfg.stage1_config, "--data", *data, "--out", str(here / "runs")]
        + ["--set", f"models=['{cfg.stage1_model}']", *cfg.round_train_sets(r, 1)],
    ]
    if cfg.trained_stage2:
        names = ", ".join(f"'{m}'" for m in cfg.trained_stage2)
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
            + ["--set", f"models=[{names}]", *cfg.round_train_sets(r, 2)]
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
