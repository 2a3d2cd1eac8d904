"""Oriented-bounding-box collision test (separating axis theorem), pure numpy, broadcasting.

Vehicles are boxes given by their front-bumper centre (x, y) [m], yaw [rad, ENU], length and width [m],
as SUMO reports positions. All functions broadcast their arguments against each other, so one call
checks an ego against M vehicles, or N x T planned ego states against M predicted vehicles at once.

Boxes that only touch (zero penetration) do not collide; any positive overlap does.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from irlsim.sim.types import EgoState, VehicleStates


def box_centers(
    x: ArrayLike, y: ArrayLike, yaw: ArrayLike, length: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Box centre [m] from the front-bumper centre: half a length back along the heading."""
    half = 0.5 * np.asarray(length, dtype=np.float64)
    return np.asarray(x) - half * np.cos(yaw), np.asarray(y) - half * np.sin(yaw)


def box_corners(
    x: ArrayLike, y: ArrayLike, yaw: ArrayLike, length: ArrayLike, width: ArrayLike
) -> np.ndarray:
    """Corners [..., 4, 2] (front-left, front-right, rear-right, rear-left) of front-bumper boxes."""
    x, y, yaw, length, width = np.broadcast_arrays(
        *(np.asarray(a, dtype=np.float64) for a in (x, y, yaw, length, width))
    )
    c, s = np.cos(yaw), np.sin(yaw)
    lon = np.stack([np.zeros_like(length), np.zeros_like(length), -length, -length], axis=-1)
    lat = np.stack([width / 2, -width / 2, -width / 2, width / 2], axis=-1)
    cx = x[..., None] + lon * c[..., None] - lat * s[..., None]
    cy = y[..., None] + lon * s[..., None] + lat * c[..., None]
    return np.stack([cx, cy], axis=-1)


def obb_penetration(
    ax: ArrayLike,
    ay: ArrayLike,
    ayaw: ArrayLike,
    alen: ArrayLike,
    awid: ArrayLike,
    bx: ArrayLike,
    by: ArrayLike,
    byaw: ArrayLike,
    blen: ArrayLike,
    bwid: ArrayLike,
) -> np.ndarray:
    """Smallest overlap [m] of the two boxes' projections over the 4 separating axes (broadcast shape).

    Positive: the boxes overlap by at least that much on every axis (a collision); <= 0: a separating
    axis exists, and -value is the gap along it (0 = touching). Boxes from front-bumper poses.
    """
    acx, acy = box_centers(ax, ay, ayaw, alen)
    bcx, bcy = box_centers(bx, by, byaw, blen)
    dx, dy = bcx - acx, bcy - acy
    ac, as_ = np.cos(ayaw), np.sin(ayaw)
    bc, bs = np.cos(byaw), np.sin(byaw)
    ahl, ahw = 0.5 * np.asarray(alen), 0.5 * np.asarray(awid)
    bhl, bhw = 0.5 * np.asarray(blen), 0.5 * np.asarray(bwid)
    # cosines between the boxes' axes: a_dir.b_dir, a_dir.b_norm, a_norm.b_dir, a_norm.b_norm
    dd = np.abs(ac * bc + as_ * bs)
    dn = np.abs(-ac * bs + as_ * bc)
    nd = np.abs(-as_ * bc + ac * bs)
    nn = np.abs(as_ * bs + ac * bc)
    # axis a_dir, a_norm, b_dir, b_norm: overlap = ra + rb - |d . u|
    o1 = ahl + bhl * dd + bhw * dn - np.abs(dx * ac + dy * as_)
    o2 = ahw + bhl * nd + bhw * nn - np.abs(-dx * as_ + dy * ac)
    o3 = bhl + ahl * dd + ahw * nd - np.abs(dx * bc + dy * bs)
    o4 = bhw + ahl * dn + ahw * nn - np.abs(-dx * bs + dy * bc)
    return np.minimum(np.minimum(o1, o2), np.minimum(o3, o4))


def obb_collide(
    ax: ArrayLike,
    ay: ArrayLike,
    ayaw: ArrayLike,
    alen: ArrayLike,
    awid: ArrayLike,
    bx: ArrayLike,
    by: ArrayLike,
    byaw: ArrayLike,
    blen: ArrayLike,
    bwid: ArrayLike,
    tol: float = 1e-9,
) -> np.ndarray:
    """True where box a and box b overlap by more than ``tol`` [m] (broadcast shape, bool)."""
    return obb_penetration(ax, ay, ayaw, alen, awid, bx, by, byaw, blen, bwid) > tol


#: [deg] heading difference above which the other vehicle is crossing the ego's path, not going its way
CROSSING_ANGLE = 30.0


def describe_collision(
    ds: float,
    dd: float,
    v_ego: float,
    v_other: float,
    dyaw: float,
    ego_lane: str,
    other_lane: str,
    lane_width: float,
) -> dict[str, float | str]:
    """What a collision was, from the two vehicles at its first step: the other vehicle's route distance
    ``ds`` [m] ahead of the ego (negative: behind), lateral offset ``dd`` [m] from it (left positive), both
    speeds [m/s], the heading difference ``dyaw`` [rad] and both SUMO lane ids (a junction's start
    with ':'). ``kind`` is one of: crossing (headings differ by more than CROSSING_ANGLE: a junction's
    foe or a vehicle turning across), rear-ended (the other came from behind, in the ego's lane, faster),
    ran-into (the other ahead, in the ego's lane), side (beside, in the next lane: one of them changing
    lanes). ``where`` is 'junction' when either is on a junction's internal lane, else 'lane'."""
    angle = abs(math.degrees(math.atan2(math.sin(dyaw), math.cos(dyaw))))
    same_lane = abs(dd) < 0.5 * lane_width
    if angle > CROSSING_ANGLE:
        kind = "crossing"
    elif same_lane and ds < 0.0:
        kind = "rear-ended" if v_other > v_ego else "side"
    elif same_lane:
        kind = "ran-into"
    else:
        kind = "side"
    where = "junction" if ego_lane.startswith(":") or other_lane.startswith(":") else "lane"
    return {
        "kind": kind,
        "where": where,
        "ds_m": round(float(ds), 2),
        "dd_m": round(float(dd), 2),
        "v_ego_ms": round(float(v_ego), 2),
        "v_other_ms": round(float(v_other), 2),
        "angle_deg": round(angle, 1),
        "ego_lane": ego_lane,
        "other_lane": other_lane,
    }


def first_collision(
    ego: EgoState, veh: VehicleStates, i: int, lanes: tuple[str, str], lap: float, lane_width: float
) -> dict[str, Any]:
    """The collision of the ego with vehicle ``i`` of ``veh`` (``lanes``: both SUMO lane ids) as
    :func:`describe_collision` records it, with the time and the other vehicle's id."""
    ds = (float(veh.s[i]) - ego.s + lap / 2) % lap - lap / 2  # [m] route distance, wrapped on a loop
    dd, dyaw = float(veh.d[i]) - ego.d, float(veh.yaw[i]) - ego.yaw
    c = describe_collision(ds, dd, ego.v, float(veh.v[i]), dyaw, *lanes, lane_width)
    return {"t": ego.t, "other": veh.ids[i], **c}


def collision_line(c: dict[str, Any]) -> str:
    """:func:`describe_collision`'s record as one line for a table: what, where, the two speeds."""
    return (
        f"{c['kind']} at a {c['where']} ({c['other']}, {c['ds_m']:+.1f} m along, {c['dd_m']:+.1f} m across, "
        f"{c['angle_deg']:.0f} deg; ego {c['v_ego_ms']:.1f} m/s on {c['ego_lane']}, other "
        f"{c['v_other_ms']:.1f} m/s on {c['other_lane']})"
    )
