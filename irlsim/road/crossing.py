"""Where a route's line comes back near itself (``Road.flat``) and whether it crosses itself away from
any junction (a bridge or tunnel, refused): pure functions over the line, once when a road is built."""

from __future__ import annotations

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.road.route import ReferenceShape

#: [m] a route's line meets itself only between points at least this far apart along it (a tight turn's
#: offset line may loop locally); the resampling step [m] of the test
CROSSING_MIN_APART = 50.0
CROSSING_STEP = 1.0


def self_crossing(pts: np.ndarray, closed: bool, gap: float) -> tuple[float, float] | None:
    """(x, y) where the polyline ``pts`` [P, 2] comes within ``gap`` [m] of itself (the route through the
    same junction twice, over or under itself, or running back on the other carriageway), or None."""
    hits = near_pairs(pts, closed, gap, first=True)
    return None if not len(hits) else (float(hits[0, 2]), float(hits[0, 3]))


def near_pairs(pts: np.ndarray, closed: bool, gap: float, first: bool = False) -> np.ndarray:
    """[H, 4] (arc length [m] of one point, of the other, x, y) of the points of the polyline ``pts``
    [P, 2], sampled every CROSSING_STEP, that lie within ``gap`` [m] of each other (only the first with
    ``first``). Points closer than CROSSING_MIN_APART along the line are not compared. Vectorised in
    blocks of points (once, when a road is built)."""
    p = np.vstack([pts, pts[:1]]) if closed else pts
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    t = np.concatenate([[0.0], np.cumsum(seg)])
    u = np.arange(0.0, t[-1], CROSSING_STEP)
    q = np.stack([np.interp(u, t, p[:, 0]), np.interp(u, t, p[:, 1])], axis=1)
    n = len(q)
    apart = int(CROSSING_MIN_APART / CROSSING_STEP)
    lap = n if closed else 2 * n
    out = []
    for lo in range(0, n, 256):
        i = np.arange(lo, min(lo + 256, n))[:, None]
        sep = np.abs(i - np.arange(n)[None, :])
        far = np.minimum(sep, lap - sep) >= apart  # [B, n]
        dist = np.hypot(q[i, 0] - q[None, :, 0], q[i, 1] - q[None, :, 1])
        hit = np.argwhere(far & (dist < gap))
        if len(hit):
            a, b = lo + hit[:, 0], hit[:, 1]
            out.append(np.stack([u[a], u[b], q[a, 0], q[a, 1]], axis=1))
            if first:
                break
    return np.concatenate(out) if out else np.zeros((0, 4))


#: [m] two passes of the route this close cross each other (at a junction, or on different levels)
CROSSING_GAP = 1.0


def check_same_level(shape: ReferenceShape, closed: bool) -> None:
    """A one-line IrlsimError where the route crosses itself away from any junction both passes touch:
    over a bridge or through a tunnel (SUMO's networks carry no heights for irlsim to tell the levels
    apart), where the vehicles of the other level would overlap the ego in the plane. A route through
    the same junction twice, or back alongside itself, passes."""
    hits = near_pairs(shape.points, closed, CROSSING_GAP)
    if not len(hits):
        return
    piece = np.searchsorted(shape.piece_arcs, hits[:, :2], side="right") - 1  # [H, 2]
    for (a, b), (x, y) in zip(piece, hits[:, 2:], strict=True):
        if not shape.piece_nodes[a] & shape.piece_nodes[b]:
            raise IrlsimError(
                f"route: it crosses itself without a junction near ({x:.0f}, {y:.0f}) (over a bridge or "
                "through a tunnel): vehicles of the other level would overlap the ego; end the route before "
                "it does"
            )
