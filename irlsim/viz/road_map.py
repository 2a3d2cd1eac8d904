"""A picture of a whole scenario: the route's lanes, where it starts and ends, its stop lines, exits and
checkpoints (with their required lanes), on the network around it (``irlsim scenario show``)."""

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
    box = (xs.min() - pad, xs.max() + pad, ys.min() - pad, ys.max() + pad)
    w, h = box[1] - box[0], box[3] - box[2]
    scale = 7.0 / max(w, h)
    fig = new_figure((w * scale + 0.6, h * scale + 0.9))
    ax = axes_in(fig, 0.3, 0.3, w * scale, h * scale)
    for edge in road.net.getEdges():  # the network around the route, thin and grey
        for lane in edge.getLanes():
            pts = np.asarray(lane.getShape())
            inside = (pts[:, 0] > box[0]) & (pts[:, 0] < box[1]) & (pts[:, 1] > box[2]) & (pts[:, 1] < box[3])
            if inside.any():
                ax.plot(pts[:, 0], pts[:, 1], color="0.82", lw=0.6, zorder=1)
    half = road.half_road
    for d in (-half, *(road.lane_centres[1:] - road.lane_width / 2), half):
        x, y = road.to_xy(s, np.full_like(s, d))
        edge = abs(d) == half
        ax.plot(
            x, y, color="0.2" if edge else "0.55", lw=1.0 if edge else 0.5, ls="-" if edge else "--", zorder=2
        )
    for sl in road.stop_lines:
        x, y = road.to_xy(np.full(2, sl.s), np.array([-half, half]))
        ax.plot(x, y, color="crimson", lw=2.5, zorder=3)
    for ex in road.exits:
        x, y = road.to_xy(ex.ramp_s, ex.ramp_d)
        ax.plot(x, y, color="darkorange", lw=1.5, zorder=3)
    for c in road.checkpoints:
        d = float(road.lane_center(c.lane)) if c.lane >= 0 else 0.0
        x, y = road.to_xy(np.array(c.s), np.array(d))
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
    fig.suptitle(title or road.name, fontsize=9)
    return save_figure(fig, path, dpi=130)
