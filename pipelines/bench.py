"""``irlsim bench``: the performance figures of docs/design/performance.md, as JSON and Markdown.

Each section is selected by its flag (``--planner``, ``--collect``, ``--infer``, ``--env``, ``--scale``);
without a section flag every section runs (:func:`irlsim.bench.report.run_benchmarks`). Everything runs
on one thread: the thread variables are set before numpy is imported. Results go to
``OUT/<section>.json`` and one ``OUT/bench.md`` with all sections found. ``--growth`` instead measures
how each cost grows with its size (:func:`irlsim.bench.growth_report.run_growth`: ``OUT/growth.json``,
``growth.md``, ``growth.png``); ``--quick`` makes that a small, fast run.
"""

from __future__ import annotations

import os

from irlsim import THREAD_VARS  # the package root imports no numpy

# one thread, set before numpy / torch are imported (the targets are per core)
for _var in THREAD_VARS:
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from irlsim.bench.report import SECTIONS, BenchRun, run_benchmarks  # noqa: E402
from irlsim.config import MAX_SEED, int_in  # noqa: E402
from irlsim.errors import IrlsimError  # noqa: E402
from irlsim.road.scenario import DEFAULT_SCENARIO  # noqa: E402

HELP = "time the planner cycle, collection and inference (docs/design/performance.md); write JSON, Markdown"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("bench"), help="output folder (default: bench/)")
    parser.add_argument(
        "--planner", action="store_true", help="time the planner cycle (2,500 policies, 15 vehicles)"
    )
    parser.add_argument(
        "--collect",
        action="store_true",
        help="time collection end to end (SUMO + planner + demonstrations + Parquet)",
    )
    parser.add_argument("--infer", action="store_true", help="time PACNN + PTACNN inference and training")
    parser.add_argument(
        "--env",
        action="store_true",
        help="Gymnasium env steps/s (irlsim/Planning-v0, 500 policies), single and 2 AsyncVectorEnv workers",
    )
    parser.add_argument("--env-steps", type=int_in(1), default=200, help="timed env steps (default 200)")
    parser.add_argument("--cycles", type=int_in(1), default=300, help="timed planner cycles (default 300)")
    parser.add_argument(
        "--scale",
        action="store_true",
        help="collection with the local pool vs Ray (2 workers), 1 -> 2 workers on a simulated two-node "
        "Ray cluster, stage-1 training cycles/s per device and precision (needs the ray extra)",
    )
    parser.add_argument(
        "--collect-cycles",
        type=int_in(1),
        default=150,
        help="planning cycles per timed collection episode (default 150)",
    )
    parser.add_argument(
        "--demonstrator",
        type=Path,
        default=None,
        metavar="COLLECT_CONFIG",
        help="--collect: time collection with the [demonstrator] of this collect config, on its scenario "
        "(e.g. configs/collect/sumo_idm.toml; default: the expert)",
    )
    parser.add_argument(
        "--seed", type=int_in(0, MAX_SEED), default=0, help="seed of the synthetic traffic (default 0)"
    )
    _train_arguments(parser)
    parser.add_argument(
        "--scenario",
        default=DEFAULT_SCENARIO,
        help=f"road of the planner section: a shipped scenario or a path (default {DEFAULT_SCENARIO})",
    )
    parser.add_argument(
        "--growth",
        action="store_true",
        help="instead of the sections: how each cost grows (planner vs policies, vehicles, lanes; "
        "collection vs workers; training epoch and memory vs cycles and policies; inference vs policies; "
        "disk per cycle): OUT/growth.json, growth.md, growth.png (about 10 min on 2 cores)",
    )
    parser.add_argument(
        "--quick", action="store_true", help="with --growth: few, small points (under a minute)"
    )


def _train_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("--train-throughput (stage-1 training settings side by side)")
    group.add_argument(
        "--train-throughput",
        action="store_true",
        help="stage-1 training cycles/s of the baseline config, each --lever and the fast config, "
        "interleaved repeats on the dataset --data (the real training loop); only this section runs "
        "unless others are named",
    )
    group.add_argument("--data", type=Path, help="dataset folder to train on (--train-throughput)")
    group.add_argument(
        "--baseline", type=Path, default=Path("configs/train/stage1.toml"), help="baseline stage-1 config"
    )
    group.add_argument(
        "--fast", type=Path, default=Path("configs/train/stage1_sampled.toml"), help="fast stage-1 config"
    )
    group.add_argument(
        "--lever",
        action="append",
        default=[],
        help="one more variant: the baseline with KEY=VALUE[,KEY=VALUE] (config fields; precision=bf16 "
        "for the bf16 forward pass); repeatable",
    )
    group.add_argument("--model", default="PACNN+S", help="stage-1 model to time (default PACNN+S)")
    group.add_argument(
        "--max-cycles", type=int_in(1), default=1024, help="train cycles of each timed run (default 1024)"
    )
    group.add_argument("--repeats", type=int_in(1), default=3, help="interleaved repeats (default 3)")
    group.add_argument(
        "--threads",
        type=int_in(0, 1024),
        default=0,
        help="torch threads of every variant (default 0: each config's own, a --lever may set threads)",
    )
    group.add_argument(
        "--side-levers",
        type=Path,
        metavar="CHECKPOINT",
        help="measure the sampled max-ent normaliser (loss time, bias) and 16-bit features (gather time, "
        "error) with this stage-1 checkpoint's thetas on --data's validation split (with or without "
        "--train-throughput)",
    )


def _train_throughput(args: argparse.Namespace) -> None:
    # lazy: torch and the training stack, which the other sections do not need
    from irlsim.bench.training import ThroughputRun, bench_train_throughput, markdown_table
    from irlsim.errors import IrlsimError
    from irlsim.outputs import check_output_dir
    from irlsim.utils import atomic_write_text, write_json

    if args.data is None:
        raise IrlsimError("bench --train-throughput needs --data DATASET (a collected dataset folder)")
    check_output_dir(args.out, "--out")
    run = ThroughputRun(
        args.data,
        args.baseline,
        args.fast,
        tuple(args.lever),
        args.model,
        args.max_cycles,
        args.repeats,
        args.threads,
    )
    res: dict[str, Any] = {"data": str(args.data), "variants": []}
    if args.train_throughput:
        res = bench_train_throughput(run)
    if args.side_levers is not None:
        from irlsim.bench.train_levers import bench_side_levers

        res["side_levers"] = bench_side_levers(args.data, args.side_levers, threads=args.threads or 2)
    write_json(args.out / "train_throughput.json", res)
    table = markdown_table(res)
    atomic_write_text(args.out / "train_throughput.md", table)
    print(table + f"wrote {args.out / 'train_throughput.md'}")


def run(args: argparse.Namespace) -> int:
    sections = tuple(name for name in SECTIONS if getattr(args, name, False))
    if args.quick and not args.growth:
        raise IrlsimError("--quick goes with --growth: add --growth, or drop --quick")
    if args.demonstrator is not None and "collect" not in sections:
        raise IrlsimError("--demonstrator goes with --collect: add --collect, or drop --demonstrator")
    if args.growth:
        if sections:
            flags = ", ".join(f"--{s}" for s in sections)
            raise IrlsimError(f"--growth runs on its own: drop {flags}, or drop --growth")
        # lazy: the growth modules are only needed here
        from irlsim.bench.growth_report import GrowthRun, run_growth

        run_growth(GrowthRun(args.out, args.quick, args.seed, args.scenario))
        return 0
    if args.train_throughput or args.side_levers is not None:
        _train_throughput(args)
        if not sections:
            return 0
    run_benchmarks(
        BenchRun(
            args.out,
            sections,
            args.cycles,
            args.env_steps,
            args.collect_cycles,
            args.seed,
            args.scenario,
            args.demonstrator,
        )
    )
    return 0
