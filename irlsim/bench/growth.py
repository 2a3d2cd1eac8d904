"""``irlsim bench --growth``: how each cost grows with its size, measured on the real parts.

Each curve is a list of (size, cost) points measured here, then fitted and reported by
:mod:`irlsim.bench.growth_report` (JSON, a Markdown table with the log-log slopes, PNG plots):

- the planner cycle [ms] against policies, vehicles and lanes (:class:`~irlsim.planner.planner.Planner`
  on synthetic cycles, :func:`irlsim.bench.planner.planner_observations`; lanes on generated straight
  roads of 1 to 4 lanes, built by netconvert as any scenario);
- collection [episodes/min] against workers (1: in this process, 2: spawned; real SUMO through libsumo,
  the expert, demonstrations, Parquet), as ``irlsim collect`` runs episodes: end to end (workers' start
  included) and after the start (from the first episode's result on);
- disk per cycle [bytes]: a collected dataset's Parquet and its training cache (``.cache``) against
  policies;
- a stage-1 training epoch [s] and the training's resident memory [MB] against dataset cycles and
  policies per cycle; inference [ms] of the trained PACNN against policies
  (:mod:`irlsim.bench.growth_train`).

Each point is timed for a fixed budget of seconds (median of what fits, at least a few repeats), so the
whole run has a bounded length: about 10 minutes on 2 cores, ``quick`` about a minute. The run itself
(:func:`irlsim.bench.growth_report.run_growth`) fits the curves and writes the results. The caller sets
one thread (``irlsim.THREAD_VARS``) before numpy is imported; training runs on ``train_threads``.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.bench.planner import planner_observations
from irlsim.road.scenario import DEFAULT_SCENARIO, Scenario, Scenarios, load_scenario, shipped_scenarios

#: timed repeats of each point at least (more while its time budget lasts)
MIN_REPEATS = 5


@dataclass(frozen=True)
class GrowthSizes:
    """The sizes each curve is measured at, and how long each point is timed."""

    policies: tuple[int, ...] = (500, 1024, 2048, 4096, 8192, 16384)
    """planner cycle and inference: policies per cycle"""
    vehicles: tuple[int, ...] = (0, 5, 15, 30, 60)
    """planner cycle: vehicles around the ego (2,500 policies)"""
    lanes: tuple[int, ...] = (1, 2, 3, 4)
    """planner cycle: lanes of a generated straight road (2,500 policies, 15 vehicles)"""
    point_s: float = 3.0
    """[s] each planner / inference point is timed for about this long"""
    workers: tuple[int, ...] = (1, 2)
    """collection: worker processes"""
    collect_episodes: int = 12
    """collection: episodes per timed collection (more than the most workers)"""
    collect_cycles: int = 40
    """collection: planning cycles per episode"""
    collect_policies: int = 500
    """collection: policies per cycle"""
    disk_policies: tuple[int, ...] = (250, 500, 1000, 2000, 4000)
    """disk per cycle: policies per cycle of the collected dataset"""
    disk_cycles: int = 40
    """disk per cycle: cycles of its one episode"""
    train_cycles: tuple[int, ...] = (128, 256, 512, 1024, 2048)
    """training epoch and memory: train cycles (``train_policies_at`` policies)"""
    train_policies_at: int = 500
    train_policies: tuple[int, ...] = (500, 1000, 2000, 4000, 8000)
    """training epoch and memory: policies per cycle (``train_cycles_at`` cycles)"""
    train_cycles_at: int = 64
    train_threads: int = 1
    """training: torch threads. One, not the two of the configs: on a 2-core host shared with other jobs,
    a step on two threads waits for whichever thread is descheduled (measured 10-25x slower than on one)"""


#: ``irlsim bench --growth --quick``: every curve, few small points (a test, under a minute)
QUICK = GrowthSizes(
    policies=(500, 1000, 2000),
    vehicles=(0, 5, 15),
    lanes=(1, 2),
    point_s=0.2,
    collect_episodes=4,
    collect_cycles=5,
    collect_policies=200,
    disk_policies=(200, 400),
    disk_cycles=5,
    train_cycles=(32, 64),
    train_policies_at=200,
    train_policies=(200, 400),
    train_cycles_at=32,
)


@dataclass(frozen=True)
class Curve:
    """One measured curve: ``y`` (in ``unit``) at each size ``x`` (in ``x_label``), with what was fixed."""

    name: str
    title: str
    x_label: str
    unit: str
    setting: str
    x: list[float]
    y: list[float]


Progress = Callable[[str], None]


def time_for(fn: Callable[[], Any], seconds: float, min_repeats: int = MIN_REPEATS) -> float:
    """Median wall time [ms] of ``fn()`` called until ``seconds`` have passed (at least ``min_repeats``
    times, at most 1,000), after one untimed call (first-call allocations, caches)."""
    fn()
    ms: list[float] = []
    t_end = time.perf_counter() + seconds
    while len(ms) < min_repeats or (time.perf_counter() < t_end and len(ms) < 1000):
        t0 = time.perf_counter()
        fn()
        ms.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(ms))


# ----------------------------------------------------------------------------------------- the planner


def _planner_ms(scenario: Scenario, n_policies: int, n_vehicles: int, seconds: float, seed: int) -> float:
    """Median planner cycle [ms] over the synthetic cycles of ``scenario`` (loaded: not read again)."""
    from irlsim.planner.config import PlannerConfig
    from irlsim.planner.planner import Planner
    from irlsim.road import load_road

    planner = Planner(load_road(scenario=scenario), PlannerConfig(n_policies=n_policies))
    observations = planner_observations(seed, scenario=scenario, n_vehicles=n_vehicles)
    for obs in observations:  # warm-up: every observation once
        planner.plan(obs)
    i = 0

    def one() -> None:
        nonlocal i
        planner.plan(observations[i % len(observations)])
        i += 1

    return time_for(one, seconds)


#: a straight two-edge road of 2 km (netconvert inputs); {lanes} lanes of 3.2 m at 100 km/h
_NODES = """<nodes>
    <node id="a" x="0" y="0" type="priority"/>
    <node id="b" x="1000" y="0" type="priority"/>
    <node id="c" x="2000" y="0" type="priority"/>
</nodes>
"""
_EDGE = (
    '    <edge id="{id}" from="{a}" to="{b}" numLanes="{lanes}" speed="27.78" priority="10" '
    'spreadType="center" width="3.2"/>\n'
)
_NETCONVERT = """<configuration>
    <input><node-files value="road.nod.xml"/><edge-files value="road.edg.xml"/></input>
    <processing><offset.disable-normalization value="true"/><no-turnarounds value="true"/></processing>
    <report><no-warnings value="true"/></report>
</configuration>
"""


def straight_road(folder: Path, lanes: int) -> str:
    """A scenario of a straight 2 km road with ``lanes`` lanes (no exit, stop line or signal) in
    ``folder``: netconvert inputs and a scenario.toml; returns the scenario.toml's path."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "road.nod.xml").write_text(_NODES)
    edges = "".join(_EDGE.format(id=a + b, a=a, b=b, lanes=lanes) for a, b in (("a", "b"), ("b", "c")))
    (folder / "road.edg.xml").write_text(f"<edges>\n{edges}</edges>\n")
    (folder / "netconvert.cfg").write_text(_NETCONVERT)
    toml = folder / "scenario.toml"
    toml.write_text(
        f'name = "straight{lanes}"\ndescription = "bench: straight road, {lanes} lanes"\n\n'
        '[network]\nnetconvert = "netconvert.cfg"\n\n[route]\nedges = ["ab", "bc"]\n'
    )
    return str(toml)


def planner_curves(sizes: GrowthSizes, seed: int, scenario: str, say: Progress) -> list[Curve]:
    """The planner cycle against policies (15 vehicles), vehicles (2,500 policies) and lanes."""
    road = f"the {scenario} road" if scenario in shipped_scenarios() else scenario  # a name, or a path
    scn = load_scenario(scenario)  # the road's file read once for every point
    by_policies = []
    for n in sizes.policies:
        by_policies.append(_planner_ms(scn, n, 15, sizes.point_s, seed))
        say(f"planner, {n} policies: {by_policies[-1]:.2f} ms per cycle")
    by_vehicles = []
    for m in sizes.vehicles:
        by_vehicles.append(_planner_ms(scn, 2500, m, sizes.point_s, seed))
        say(f"planner, {m} vehicles: {by_vehicles[-1]:.2f} ms per cycle")
    by_lanes = []
    with tempfile.TemporaryDirectory() as tmp:
        for lanes in sizes.lanes:
            path = straight_road(Path(tmp) / f"lanes{lanes}", lanes)
            by_lanes.append(_planner_ms(load_scenario(path), 2500, 15, sizes.point_s, seed))
            say(f"planner, {lanes} lane{'s' if lanes > 1 else ''}: {by_lanes[-1]:.2f} ms per cycle")
    return [
        Curve(
            "planner_policies", "planner cycle vs policies", "policies", "ms", f"15 vehicles, {road}",
            list(map(float, sizes.policies)), by_policies,
        ),
        Curve(
            "planner_vehicles", "planner cycle vs vehicles", "vehicles", "ms", f"2,500 policies, {road}",
            list(map(float, sizes.vehicles)), by_vehicles,
        ),
        Curve(
            "planner_lanes", "planner cycle vs lanes", "lanes", "ms",
            "2,500 policies, 15 vehicles, a straight 2 km road", list(map(float, sizes.lanes)), by_lanes,
        ),
    ]  # fmt: skip


# ---------------------------------------------------------------------------------- collection and disk


def _episode_jobs(
    out: Path, n_policies: int, cycles: int, n: int, seed: int, scenarios: Scenarios
) -> list[Any]:
    """``n`` expert episodes of ``cycles`` cycles of ``n_policies`` policies, 15 vehicles, on the oval
    (``scenarios``: the roads read once, handed to every episode as ``irlsim collect`` does)."""
    from irlsim.config import load_config
    from irlsim.data.collection import CollectConfig, EpisodeJob
    from irlsim.executor import Job

    cfg = load_config(
        CollectConfig,
        None,
        {"max_cycles": cycles, "planner.n_policies": n_policies, "scenario.n_vehicles": 15},
        scenarios=scenarios,
    )
    jobs = [EpisodeJob(str(out), "train", i, seed + i, cfg, scenarios=scenarios) for i in range(n)]
    return [Job(f"train/{i}", job) for i, job in enumerate(jobs)]


def _collect(jobs: list[Any], workers: int) -> tuple[float, int, float]:
    """Run the episode jobs as ``irlsim collect`` does (1 worker: in this process; more: spawned);
    returns (wall seconds, cycles, seconds from the ``workers``-th episode's result to the last)."""
    from irlsim.data.collection import collect_episode
    from irlsim.executor import run_jobs

    arrivals: list[float] = []
    t0 = time.perf_counter()
    done = run_jobs(
        collect_episode,
        jobs,
        executor="local",
        workers=workers,
        on_result=lambda job, stats: arrivals.append(time.perf_counter()),
    )
    wall = time.perf_counter() - t0
    if done.failed:
        raise RuntimeError(f"benchmark episodes failed: {done.failed}")
    cycles = sum(int(r["collect/cycles"]) for r in done.results.values())
    return wall, cycles, arrivals[-1] - arrivals[min(workers, len(arrivals)) - 1]


def collect_curves(sizes: GrowthSizes, seed: int, say: Progress) -> list[Curve]:
    """Episodes per minute with each worker count: end to end (workers' start included), and after the
    start: with w workers, the episodes after the first w over the time from the w-th result to the
    last (each worker's first episode carries its start)."""
    scenarios = Scenarios()
    scenarios(DEFAULT_SCENARIO)  # the default road read and its network built once, before the workers
    rates, steady = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for w in sizes.workers:
            n, cycles = sizes.collect_episodes, sizes.collect_cycles
            jobs = _episode_jobs(Path(tmp) / f"w{w}", sizes.collect_policies, cycles, n, seed, scenarios)
            wall, total, after_start = _collect(jobs, w)
            rates.append(n / wall * 60.0)
            steady.append((n - w) / after_start * 60.0)
            workers = f"{w} worker{'s' if w > 1 else ''}"
            say(
                f"collection, {workers}: {rates[-1]:.1f} episodes/min ({total / wall:.0f} cycles/s), "
                f"{steady[-1]:.1f} after the start"
            )
    setting = (
        f"{sizes.collect_episodes} episodes of {sizes.collect_cycles} cycles, "
        f"{sizes.collect_policies} policies, 15 vehicles, the oval"
    )
    x = list(map(float, sizes.workers))
    return [
        Curve("collect_workers", "collection vs workers", "workers", "episodes/min", setting, x, rates),
        Curve(
            "collect_workers_started", "collection vs workers, after the start", "workers", "episodes/min",
            setting, x, steady,
        ),
    ]  # fmt: skip


def _folder_bytes(folder: Path, pattern: str) -> int:
    return sum(p.stat().st_size for p in folder.rglob(pattern) if p.is_file())


def disk_curves(sizes: GrowthSizes, seed: int, say: Progress) -> list[Curve]:
    """Bytes per cycle of a collected dataset's Parquet files and of its training cache, per policy count:
    one episode, a manifest (``irlsim.data.layout.write_manifest``), the cache the reader builds."""
    from irlsim.data.collection import data_config
    from irlsim.data.layout import write_manifest
    from irlsim.data.reader import open_dataset

    parquet, cache = [], []
    scenarios = Scenarios()  # the default road read once for every point
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes.disk_policies:
            out = Path(tmp) / f"n{n}"
            jobs = _episode_jobs(out, n, sizes.disk_cycles, 1, seed, scenarios)
            _, cycles, _ = _collect(jobs, 1)
            cfg = jobs[0].arg.config
            seeds = {"train": [j.arg.seed for j in jobs], "validation": [], "test": []}
            splits = {"train": [0], "validation": [], "test": []}
            write_manifest(out, {"config": data_config(cfg, scenarios), "seeds": seeds, "splits": splits})
            open_dataset(out).split_tensors("train")  # builds <out>/.cache/train
            parquet.append(_folder_bytes(out, "*.parquet") / cycles)
            cache.append(_folder_bytes(out / ".cache", "*") / cycles)
            kb = f"{parquet[-1] / 1e3:.1f} kB Parquet, {cache[-1] / 1e3:.1f} kB cache"
            say(f"disk, {n} policies: {kb} per cycle")
    x = list(map(float, sizes.disk_policies))
    setting = f"one episode of {sizes.disk_cycles} cycles, 15 vehicles, the oval"
    return [
        Curve("disk_parquet", "Parquet per cycle vs policies", "policies", "bytes", setting, x, parquet),
        Curve("disk_cache", "training cache per cycle vs policies", "policies", "bytes", setting, x, cache),
    ]
