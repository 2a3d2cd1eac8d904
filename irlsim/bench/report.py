"""``irlsim bench`` as a library: :func:`run_benchmarks` with :class:`BenchRun`, the figures of
docs/design/performance.md as JSON and Markdown.

Each section is a function ``(BenchRun) -> dict`` registered in :data:`SECTIONS`: ``planner``
(:mod:`irlsim.bench.planner`), ``collect``, ``infer``, ``env`` (:mod:`irlsim.bench.episodes`) and
``scale`` (:mod:`irlsim.bench.scale`). Results go to ``out/<section>.json`` and one ``out/bench.md`` with
all sections found there. The caller sets one thread (``irlsim.THREAD_VARS``) before numpy is imported:
the targets are per core.
"""

from __future__ import annotations

import json
import platform
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim.bench.episodes import bench_collect as run_collect
from irlsim.bench.episodes import bench_env as run_env
from irlsim.bench.episodes import bench_infer as run_infer
from irlsim.bench.planner import bench_planner
from irlsim.bench.scale import bench_scale as run_scale
from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_dir
from irlsim.road.scenario import DEFAULT_SCENARIO
from irlsim.utils import atomic_write_text, write_json


@dataclass(frozen=True)
class BenchRun:
    """One ``irlsim bench``: the sections to time (empty: all) and their sizes."""

    out: Path = Path("bench")
    sections: tuple[str, ...] = ()
    cycles: int = 300
    """timed planner cycles"""
    env_steps: int = 200
    """timed Gymnasium env steps"""
    collect_cycles: int = 150
    """planning cycles per timed collection episode"""
    seed: int = 0
    """seed of the synthetic traffic"""
    scenario: str = DEFAULT_SCENARIO
    """the road of the planner section (a shipped scenario or a scenario.toml path)"""
    demonstrator: Path | None = None
    """the collect section: a collect config whose ``[demonstrator]`` drives (None: the expert)"""


#: docs/design/performance.md targets, per section: (metric key, comparison, value, unit)
TARGETS: dict[str, tuple[str, str, float, str]] = {
    "planner": ("median_ms", "<=", 5.0, "ms"),
    "collect": ("cycles_per_s_per_worker_with_2", ">=", 25.0, "cycles/s"),
    "infer": ("infer_median_ms", "<=", 10.0, "ms"),
    "scale": ("ray_over_local", ">=", 0.9, "x the local pool"),
}


def _planner(run: BenchRun) -> dict[str, Any]:
    return bench_planner(cycles=run.cycles, seed=run.seed, scenario=run.scenario)


def _collect(run: BenchRun) -> dict[str, Any]:
    return run_collect(
        cycles=run.collect_cycles, n_policies=2500, seed=run.seed, demonstrator=run.demonstrator
    )


def _infer(run: BenchRun) -> dict[str, Any]:
    return run_infer(n_policies=2500, seed=run.seed)


def _env(run: BenchRun) -> dict[str, Any]:
    return run_env(steps=max(run.env_steps, 1), n_policies=500, n_envs=2, seed=run.seed)


def _scale(run: BenchRun) -> dict[str, Any]:
    return run_scale(cycles=run.collect_cycles, n_policies=2500, seed=run.seed)


#: section name -> function; ``irlsim bench --<name>`` selects it
SECTIONS: dict[str, Callable[[BenchRun], dict[str, Any]]] = {
    "planner": _planner,
    "collect": _collect,
    "infer": _infer,
    "env": _env,
    "scale": _scale,
}


def markdown(results: dict[str, dict[str, Any]]) -> str:
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


def run_benchmarks(run: BenchRun) -> Path:
    """Time the sections of ``run`` (all when none is named), write ``<section>.json`` and ``bench.md``
    (every section result present in the folder, earlier runs included); returns bench.md's path."""
    if run.cycles < 1:
        raise IrlsimError(f"--cycles must be >= 1, got {run.cycles}")
    if run.collect_cycles < 1:
        raise IrlsimError(f"--collect-cycles must be >= 1, got {run.collect_cycles}")
    unknown = [s for s in run.sections if s not in SECTIONS]
    if unknown:
        raise IrlsimError(f"unknown bench section(s) {', '.join(unknown)}: choose from {', '.join(SECTIONS)}")
    check_output_dir(run.out, "--out")
    chosen = [name for name in SECTIONS if name in run.sections] or list(SECTIONS)
    for name in chosen:
        res = SECTIONS[name](run)
        write_json(run.out / f"{name}.json", res)
        print(f"{name}: " + ", ".join(f"{k} {v}" for k, v in res.items() if k != "what"))
    results = {}
    for name in SECTIONS:
        p = run.out / f"{name}.json"
        if p.is_file():
            results[name] = json.loads(p.read_text())
    atomic_write_text(run.out / "bench.md", markdown(results))
    print(f"wrote {run.out / 'bench.md'}")
    return run.out / "bench.md"
