"""Oriented-bounding-box collision test (separating axis theorem), pure numpy, broadcasting.

Vehicles are boxes given by their front-bumper centre (x, y) [m], yaw [rad, ENU], length and width [m],
as SUMO reports positions. All functions broadcast their arguments against each other, so one call
checks an ego against M vehicles, or N x T planned ego states against M predicted vehicles at once.

Boxes that only touch (zero penetration) do not collide; any positive overlap does.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


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
