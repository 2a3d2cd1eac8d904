"""One planning cycle of a :class:`PolicySet` as a picture (``irlsim plot-cycle``): the policies on the road
coloured by value, the executed one, the vehicles and what the planner predicts they do.

The drawing itself is :func:`irlsim.viz.frames.draw_policies`, the same as the drive stage's cycle pictures;
this module only turns a PolicySet, values and vehicle states into its arrays. The vehicles' predictions
are the planner's own (:func:`irlsim.planner.prediction.predicted_motion`: constant speed, or braking to
stand at the next stop line), so the picture shows what the proximity feature and the collision label see.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.planner.features import F32
from irlsim.planner.policy_set import PolicySet
from irlsim.planner.prediction import predicted_motion
from irlsim.road import Road
from irlsim.sim.types import VehicleStates
from irlsim.viz.frames import draw_policies
from irlsim.viz.scene import drawn_subset, road_lines, value_ranks


def predicted_vehicles(road: Road, s_ego: float, vehicles: VehicleStates, t: np.ndarray) -> np.ndarray:
    """[M, K, 3] world (x, y, yaw) of each vehicle's front bumper at times ``t`` [K] (s), as the planner
    predicts it from the ego at unwrapped route position ``s_ego`` [m] (constant d)."""
    m = vehicles.count
    if m == 0:
        return np.zeros((0, len(t), 3))
    lap = road.lap_length
    ds0 = (vehicles.s - (s_ego % lap) + lap / 2) % lap - lap / 2  # as the planner relates them to the ego
    stops = tuple(float(sl.s) for sl in road.stop_lines)
    centre, _ = predicted_motion(np.ones(m, bool), ds0, vehicles, lap, np.asarray(t, F32), stops)
    s = s_ego + centre.astype(np.float64) + vehicles.length[:, None] / 2  # centre -> front bumper
    x, y = road.to_xy(s, np.broadcast_to(vehicles.d[:, None], s.shape))
    return np.stack([x, y, road.heading(s)], axis=-1)


def draw_cycle(
    ax: Any,
    road: Road,
    ps: PolicySet,
    value: np.ndarray,
    chosen: int | None = None,
    vehicles: VehicleStates | None = None,
    horizon: float = 5.0,
    ego_size: tuple[float, float] = (4.5, 1.8),
    highlight: np.ndarray | None = None,
    max_drawn: int = 2500,
) -> None:
    """Draw the cycle ``ps`` on ``ax``: policies coloured by the rank of ``value`` [N] (green high, red
    low; a colour bar), ``chosen`` (black), ``highlight`` indices (blue, e.g. the highest-attention
    policies), ``vehicles`` with the planner's predictions over ``horizon`` [s], the road around the ego.
    At most ``max_drawn`` policies plus the chosen and highlighted ones are drawn."""
    n = ps.n_policies
    value = np.asarray(value, dtype=np.float64)
    assert value.shape == (n,), f"value must be [{n}], got {value.shape}"
    hl = np.zeros(0, np.int64) if highlight is None else np.asarray(highlight, dtype=np.int64)
    always = hl if chosen is None else np.append(hl, chosen)
    idx = drawn_subset(n, max_drawn, always)
    s0 = float(ps.s[0, 0])
    veh = vehicles if vehicles is not None else VehicleStates.empty()
    t = np.linspace(0.0, horizon, ps.n_steps)
    draw_policies(
        ax,
        ps.x[idx],
        ps.y[idx],
        value_ranks(value)[idx],
        np.isin(idx, hl),
        None if chosen is None else int(np.searchsorted(idx, chosen)),
        (float(ps.x[0, 0]), float(ps.y[0, 0]), float(ps.yaw[0, 0]), float(ps.v[0, 0]), *ego_size),
        veh.boxes(),
        road_lines(road, s0),
        view_yaw=float(road.heading(np.array(s0))),
        predictions=predicted_vehicles(road, s0, veh, t) if veh.count else None,
        title=f"t = {ps.t:.1f} s   v = {3.6 * float(ps.v[0, 0]):.0f} km/h",
    )
