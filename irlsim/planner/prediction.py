"""How the planner predicts the other vehicles over its horizon, in the route frame: constant speed along
the route at constant d; braking to stand before the next stop line, behind the vehicles queued there; and
a vehicle turning into the route inside a junction along its way into it (its box's ``motion``,
:func:`irlsim.planner.planner.route_frame_boxes`). Shared by the features, the expert's following
check and the cycle pictures."""

from __future__ import annotations

import numpy as np

from irlsim.sim.types import VehicleStates

F32 = np.float32


#: [m] background vehicles heading for a stop line within this distance are predicted to stop
STOP_PREDICTION_REACH = 80.0
#: [m] bumper gap a queued background vehicle keeps to the one ahead (vtypes.add.xml minGap)
QUEUE_GAP = 2.5


def predicted_stop_distance(
    s: np.ndarray,
    d: np.ndarray,
    length: np.ndarray,
    width: np.ndarray,
    stop_lines_s: tuple[float, ...],
    lap: float,
) -> np.ndarray:
    """[M] distance [m] each vehicle (front bumper at wrapped route position ``s``, offset ``d``) still
    travels before it stands at the next stop line, queue included; inf without a stop line within
    ``STOP_PREDICTION_REACH``. A vehicle stands 0.3 m before the line, or ``QUEUE_GAP`` behind the rear of
    the last vehicle queued ahead of it in its lane (the vehicles of its lane between it and the same
    line, each taking its length + QUEUE_GAP): without the queue, a follower is predicted to roll on to
    the line and the gap behind it looks metres larger than it will be."""
    m = len(s)
    if not stop_lines_s or m == 0:
        return np.full(m, np.inf)
    ahead = np.stack([(sl - s) % lap for sl in stop_lines_s]).min(axis=0)  # [M] to the next line
    stops = ahead < STOP_PREDICTION_REACH
    # n is queued before m: same lane, heading for the same line, closer to it
    same_lane = np.abs(d[:, None] - d[None, :]) < (width[:, None] + width[None, :]) / 2
    before = stops[None, :] & (ahead[None, :] < ahead[:, None]) & same_lane  # [m, n]
    queue = (before * (length + QUEUE_GAP)[None, :]).sum(axis=1)
    return np.where(stops, np.maximum(ahead - 0.3 - queue, 0.1), np.inf)


def predicted_motion(
    near: np.ndarray,
    ds0: np.ndarray,
    vehicles: VehicleStates,
    lap: float,
    t: np.ndarray,
    stop_lines_s: tuple[float, ...],
) -> tuple[np.ndarray, np.ndarray]:
    """([M, T], [M, T]) float32: predicted route-frame centre (relative to the ego) and speed of each
    near vehicle: constant speed, or braking at constant deceleration to stand where it will stop before
    the next stop line (:func:`predicted_stop_distance`; SUMO brakes about like that), or, with a
    ``motion``, along its way into the route at its speed."""
    v_m = vehicles.v[near].astype(F32)[:, None]
    travel = v_m * t[None, :]
    speed = np.broadcast_to(v_m, travel.shape)
    # the queue counts every vehicle, not only the near ones
    to_stop = predicted_stop_distance(
        vehicles.s, vehicles.d, vehicles.length, vehicles.width, stop_lines_s, lap
    )[near]
    stops = np.isfinite(to_stop)
    if stops.any():
        dist = np.where(stops, to_stop, 1.0).astype(F32)[:, None]
        b = v_m * v_m / (2 * dist) + F32(1e-3)
        tt = np.minimum(t[None, :], v_m / b)
        braking = np.minimum(v_m * tt - 0.5 * b * tt * tt, dist)
        travel = np.where(stops[:, None], braking, travel)
        speed = np.where(stops[:, None], np.maximum(v_m - b * tt, 0.0), speed)
    centre = ds0[near].astype(F32)[:, None] + travel - vehicles.length[near].astype(F32)[:, None] / 2
    if vehicles.motion is not None:  # along its way into the route, at its speed
        moved = vehicles.motion[near]  # [M, T, 2]
        way = np.isfinite(moved[:, 0, 0])
        start = (ds0[near] - vehicles.length[near] / 2)[way, None]
        centre = np.array(centre, dtype=F32)
        centre[way] = start + moved[way, :, 0]
        speed = np.array(speed, dtype=F32)
        speed[way] = v_m[way]
    return centre.astype(F32), np.ascontiguousarray(speed, dtype=F32)


def predicted_d(vehicles: VehicleStates, near: np.ndarray) -> np.ndarray:
    """[M, 1] float32 the d of each ``near`` vehicle, constant over the horizon; [M, T] where some vehicle
    moves along its way into the route (``motion``)."""
    d = vehicles.d[near][:, None]
    if vehicles.motion is not None:
        d = d + np.nan_to_num(vehicles.motion[near][:, :, 1])
    return d.astype(F32)
