"""Benchmark of the planner cycle (docs/design/performance.md; ``irlsim bench --planner``): synthetic cycles
on the real road. Measured, never asserted."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from irlsim.planner.config import PlannerConfig
from irlsim.planner.planner import Planner
from irlsim.road import load_road
from irlsim.road.scenario import DEFAULT_SCENARIO, Scenario, load_scenario
from irlsim.sim.types import EgoState, Observation, VehicleStates


def planner_observations(
    seed: int, n_obs: int = 12, scenario: str | Scenario = DEFAULT_SCENARIO, n_vehicles: int = 15
) -> list[Any]:
    """Synthetic cycles on the scenario's road (a loaded Scenario is not read again): ``n_vehicles``
    vehicles within +-150 m in random lanes at 25-35 km/h, the ego at 5-20 m/s; a third of them before an
    active stop line (if the road has one), some before an exit in the rightmost lane (if it has one), on
    an open route along its stretch."""

    road = load_road(scenario=scenario)
    rng = np.random.default_rng(seed)
    lap = road.lap_length
    out = []
    for k in range(n_obs):
        lines = [sl.s for sl in road.stop_lines] + [g.s for g in road.signals]
        if k % 3 == 0 and lines:
            line = lines[k % len(lines)]
            s0, stop_s = line - rng.uniform(20, 120), line
        elif k % 3 == 1 and road.exits:
            s0, stop_s = road.exits[k % len(road.exits)].s_start - rng.uniform(10, 100), np.inf
        else:
            hi = lap if road.closed else road.route_end_s - 200.0
            s0, stop_s = rng.uniform(road.route_begin_s, hi), np.inf
        d0 = float(road.lane_center(int(rng.integers(0, road.n_lanes))))
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
        m = n_vehicles
        s = (s0 + rng.uniform(-150, 150, m)) % lap
        d = road.lane_center(rng.integers(0, road.n_lanes, m))
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


def bench_planner(cycles: int = 300, seed: int = 0, scenario: str = DEFAULT_SCENARIO) -> dict[str, Any]:
    """The planner cycle at the default config (2,500 policies) over ``cycles`` synthetic cycles."""
    scn = load_scenario(scenario)  # the road's file read once: the planner's road and the cycles'
    planner = Planner(load_road(scenario=scn), PlannerConfig())
    observations = planner_observations(seed, scenario=scn)
    for obs in observations:  # warm-up: caches, first-call allocations
        planner.plan(obs)
    ms = []
    for i in range(max(cycles, 1)):
        planner.plan(observations[i % len(observations)])
        ms.append(planner.last_ms)
    arr = np.array(ms)
    # the world x / y / yaw of a PolicySet are computed on first read; time a cycle that reads them all
    # too (as pictures do; the dataset writer reads yaw only)
    ms_world = []
    for i in range(max(cycles // 3, 1)):
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
