"""``irlsim bench``: the performance figures of docs/DESIGN.md section 9, as JSON and Markdown.

Each section is a function ``(args) -> dict`` registered in ``SECTIONS`` and selected by its flag
(``--planner``, ``--collect``, ``--infer``). Without a section
flag every registered section runs. Everything runs on one thread: the thread variables are set before
numpy is imported. Results go to ``OUT/<section>.json`` and one ``OUT/bench.md`` with all sections found.
"""

from __future__ import annotations

import os

from irlsim import THREAD_VARS  # the package root imports no numpy

# one thread, set before numpy / torch are imported (the targets are per core)
for _var in THREAD_VARS:
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from irlsim.benchmarks import bench_collect as run_collect  # noqa: E402
from irlsim.benchmarks import bench_env as run_env  # noqa: E402
from irlsim.benchmarks import bench_infer as run_infer  # noqa: E402
from irlsim.benchmarks_scale import bench_scale as run_scale  # noqa: E402
from irlsim.config import MAX_SEED, int_in  # noqa: E402
from irlsim.errors import IrlsimError  # noqa: E402
from irlsim.outputs import check_output_dir  # noqa: E402
from irlsim.planner.config import PlannerConfig  # noqa: E402
from irlsim.planner.planner import Planner  # noqa: E402
from irlsim.road import LANE_WIDTH, load_road  # noqa: E402
from irlsim.sim.types import EgoState, Observation, VehicleStates  # noqa: E402
from irlsim.utils import atomic_write_text, write_json  # noqa: E402

HELP = "time the planner cycle, collection and inference (docs/DESIGN.md section 9); write JSON and Markdown"

#: docs/DESIGN.md section 9 targets, per section: (metric key, comparison, value, unit)
TARGETS: dict[str, tuple[str, str, float, str]] = {
    "planner": ("median_ms", "<=", 5.0, "ms"),
    "collect": ("cycles_per_s_per_worker_with_2", ">=", 25.0, "cycles/s"),
    "infer": ("infer_median_ms", "<=", 10.0, "ms"),
    "scale": ("ray_over_local", ">=", 0.9, "x the local pool"),
}


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


# ---------------------------------------------------------------------------------------------- planner
def _planner_observations(seed: int, n_obs: int = 12) -> list[Any]:
    """Synthetic cycles on the real road: 15 vehicles within +-150 m in random lanes at 25-35 km/h,
    the ego at 5-20 m/s; a third of them before an active stop line, some before an exit in lane 0."""

    road = load_road()
    rng = np.random.default_rng(seed)
    lap = road.lap_length
    out = []
    for k in range(n_obs):
        if k % 3 == 0:
            line = road.stop_lines[k % 2].s
            s0, stop_s = line - rng.uniform(20, 120), line
        elif k % 3 == 1:
            s0, stop_s = road.exits[k % 2].s_start - rng.uniform(10, 100), np.inf
        else:
            s0, stop_s = rng.uniform(0, lap), np.inf
        d0 = float(road.lane_center(int(rng.integers(0, 3))))
        v0 = float(rng.uniform(5, 20))
        x, y = road.to_xy(np.array(s0), np.array(d0))
        ego = EgoState(
            0.0,
            float(x),
            float(y),
            float(road.heading(np.array(s0))),
            v0,
            0.0,
            s0,
            d0,
            0.0,
            0.0,
            int(road.lane_of_d(np.array(d0))),
        )
        m = 15
        s = (s0 + rng.uniform(-150, 150, m)) % lap
        d = (rng.integers(0, 3, m) - 1.0) * LANE_WIDTH
        vx, vy = road.to_xy(s, d)
        veh = VehicleStates(
            tuple(f"bg{i}" for i in range(m)),
            vx,
            vy,
            road.heading(s),
            rng.uniform(25 / 3.6, 35 / 3.6, m),
            s,
            d,
            np.full(m, 4.5),
            np.full(m, 1.8),
        )
        ahead = [((c.s - s0 % lap) % lap, c.index) for c in road.checkpoints]
        dist, idx = min(ahead)
        out.append(Observation(ego, veh, idx, s0 + dist, stop_s, lap))
    return out


def bench_planner(args: argparse.Namespace) -> dict[str, Any]:

    planner = Planner(load_road(), PlannerConfig())
    observations = _planner_observations(args.seed)
    for obs in observations:  # warm-up: caches, first-call allocations
        planner.plan(obs)
    ms = []
    for i in range(max(args.cycles, 1)):
        planner.plan(observations[i % len(observations)])
        ms.append(planner.last_ms)
    arr = np.array(ms)
    # the world x / y / yaw of a PolicySet are computed on first read; time a cycle that reads them all
    # too (as pictures do; the dataset writer reads yaw only)
    ms_world = []
    for i in range(max(args.cycles // 3, 1)):
        t0 = time.perf_counter()
        ps = planner.plan(observations[i % len(observations)])
        ps.x, ps.y, ps.yaw  # noqa: B018
        ms_world.append((time.perf_counter() - t0) * 1e3)
    return {
        "what": "planner cycle: sampling + trajectories (s, d, v, lane; world x, y, yaw on first read) + "
        "15 features + control points + labels + sort",
        "n_policies": planner.cfg.n_policies,
        "n_vehicles": 15,
        "n_steps": planner.cfg.n_steps,
        "cycles": len(ms),
        "threads": 1,
        "median_ms": round(float(np.median(arr)), 3),
        "p90_ms": round(float(np.percentile(arr, 90)), 3),
        "mean_ms": round(float(arr.mean()), 3),
        "min_ms": round(float(arr.min()), 3),
        "median_ms_reading_xy_yaw": round(float(np.median(ms_world)), 3),
    }


def bench_collect(args: argparse.Namespace) -> dict[str, Any]:

    return run_collect(cycles=args.collect_cycles, n_policies=2500, seed=args.seed)


def bench_infer(args: argparse.Namespace) -> dict[str, Any]:

    return run_infer(n_policies=2500, seed=args.seed)


def bench_env(args: argparse.Namespace) -> dict[str, Any]:
    return run_env(steps=max(args.env_steps, 1), n_policies=500, n_envs=2, seed=args.seed)


def bench_scale(args: argparse.Namespace) -> dict[str, Any]:
    return run_scale(cycles=args.collect_cycles, n_policies=2500, seed=args.seed)


#: section name -> function; ``--<name>`` selects it
SECTIONS: dict[str, Callable[[argparse.Namespace], dict[str, Any]]] = {
    "planner": bench_planner,
    "collect": bench_collect,
    "infer": bench_infer,
    "env": bench_env,
    "scale": bench_scale,
}


def _markdown(results: dict[str, dict[str, Any]]) -> str:
    lines = [
        "# irlsim benchmarks",
        "",
        f"Machine: {platform.machine()}, {platform.processor() or 'cpu'}, "
        f"Python {platform.python_version()}; "
        "one thread (collection: one worker, then two; training: two threads).",
        "",
        "| section | figure | value | target |",
        "|---|---|---|---|",
    ]
    for name, res in results.items():
        tgt = TARGETS.get(name)
        for key, value in res.items():
            if key in ("what",) or isinstance(value, (dict, list)):
                continue
            target = f"{tgt[1]} {tgt[2]:g} {tgt[3]}" if tgt and tgt[0] == key else ""
            lines.append(f"| {name} | {key} | {value} | {target} |")
    lines.append("")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:

    if args.cycles < 1:
        raise IrlsimError(f"--cycles must be >= 1, got {args.cycles}")
    if args.collect_cycles < 1:
        raise IrlsimError(f"--collect-cycles must be >= 1, got {args.collect_cycles}")
    check_output_dir(args.out, "--out")
    chosen = [name for name in SECTIONS if getattr(args, name, False)] or list(SECTIONS)
    for name in chosen:
        res = SECTIONS[name](args)
        write_json(args.out / f"{name}.json", res)
        print(f"{name}: " + ", ".join(f"{k} {v}" for k, v in res.items() if k != "what"))
    # bench.md summarises every section result present in the folder (earlier runs included)
    results = {}
    for name in SECTIONS:
        p = args.out / f"{name}.json"
        if p.is_file():
            results[name] = json.loads(p.read_text())
    atomic_write_text(args.out / "bench.md", _markdown(results))
    print(f"wrote {args.out / 'bench.md'}")
    return 0
