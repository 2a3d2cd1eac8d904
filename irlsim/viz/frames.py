"""Pictures of closed-loop driving (``irlsim drive``): one planning cycle from above, the temporal attention,
and an animation of an episode segment with the radar chart of theta.

Everything here is a pure function of a :class:`CycleFrame` (plain arrays, no SUMO, no road object), so it
is testable on synthetic data. Matplotlib's Agg canvas is used through ``matplotlib.figure.Figure``
(never pyplot), so drawing needs no display and keeps no global state. Files are written atomically.

The cycle picture follows the paper's Fig. 1: policies coloured by value from red (low) to green (high),
the colour being the policy's value *rank* among all N policies of the cycle (values of a learned reward
span orders of magnitude; ranks keep the gradient readable); the top-k policies by policy attention in
blue; the executed policy in black. Only a subset of the policies is drawn (``CycleFrame`` keeps at most
a few hundred), as in the paper. :func:`draw_policies` draws such a scene from plain arrays; ``irlsim
plot-cycle`` (:mod:`irlsim.viz.cycle`) uses it too.

Layout (why the figure height is computed): the scene is drawn to scale (equal aspect) in a window fitted
to the road and the drawn policies (:func:`scene_window`), about 90 m x 12 m at speed. A fixed figure
shape would leave most of its height empty, so the figures' heights follow the window
(:func:`cycle_figure_size`); an animation uses one window, the union over its frames, so its axes stay put.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.viz.figure import axes_in, new_figure, save_figure
from irlsim.viz.radar import draw_radar, save_radar
from irlsim.viz.scene import CycleFrame, Window, cycle_window, fit_window, view_scene

#: line kinds of :attr:`CycleFrame.lines` and how they are drawn
LINE_STYLE = {
    "edge": {"color": "0.3", "lw": 1.4, "ls": "-"},
    "divider": {"color": "0.55", "lw": 1.0, "ls": (0, (5, 5))},
    "ramp": {"color": "0.45", "lw": 1.0, "ls": "-"},
    "stop": {"color": "#b00000", "lw": 3.0, "ls": "-"},
}

#: font sizes [pt]: legible at 100 dpi in the stills and at 70 dpi in the GIF (10-inch-wide figures)
FONT = {"title": 13.0, "label": 11.0, "tick": 10.0, "legend": 10.0}

#: the highest-attention policies: a saturated blue, distinct from every colour of the value map
TOP_COLOR = "#1d4ed8"
VEHICLE_COLOR = "0.45"
PREDICTION_COLOR = "#7e22ce"
EGO_COLOR = "tab:orange"

#: figure margins around the cycle axes [in]: left (y label), right (colour bar), top (title), bottom
#: (x label, then the legend row)
_MARGIN = {"left": 0.8, "right": 1.05, "top": 0.45, "bottom": 0.95}
#: [in] from the axes' bottom edge down to the legend row (below the tick labels and the x label)
_LEGEND_DROP = 0.55


def cycle_figure_size(window: Window, width: float = 10.0) -> tuple[float, float]:
    """(width, height) [in] of a figure holding only the cycle axes: the axes keep the window's aspect."""
    w = width - _MARGIN["left"] - _MARGIN["right"]
    # whole tenths of an inch: an integer number of pixels at any dpi that is a multiple of 10
    return width, round(_MARGIN["top"] + w * window.aspect + _MARGIN["bottom"], 1)


def cycle_axes(fig: Any, window: Window, top: float = 0.0) -> Any:
    """The cycle axes on ``fig``: full width between the margins, as tall as the window's aspect needs,
    ``top`` [in] below the figure's top edge."""
    fw, fh = fig.get_size_inches()
    w = fw - _MARGIN["left"] - _MARGIN["right"]
    h = w * window.aspect
    return axes_in(fig, _MARGIN["left"], fh - top - _MARGIN["top"] - h, w, h)


# size-ok: one matplotlib scene; its drawing order (road, policies, vehicles, ego) is the z-order
def draw_policies(
    ax: Any,
    x: np.ndarray,
    y: np.ndarray,
    value_rank: np.ndarray,
    top: np.ndarray,
    chosen: int | None,
    ego: Sequence[float],
    vehicles: np.ndarray,
    lines: Sequence[tuple[str, np.ndarray]] = (),
    view_yaw: float | None = None,
    predictions: np.ndarray | None = None,
    *,
    window: Window | None = None,
    view: float = 40.0,
    title: str | None = None,
    legend: bool = True,
    colorbar: bool = True,
) -> Window:
    """One planning cycle from above on ``ax``; the one drawing of policy sets (drive stage and plot-cycle).

    x, y [P, T] world positions of the drawn policies; value_rank [P] in [0, 1] (red low, green high);
    top [P] bool, the highest-attention policies (blue); chosen: the executed policy (black); ego
    (x, y, yaw, v, length, width) with x, y the front bumper; vehicles [M, 5] (x, y, yaw, length, width);
    lines (kind, [Q, 2] world xy) road lines; predictions [M, K, 3] (x, y, yaw) of the vehicles, dotted.

    Drawn around the ego (origin) in the view frame: ``view_yaw`` (the road's heading at the ego; None =
    the ego's yaw) points right. Layers, bottom to top: road, policies by value (best last), the top
    policies (thick blue, with their end points), the executed one (black), vehicles, predictions, ego.
    The window is ``window``, or fitted (:func:`scene_window`); equal aspect. Returns the window.
    """
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize

    sc = view_scene(x, y, ego, vehicles, lines, view_yaw, predictions)
    win = window or fit_window(sc, view)
    for kind, xy in sc.lines:
        st = LINE_STYLE.get(kind, LINE_STYLE["edge"])
        ax.plot(xy[:, 0], xy[:, 1], color=st["color"], lw=st["lw"], ls=st["ls"], zorder=1)
    segs = np.stack([sc.px, sc.py], axis=-1)  # [P, T, 2]
    cmap = colormaps["RdYlGn"]
    rank = np.asarray(value_rank, dtype=np.float64)
    order = np.argsort(rank, kind="stable")  # high values drawn last (on top)
    ax.add_collection(
        LineCollection(list(segs[order]), colors=cmap(rank[order]), linewidths=0.8, alpha=0.75, zorder=2)
    )
    handles = []
    top_idx = np.flatnonzero(np.asarray(top, dtype=bool))
    if len(top_idx):
        # above every value-coloured policy and thicker than the executed one, so a top policy on the
        # executed path still shows as a blue band around the black line; the end points tell apart
        # policies that share a path at different speeds
        ax.add_collection(
            LineCollection(list(segs[top_idx]), colors=TOP_COLOR, linewidths=3.2, zorder=4, capstyle="round")
        )
        ax.scatter(segs[top_idx, -1, 0], segs[top_idx, -1, 1], s=30, color=TOP_COLOR, zorder=4, lw=0)
        label = f"top-{len(top_idx)} attention"
        handles.append(ax.plot([], [], color=TOP_COLOR, lw=3.2, marker="o", ms=5, label=label)[0])
    if chosen is not None:
        ch = segs[chosen]
        ax.plot(ch[:, 0], ch[:, 1], color="black", lw=1.8, zorder=5, solid_capstyle="round")
        ax.plot(ch[-1, 0], ch[-1, 1], "o", color="black", ms=5, zorder=5)
        handles.append(ax.plot([], [], color="black", lw=1.8, marker="o", ms=5, label="executed")[0])
    for b in sc.boxes:
        ax.fill(b[:, 0], b[:, 1], color=VEHICLE_COLOR, ec="0.1", lw=0.8, zorder=6)
    if len(sc.boxes):
        handles.append(
            ax.plot([], [], ls="none", marker="s", ms=10, mfc=VEHICLE_COLOR, mec="0.1", label="vehicle")[0]
        )
    if sc.pred is not None and sc.pred_boxes is not None:
        for path, b in zip(sc.pred, sc.pred_boxes, strict=True):
            ax.plot(path[:, 0], path[:, 1], color=PREDICTION_COLOR, lw=1.6, ls=":", zorder=6)
            ax.plot(b[:, 0], b[:, 1], color=PREDICTION_COLOR, lw=1.2, ls="--", zorder=6)
        handles.append(
            ax.plot([], [], color=PREDICTION_COLOR, lw=1.6, ls=":", label="predicted (end: dashed box)")[0]
        )
    ax.fill(sc.ego_box[:, 0], sc.ego_box[:, 1], color=EGO_COLOR, ec="black", lw=1.0, zorder=7)
    handles.append(ax.plot([], [], ls="none", marker="s", ms=10, mfc=EGO_COLOR, mec="black", label="ego")[0])
    ax.set_xlim(win.x0, win.x1)
    ax.set_ylim(win.y0, win.y1)
    ax.set_aspect("equal")
    ax.set_xlabel("along the road from the ego [m]", fontsize=FONT["label"])
    ax.set_ylabel("left [m]", fontsize=FONT["label"])
    ax.tick_params(labelsize=FONT["tick"])
    if legend:
        # one row under the x label (a fixed offset in inches, whatever the axes' height): the road
        # stays uncovered, and a caller's own title (default pad) does not collide with it
        from matplotlib.transforms import ScaledTranslation

        below = ax.transAxes + ScaledTranslation(0.0, -_LEGEND_DROP, ax.figure.dpi_scale_trans)
        ax.legend(
            handles=handles,
            loc="upper left",
            bbox_to_anchor=(0.0, 0.0),
            bbox_transform=below,
            ncol=len(handles),
            fontsize=FONT["legend"],
            frameon=False,
            borderaxespad=0.0,
            handlelength=2.2,
            columnspacing=1.4,
        )
    if title:
        ax.set_title(title, fontsize=FONT["title"])
    if colorbar:
        # an inset axes follows the axes box after the equal-aspect adjustment, whatever the caller's layout
        cax = ax.inset_axes((1.01, 0.0, 0.015, 1.0))
        cb = ax.figure.colorbar(ScalarMappable(Normalize(0.0, 1.0), cmap), cax=cax, ticks=[0.0, 1.0])
        cb.ax.set_yticklabels(["low", "high"], fontsize=FONT["tick"])
        cb.set_label("value", fontsize=FONT["label"], labelpad=-6.0)
    return win


def draw_cycle(
    ax: Any, frame: CycleFrame, view: float = 40.0, legend: bool = True, window: Window | None = None
) -> Window:
    """A frame's cycle on axes ``ax`` (:func:`draw_policies`); ``window`` fixed, or fitted with at least
    ``view`` [m] ahead. Returns the window."""
    return draw_policies(
        ax,
        frame.x,
        frame.y,
        frame.value_rank,
        frame.top_attention,
        frame.chosen,
        frame.ego,
        frame.vehicles,
        frame.lines,
        frame.view_yaw,
        frame.predictions,
        window=window,
        view=view,
        title=frame.title,
        legend=legend,
    )


def draw_temporal(ax: Any, weights: np.ndarray | None, model: str = "") -> None:
    """Bar chart of the temporal attention weights [H] (oldest first; the last bar is the current cycle)."""
    ax.set_title("temporal attention", fontsize=FONT["title"])
    if weights is None or len(weights) == 0:
        ax.text(
            0.5,
            0.5,
            f"no temporal attention\n({model or 'this model'} has none)",
            ha="center",
            va="center",
            fontsize=FONT["label"],
            transform=ax.transAxes,
        )
        ax.set_xticks([])
        ax.set_yticks([])
        return
    w = np.asarray(weights, dtype=np.float64)
    h = len(w)
    lags = np.arange(-(h - 1), 1)
    ax.bar(lags, w, color="tab:purple", width=0.8)
    ax.set_xticks(lags)
    ax.set_xticklabels([str(k) if k else "now" for k in lags], fontsize=FONT["tick"])
    ax.set_xlabel("history [cycles before now]", fontsize=FONT["label"])
    ax.set_ylabel("weight", fontsize=FONT["label"])
    ax.set_ylim(0.0, max(1.0 / h * 1.5, float(w.max()) * 1.1))
    ax.axhline(1.0 / h, color="0.4", lw=1.0, ls="--", label="uniform")
    ax.legend(loc="best", fontsize=FONT["legend"], frameon=False)
    ax.tick_params(labelsize=FONT["tick"])


# ------------------------------------------------------------------------------------------ files


def save_cycle(path: str | Path, frame: CycleFrame, dpi: int = 100) -> Path:
    """``cycle_XXXX.png``: the policy set from above, 10 in wide, as tall as its window needs
    (:func:`cycle_figure_size`)."""
    win = cycle_window(frame)
    fig = new_figure(cycle_figure_size(win))
    draw_cycle(cycle_axes(fig, win), frame, window=win)
    return save_figure(fig, path, dpi)


def save_temporal(path: str | Path, frame: CycleFrame, dpi: int = 100) -> Path:
    """``temporal_XXXX.png``: the temporal attention weights (6 x 3.6 in)."""
    fig = new_figure((6.0, 3.6))
    draw_temporal(fig.add_subplot(111), frame.temporal_weights, frame.model)
    fig.tight_layout()
    return save_figure(fig, path, dpi)


def save_frame_pictures(
    out_dir: str | Path, frame: CycleFrame, reference: np.ndarray | None = None, dpi: int = 100
) -> list[Path]:
    """The three stills of one cycle: cycle_XXXX.png, radar_XXXX.png, temporal_XXXX.png (XXXX = cycle)."""

    out = Path(out_dir)
    tag = f"{frame.cycle:04d}"
    return [
        save_cycle(out / f"cycle_{tag}.png", frame, dpi),
        save_radar(
            out / f"radar_{tag}.png",
            frame.theta,
            reference=reference,
            title=f"{frame.model}: predicted theta, cycle {frame.cycle}",
            dpi=dpi,
        ),
        save_temporal(out / f"temporal_{tag}.png", frame, dpi),
    ]


#: height [in] of the animation's bottom row (radar and temporal attention)
_PANEL_ROW = 4.6


def panels_figure_size(window: Window, width: float = 10.0) -> tuple[float, float]:
    """(width, height) [in] of the animation's figure: the cycle (its window's aspect) over a row of
    :data:`_PANEL_ROW` inches."""
    w, h = cycle_figure_size(window, width)
    return w, round(h + _PANEL_ROW, 1)


def draw_panels(
    fig: Any, frame: CycleFrame, reference: np.ndarray | None = None, window: Window | None = None
) -> None:
    """The animation's layout on ``fig`` (sized by :func:`panels_figure_size`): the cycle from above (top,
    full width, in ``window`` or its own), radar of theta (bottom left), temporal attention (bottom right)."""

    fig.clear()
    win = window or cycle_window(frame)
    draw_cycle(cycle_axes(fig, win), frame, window=win)
    row = _PANEL_ROW
    radar = axes_in(fig, 1.35, 0.55, row - 1.45, row - 1.45, projection="polar")
    draw_radar(radar, frame.theta, reference=reference, title="theta")
    draw_temporal(axes_in(fig, 6.0, 0.75, 3.7, row - 1.55), frame.temporal_weights, frame.model)


def save_animation(
    path: str | Path,
    frames: Sequence[CycleFrame],
    reference: np.ndarray | None = None,
    fps: int = 5,
    dpi: int = 70,
    width: float = 10.0,
) -> Path:
    """``episode.gif``: the panels of every frame, ``fps`` frames per second (matplotlib PillowWriter).

    One window for all frames (the union of their windows), so the road does not jump between frames;
    the figure is ``width`` inches wide and as tall as :func:`panels_figure_size` says. Written to a
    temporary ``.gif`` beside ``path`` and renamed, so a killed run leaves no half file.
    """
    from matplotlib.animation import PillowWriter

    if not frames:
        raise ValueError("save_animation needs at least one frame")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.partial.gif")
    win = cycle_window(frames[0])
    for fr in frames[1:]:
        win = win.union(cycle_window(fr))
    fig = new_figure(panels_figure_size(win, width))
    writer = PillowWriter(fps=fps)
    try:
        with writer.saving(fig, str(tmp), dpi):
            for fr in frames:
                draw_panels(fig, fr, reference, win)
                writer.grab_frame()
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path
