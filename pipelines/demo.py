"""``irlsim demo`` (``make demo``): the whole chain on the small default configuration.

net -> collect (configs/collect/default.toml) -> train stage 1 -> train stage 2 -> evaluate -> drive.
Each step is a library call (:mod:`irlsim.workflows`), printed before it runs as the command a user would
type to do the same; finished steps resume.
``--preset tiny`` runs the same chain on the smoke configs (configs/collect/tiny.toml,
configs/train/tiny_stage*.toml) with short drives: a check that every stage connects, in about a minute.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from irlsim.config import int_in, load_config
from irlsim.data.collection import CollectConfig
from irlsim.models.registry import STAGE1_MODELS, STAGE2_BASE
from irlsim.train.config import Stage1Config, Stage2Config
from irlsim.workflows.collect import CollectRun, collect_dataset
from irlsim.workflows.drive import DriveRun, drive_models
from irlsim.workflows.evaluate import EvaluateRun, evaluate_runs
from irlsim.workflows.net import build_network
from irlsim.workflows.steps import exit_status
from irlsim.workflows.train import TrainRun, train_models

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


@dataclass(frozen=True)
class Step:
    """One step of the chain: the library call ``call(request)``, and the ``irlsim`` command line that
    does the same (what the demo prints before the step runs, for the user to re-type)."""

    command: tuple[str, ...]
    request: Any
    """the workflow's typed request (``CollectRun``, ``TrainRun``, ...; the net has none)"""
    call: Callable[[Any], bool]
    """the workflow, True when it finished"""

    def run(self) -> bool:
        return self.call(self.request)


def _built(force: bool) -> bool:
    return bool(build_network(force))


def _collected(run: CollectRun) -> bool:
    return collect_dataset(run).ok


def _trained(run: TrainRun) -> bool:
    return bool(train_models(run))


def _evaluated(run: EvaluateRun) -> bool:
    return bool(evaluate_runs(run))


def _driven(run: DriveRun) -> bool:
    return drive_models(run) is not None


def steps(args: argparse.Namespace) -> list[Step]:
    preset = args.preset
    data, runs = Path(args.data), Path(args.runs)
    collect_toml = CONFIGS / "collect" / f"{preset}.toml"
    stage1_toml = CONFIGS / "train" / f"{_train(preset)}stage1.toml"
    stage2_toml = CONFIGS / "train" / f"{_train(preset)}stage2.toml"
    train = ("--data", str(data), "--out", str(runs))
    out = [
        Step(("net",), False, _built),
        Step(
            ("collect", "--config", str(collect_toml), "--out", str(data), "--seed", str(args.seed)),
            CollectRun(load_config(CollectConfig, collect_toml, {"seed": args.seed}), data),
            _collected,
        ),
        Step(
            ("train", "--stage", "1", "--config", str(stage1_toml), *train),
            TrainRun(load_config(Stage1Config, stage1_toml), (data,), runs),
            _trained,
        ),
        Step(
            ("train", "--stage", "2", "--config", str(stage2_toml), *train),
            TrainRun(load_config(Stage2Config, stage2_toml), (data,), runs),
            _trained,
        ),
        Step(
            ("evaluate", "--data", str(data), "--runs", str(runs), "--out", str(runs / "eval")),
            EvaluateRun((data,), runs, runs / "eval"),
            _evaluated,
        ),
    ]
    if not args.skip_drive:
        # tiny: a few planning cycles per model are enough to show that the checkpoints drive
        tiny = preset == "tiny"
        drive = DriveRun(
            DRIVE_MODELS,
            runs,
            episodes=1 if tiny else 3,
            laps=1,
            seed=100 + args.seed,
            config_file=collect_toml,
            out=runs / "drive",
            frames=3 if tiny else 40,
            max_cycles=30 if tiny else 0,
        )
        line = ["drive", "--runs", str(runs), "--model", ",".join(DRIVE_MODELS)]
        line += ["--episodes", "1", "--laps", "1", "--max-cycles", "30", "--frames", "3"] if tiny else []
        line += [] if tiny else ["--episodes", "3", "--laps", "1"]
        line += ["--seed", str(100 + args.seed), "--config", str(collect_toml)]
        # as in the paper: the learned reward alone, no model-based collision check ...
        out.append(Step((*line, "--out", str(runs / "drive")), drive, _driven))
        # ... and with the expert's model-based filter (collision / off-road / exit labels) added
        safety = replace(drive, safety=True, frames=0, out=runs / "drive_safety")
        out.append(
            Step((*line, "--safety", "--frames", "0", "--out", str(runs / "drive_safety")), safety, _driven)
        )
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
    for step in steps(args):
        cmd = step.command
        print(f"\n$ irlsim {' '.join(cmd)}", flush=True)
        t_step = time.perf_counter()
        rc = exit_status(step.run)
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
