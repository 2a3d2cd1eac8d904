"""The following check of the expert's selection and of the following rule (``irlsim drive
--keep-distance``): every policy against the vehicles predicted ahead of it in its lane."""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.planner.prediction import predicted_stop_distance
from irlsim.sim.types import Observation


def lane_outlook(
    internals: Any,
    obs: Observation,
    sel: Any,  # irlsim.planner.expert.SelectionConfig
    dt: float,
    stop_lines: tuple[float, ...],
    ego_width: float,
    v_target: float,
    accel: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(shortfall [N] m, outlook [N] m) of every policy against the vehicles predicted ahead of it.
    ``accel`` [M] m/s^2 (``obs.vehicles``' order; None: every one at constant speed): a vehicle braking
    harder than ``BRAKING`` is predicted to brake on at that rate to a stand (:func:`braking_travel`).

    shortfall: by how much the policy falls short, at worst over the check times
    ``sel.follow_times`` [s], of a safe following distance to the vehicle predicted ahead of it in its
    lane then: required gap = headway v + gap + max(0, v^2 - v_m^2) / (2 b) (it could still fall back
    behind that vehicle braking ``follow_decel``). Vehicles are predicted at constant speed, standing
    where they will stop before a stop line within 80 m, queue included
    (:func:`irlsim.planner.prediction.predicted_stop_distance`). Without it the expert, whose
    safety zone looks 3 s ahead, keeps choosing policies that brake late in the horizon, closes in on
    slow vehicles at full speed and is then pushed out of its lane by the safety zone.

    outlook: the progress the policy's final lane offers for ``sel.outlook_time`` seconds beyond the
    horizon: v_target * outlook_time, or less where the predicted vehicle ahead in that lane at the
    horizon (gap g, speed v_m) limits it to max(0, g - follow_gap) + v_m * outlook_time; capped at the
    active stop line. It extends the 5 s horizon for the choice of lane: leaving a lane blocked by slow
    vehicles pays off only after the horizon."""
    lon, lat = internals.lon, internals.lat
    n = len(internals.lon_idx)
    veh = obs.vehicles
    s_end = lon.s[internals.lon_idx, -1]
    outlook = np.full(n, v_target * sel.outlook_time)
    if np.isfinite(obs.stop_s):
        outlook = np.minimum(outlook, np.maximum(obs.stop_s - obs.ego.s - s_end, 0.0))
    shortfall = np.zeros(n)
    if veh.count == 0:
        return shortfall, outlook
    lap = obs.lap_length
    ds0 = (veh.s - obs.ego.s % lap + lap / 2) % lap - lap / 2
    near = (ds0 > -20.0) & (ds0 < 200.0)
    if not near.any():
        return shortfall, outlook
    cols = [min(int(round(t / dt)), lon.s.shape[1] - 1) for t in sel.follow_times]
    t = np.array([c * dt for c in cols])  # [C]
    v_m = veh.v[near][:, None]  # [M, 1]
    travel, v_c = braking_travel(v_m, None if accel is None else accel[near][:, None], t)  # [M, C] each
    # where each stands at the next stop line, queue included (the planner's prediction)
    to_stop = predicted_stop_distance(veh.s, veh.d, veh.length, veh.width, stop_lines, lap)[near][:, None]
    stands = travel >= to_stop  # False where to_stop is inf (no stop line within reach)
    travel = np.where(stands, to_stop, travel)
    v_c = np.where(stands, 0.0, v_c)
    rear = ds0[near][:, None] + travel - veh.length[near][:, None]  # [M, C] rear bumpers
    s_e = lon.s[:, cols][internals.lon_idx]  # [N, C] front bumper, relative
    v_e = lon.v[:, cols][internals.lon_idx]
    d_e = lat.d[:, cols][internals.lat_idx]
    gap = rear[None] - s_e[:, None, :]  # [N, M, C]
    band = (veh.width[near] + ego_width) / 2 + 0.3  # [M] |d| apart within which a vehicle is in the lane
    same = np.abs(d_e[:, None, :] - veh.d[near][None, :, None]) < band[None, :, None]
    need = (
        sel.follow_headway * v_e[:, None, :]
        + sel.follow_gap
        + np.maximum(v_e[:, None, :] ** 2 - v_c[None] ** 2, 0.0) / (2 * sel.follow_decel)
    )
    # now: the ego's offset (every policy starts at it) and each vehicle's rear ahead of its front
    d_now = lat.d[internals.lat_idx, 0][:, None]  # [N, 1]
    same_now = np.abs(d_now - veh.d[near][None, :]) < band[None, :]
    ahead = _ahead_in_lane(same, gap, same_now & (ds0[near] - veh.length[near] > -BEHIND)[None, :])
    shortfall = np.where(ahead, np.maximum(need - gap, 0.0), 0.0).max(axis=(1, 2))
    # the lead at the horizon (the last check time) in the final lane
    g_end = np.where(ahead[:, :, -1], gap[:, :, -1], np.inf)  # [N, M]
    lead = np.argmin(g_end, axis=1)
    g_lead = g_end[np.arange(n), lead]
    limited = np.maximum(g_lead - sel.follow_gap, 0.0) + v_c[lead, -1] * sel.outlook_time
    outlook = np.where(np.isfinite(g_lead), np.minimum(outlook, limited), outlook)
    return shortfall, outlook


#: [m] a vehicle whose rear is less than this behind the ego's front is still ahead of it
BEHIND = 2.0
#: [m/s^2] a vehicle decelerating harder than this is predicted braking on (``lane_outlook``'s ``accel``)
BRAKING = -1.0


def braking_travel(v: np.ndarray, a: np.ndarray | None, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(travel [M, C] m, speed [M, C] m/s) at the times ``t`` [C] of vehicles at speeds ``v`` [M, 1]: at
    constant speed, or where ``a`` [M, 1] is below ``BRAKING``, braking at ``a`` until they stand."""
    travel, speed = v * t[None, :], np.broadcast_to(v, (len(v), len(t))).copy()
    if a is None:
        return travel, speed
    brake = a < BRAKING
    decel = np.where(brake, -a, 1.0)
    tt = np.minimum(t[None, :], v / decel)  # braking until the stand
    return np.where(brake, v * tt - 0.5 * decel * tt**2, travel), np.where(brake, v - decel * tt, speed)


def _ahead_in_lane(same: np.ndarray, gap: np.ndarray, ahead_now: np.ndarray) -> np.ndarray:
    """[N, M, C] bool: vehicle m is ahead of policy n in its lane at check time c: in the same lane
    (``same``) with its rear bumper less than ``BEHIND`` behind the ego's front (``gap``), or in the same
    lane and ahead of it at the check before (``ahead_now`` [N, M]: now), so that a policy that drives
    into or through the vehicle ahead in its lane keeps it ahead, its gap negative, instead of leaving it
    behind unseen; a vehicle the policy passes in another lane and then drives in front of is behind it."""
    out = np.empty_like(same)
    prev = ahead_now
    for c in range(same.shape[2]):  # the check times (five), not policies
        prev = same[:, :, c] & ((gap[:, :, c] > -BEHIND) | prev)
        out[:, :, c] = prev
    return out
