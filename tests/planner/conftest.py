"""Shared fixtures of the planner tests: the oval's road and synthetic observations (no SUMO)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from irlsim.planner.config import PlannerConfig
from irlsim.planner.planner import Planner
from irlsim.road import Road, load_road
from irlsim.sim.types import EgoState, Observation, VehicleStates


@pytest.fixture(scope="session")
def road() -> Road:
    return load_road()


@pytest.fixture(scope="session")
def planner(road: Road) -> Planner:
    return Planner(road, PlannerConfig())


def make_obs(
    road: Road,
    s: float,
    d: float,
    v: float,
    *,
    a: float = 0.0,
    d_dot: float = 0.0,
    vehicles: VehicleStates | None = None,
    stop_s: float = math.inf,
    t: float = 0.0,
) -> Observation:
    """An observation with the ego at route position (s, d) at speed v; target = next checkpoint."""
    x, y = road.to_xy(np.array(s), np.array(d))
    ego = EgoState(
        t=t,
        x=float(x),
        y=float(y),
        yaw=float(road.heading(np.array(s))),
        v=v,
        a=a,
        s=s,
        d=d,
        d_dot=d_dot,
        d_ddot=0.0,
        lane=int(road.lane_of_d(np.array(d))),
    )
    sw = s % road.lap_length
    ahead = [((c.s - sw) % road.lap_length, c.index) for c in road.checkpoints]
    dist, idx = min(ahead)
    return Observation(ego, vehicles or VehicleStates.empty(), idx, s + dist, stop_s, road.lap_length)


def make_vehicles(road: Road, items: list[tuple[float, float, float]]) -> VehicleStates:
    """Vehicles from (s, d, v) triples (front bumpers, route frame), 4.5 m x 1.8 m."""
    s = np.array([i[0] for i in items], dtype=float)
    d = np.array([i[1] for i in items], dtype=float)
    v = np.array([i[2] for i in items], dtype=float)
    x, y = road.to_xy(s, d)
    m = len(items)
    return VehicleStates(
        tuple(f"v{i}" for i in range(m)),
        x,
        y,
        road.heading(s),
        v,
        s % road.lap_length,
        d,
        np.full(m, 4.5),
        np.full(m, 1.8),
    )
