"""A picture of a whole scenario: the route's lanes, where it starts (triangle) and ends (square), its
stop lines (red), traffic lights (green with a yellow dot), exits (orange) and checkpoints (with their
required lanes), on the network around it (``irlsim scenario show``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from irlsim.road import Road
from irlsim.viz.figure import axes_in, new_figure, save_figure


def draw_scenario(road: Road, path: str | Path, title: str = "") -> Path:
    """Draw ``road`` (its route on its network) into a PNG at ``path``; returns the path."""
    lo, hi = road.route_begin_s, (road.route_end_s if not road.closed else road.lap_length)
    s = np.arange(lo, hi + 1.0, 2.0)
    xs, ys = road.to_xy(s, np.zeros_like(s))
    pad = 80.0
    cx, cy = (xs.min() + xs.max()) / 2, (ys.min() + ys.max()) / 2
    hw = max((xs.max() - xs.min()) / 2 + pad, 0.3 * ((ys.max() - ys.min()) / 2 + pad))
    hh = max((ys.max() - ys.min()) / 2 + pad, 0.3 * hw)
    box = (cx - hw, cx + hw, cy - hh, cy + hh)  # never a sliver: the network around a straight route
    w, h = box[1] - box[0], box[3] - box[2]
    scale = 7.0 / max(w, h)
    fig = new_figure((max(w * scale + 0.6, 4.0), h * scale + 0.9))
    ax = axes_in(fig, 0.3, 0.3, w * scale, h * scale)
    for edge in road.net.getEdges():  # the network around the route, thin and grey
        for lane in edge.getLanes():
            pts = np.asarray(lane.getShape())
            inside = (pts[:, 0] > box[0]) & (pts[:, 0] < box[1]) & (pts[:, 1] > box[2]) & (pts[:, 1] < box[3])
            if inside.any():
                ax.plot(pts[:, 0], pts[:, 1], color="0.82", lw=0.6, zorder=1)
    half = road.half_road
    lane_lo, lane_hi = road.lane_bounds(s)
    right, left = road.road_edges(s)  # the lanes that exist at each s (an added lane widens the road)
    for edge_d in (right, left):
        x, y = road.to_xy(s, edge_d)
        ax.plot(x, y, color="0.2", lw=1.0, zorder=2)
    for k in range(road.n_lanes - 1):  # the divider between lanes k and k + 1 where both exist
        both = (lane_lo <= k) & (lane_hi >= k + 1)
        x, y = road.to_xy(s, np.full_like(s, float(road.lane_center(k)) + road.lane_width / 2))
        ax.plot(np.where(both, x, np.nan), y, color="0.55", lw=0.5, ls="--", zorder=2)
    for sl in road.stop_lines:
        x, y = road.to_xy(np.full(2, sl.s), np.array([-half, half]))
        ax.plot(x, y, color="crimson", lw=2.5, zorder=3)
    for g in road.signals:
        x, y = road.to_xy(np.full(2, g.s), np.array([-half, half]))
        ax.plot(x, y, color="darkgreen", lw=2.5, zorder=3)
        ax.plot([float(x.mean())], [float(y.mean())], marker="o", ms=5, color="gold", mec="k", zorder=4)
    for ex in road.exits:
        x, y = road.to_xy(ex.ramp_s, ex.ramp_d)
        ax.plot(x, y, color="darkorange", lw=1.5, zorder=3)
    for c in road.checkpoints:
        dc = float(road.lane_center(c.lane)) if c.lane >= 0 else 0.0
        x, y = road.to_xy(np.array(c.s), np.array(dc))
        ax.plot([float(x)], [float(y)], marker="o", ms=6, color="seagreen", zorder=4)
        ax.annotate(
            f"C{c.index}" + (f" lane {c.lane}" if c.lane >= 0 else ""),
            (float(x), float(y)),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize=7,
            color="seagreen",
        )
    if not road.closed:
        ax.plot([xs[0]], [ys[0]], marker=">", ms=8, color="royalblue", zorder=4)
        ax.plot([xs[-1]], [ys[-1]], marker="s", ms=7, color="royalblue", zorder=4)
    ax.set_xlim(box[0], box[1])
    ax.set_ylim(box[2], box[3])
    ax.set_aspect("equal")
    ax.tick_params(labelsize=6)
    fig.suptitle(title or road.name, fontsize=7, wrap=True)
    return save_figure(fig, path, dpi=130)
