"""One planning cycle as a picture: policies on the road coloured by value, the chosen one, vehicles.

``draw_cycle(ax, road, ps, value, ...)`` is reusable: the drive stage passes ``highlight`` (e.g. the
highest-attention policies) to draw them in blue on top.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.planner.policy_set import PolicySet
from irlsim.road import HALF_ROAD, LANE_WIDTH, Road
from irlsim.sim.types import VehicleStates


def _box(x: float, y: float, yaw: float, length: float, width: float) -> np.ndarray:
    """Corners [5, 2] of a box whose front-bumper centre is (x, y)."""
    c, s = np.cos(yaw), np.sin(yaw)
    loc = np.array(
        [[0, -width / 2], [0, width / 2], [-length, width / 2], [-length, -width / 2], [0, -width / 2]]
    )
    return np.stack([x + loc[:, 0] * c - loc[:, 1] * s, y + loc[:, 0] * s + loc[:, 1] * c], axis=1)


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
    """Draw road lines around the ego, policies coloured by ``value`` [N] (green high, red low), the
    ``chosen`` policy (thick black), ``highlight`` indices (blue), vehicles and their constant-velocity
    predictions over ``horizon`` seconds (route frame, constant d)."""
    from matplotlib import cm
    from matplotlib.collections import LineCollection

    s0 = float(ps.s[0, 0])
    s_line = s0 + np.linspace(-60.0, max(ps.s[:, -1].max() - s0, 20.0) + 40.0, 200)
    for d in np.arange(-HALF_ROAD, HALF_ROAD + 1e-6, LANE_WIDTH):
        x, y = road.to_xy(s_line, np.full_like(s_line, d))
        edge = abs(abs(d) - HALF_ROAD) < 1e-6
        ax.plot(
            x, y, color="0.3" if edge else "0.7", lw=1.2 if edge else 0.8, ls="-" if edge else "--", zorder=1
        )
    for ex in road.exits:
        rs = (ex.ramp_s - s0 + road.lap_length / 2) % road.lap_length - road.lap_length / 2 + s0
        if np.any(np.abs(rs - s0) < 200):
            x, y = road.to_xy(rs, ex.ramp_d)
            ax.plot(x, y, color="0.5", lw=6, alpha=0.3, zorder=1)
    idx = np.arange(ps.n_policies)
    if len(idx) > max_drawn:
        idx = idx[np.linspace(0, len(idx) - 1, max_drawn).astype(int)]
    v = np.asarray(value, dtype=np.float64)[idx]
    lo, hi = np.percentile(v, 5), np.percentile(v, 100)
    norm = np.clip((v - lo) / max(hi - lo, 1e-9), 0, 1)
    order = np.argsort(norm)  # best drawn last (on top)
    segs = np.stack([ps.x[idx[order]], ps.y[idx[order]]], axis=2)
    ax.add_collection(
        LineCollection(list(segs), colors=cm.RdYlGn(norm[order]), linewidths=0.6, alpha=0.6, zorder=2)
    )
    if highlight is not None and len(highlight):
        hs = np.stack([ps.x[highlight], ps.y[highlight]], axis=2)
        ax.add_collection(LineCollection(list(hs), colors="tab:blue", linewidths=1.2, alpha=0.9, zorder=3))
    if chosen is not None:
        ax.plot(ps.x[chosen], ps.y[chosen], color="k", lw=2.2, zorder=4, label="executed")
    ax.fill(*_box(ps.x[0, 0], ps.y[0, 0], ps.yaw[0, 0], *ego_size).T, color="tab:blue", zorder=5, label="ego")
    if vehicles is not None and vehicles.count:
        t = np.linspace(0.0, horizon, 11)
        for k in range(vehicles.count):
            ds = (
                vehicles.s[k] - s0 % road.lap_length + road.lap_length / 2
            ) % road.lap_length - road.lap_length / 2
            if not -60 < ds < 200:
                continue
            sp = s0 + ds + vehicles.v[k] * t
            px, py = road.to_xy(sp, np.full_like(sp, vehicles.d[k]))
            ax.plot(px, py, color="tab:purple", lw=1.0, ls=":", zorder=3)
            ax.fill(
                *_box(vehicles.x[k], vehicles.y[k], vehicles.yaw[k], vehicles.length[k], vehicles.width[k]).T,
                color="0.25",
                zorder=5,
            )
    ax.set_aspect("equal")
    ax.set_xlim(ps.x.min() - 15, ps.x.max() + 15)
    ax.set_ylim(ps.y.min() - 15, ps.y.max() + 15)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
