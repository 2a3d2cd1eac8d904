"""``irlsim bench``: the performance figures of docs/DESIGN.md section 9, as JSON and Markdown.

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

from irlsim.bench.report import SECTIONS, BenchRun, run_benchmarks  # noqa: E402
from irlsim.config import MAX_SEED, int_in  # noqa: E402
from irlsim.errors import IrlsimError  # noqa: E402

HELP = "time the planner cycle, collection and inference (docs/DESIGN.md section 9); write JSON and Markdown"


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
        help="Gymnasium env steps/s (irlsim/Oval-v0, 500 policies), single and 2 AsyncVectorEnv workers",
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
        "--seed", type=int_in(0, MAX_SEED), default=0, help="seed of the synthetic traffic (default 0)"
    )
    parser.add_argument(
        "--scenario",
        default="oval",
        help="road of the planner section: a shipped scenario or a path (default oval)",
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


def run(args: argparse.Namespace) -> int:
    sections = tuple(name for name in SECTIONS if getattr(args, name, False))
    if args.quick and not args.growth:
        raise IrlsimError("--quick goes with --growth: add --growth, or drop --quick")
    if args.growth:
        if sections:
            flags = ", ".join(f"--{s}" for s in sections)
            raise IrlsimError(f"--growth runs on its own: drop {flags}, or drop --growth")
        # lazy: the growth modules are only needed here
        from irlsim.bench.growth_report import GrowthRun, run_growth

        run_growth(GrowthRun(args.out, args.quick, args.seed, args.scenario))
        return 0
    run_benchmarks(
        BenchRun(
            args.out, sections, args.cycles, args.env_steps, args.collect_cycles, args.seed, args.scenario
        )
    )
    return 0
