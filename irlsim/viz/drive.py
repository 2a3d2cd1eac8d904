"""Pictures of closed-loop driving (``irlsim drive``): one planning cycle from above, the temporal attention,
and an animation of an episode segment with the radar chart of theta.

Everything here is a pure function of a :class:`CycleFrame` (plain arrays, no SUMO, no road object), so it
is testable on synthetic data. Matplotlib's Agg canvas is used through ``matplotlib.figure.Figure``
(never pyplot), so drawing needs no display and keeps no global state. Files are written atomically.

The cycle picture follows the paper's Fig. 1: policies coloured by value from red (low) to green (high),
the colour being the policy's value *rank* among all N policies of the cycle (values of a learned reward
span orders of magnitude; ranks keep the gradient readable); the top-k policies by policy attention in
blue; the executed policy in black. Only a subset of the policies is drawn (``CycleFrame`` keeps at most
a few hundred), as in the paper.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES

#: line kinds of :attr:`CycleFrame.lines` and how they are drawn
LINE_STYLE = {
    "edge": {"color": "0.35", "lw": 1.2, "ls": "-"},
    "divider": {"color": "0.6", "lw": 0.8, "ls": (0, (4, 4))},
    "ramp": {"color": "0.5", "lw": 0.9, "ls": "-"},
    "stop": {"color": "tab:red", "lw": 2.0, "ls": "-"},
}


@dataclass(frozen=True)
class CycleFrame:
    """What the pictures of one planning cycle need. P drawn policies (a subset of the cycle's N), T states.

    x, y:            [P, T] float32  world positions of the drawn policies [m]
    value_rank:      [P] float32     value rank among all N policies of the cycle, 0 = lowest, 1 = highest
    top_attention:   [P] bool        among the cycle's top-k policies by policy attention
    chosen:          index (into P) of the executed policy
    theta:           [15] float64    the reward weights that scored the cycle
    attention:       [P] float32 or None  policy attention of the drawn policies (PACNN family)
    temporal_weights: [H] float64 or None  temporal attention over the history, oldest first (PTACNN)
    ego:             (x [m], y [m], yaw [rad], v [m/s], length [m], width [m]); x, y = front bumper
    vehicles:        [M, 5] float64  (x, y, yaw, length, width) of the other vehicles, front bumpers
    lines:           road lines around the ego: (kind in LINE_STYLE, [Q, 2] xy)
    view_yaw:        [rad] direction drawn to the right: the road's heading at the ego (None: ego's yaw)
    """

    model: str
    cycle: int
    t: float
    x: np.ndarray
    y: np.ndarray
    value_rank: np.ndarray
    top_attention: np.ndarray
    chosen: int
    theta: np.ndarray
    ego: tuple[float, float, float, float, float, float]
    vehicles: np.ndarray
    attention: np.ndarray | None = None
    temporal_weights: np.ndarray | None = None
    lines: tuple[tuple[str, np.ndarray], ...] = ()
    info: dict[str, Any] = field(default_factory=dict)
    view_yaw: float | None = None

    def __post_init__(self) -> None:
        p, t = self.x.shape
        assert self.y.shape == (p, t), f"y: {self.y.shape} != {(p, t)}"
        assert self.value_rank.shape == (p,) and self.top_attention.shape == (p,)
        assert 0 <= self.chosen < p, f"chosen {self.chosen} not in [0, {p})"
        assert self.theta.shape == (len(FEATURE_NAMES),), self.theta.shape
        assert self.vehicles.ndim == 2 and self.vehicles.shape[1] == 5, self.vehicles.shape
        if self.attention is not None:
            assert self.attention.shape == (p,), self.attention.shape


# ------------------------------------------------------------------------------------------ figure plumbing


def new_figure(size: tuple[float, float]) -> Any:
    """A matplotlib Figure on an Agg canvas (no pyplot, no display)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Any, path: str | Path, dpi: int = 100) -> Path:
    """Save ``fig`` as PNG atomically (temporary file beside ``path``, then rename)."""
    from irlsim.utils import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
        os.chmod(tmp, 0o644)  # mkstemp makes it private; pictures are for everyone
    return path


# ------------------------------------------------------------------------------------------ drawing


def _box(x: float, y: float, yaw: float, length: float, width: float) -> np.ndarray:
    """Corners [5, 2] (closed) of a box whose *front-bumper centre* is (x, y)."""
    c, s = math.cos(yaw), math.sin(yaw)
    cx, cy = x - 0.5 * length * c, y - 0.5 * length * s
    hl, hw = 0.5 * length, 0.5 * width
    local = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw], [hl, hw]])
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.array([cx, cy])


def draw_cycle(ax: Any, frame: CycleFrame, view: float = 70.0, legend: bool = True) -> None:
    """The cycle from above on axes ``ax``: road, vehicles, policies by value, attention, executed policy.

    Drawn around the ego (at the origin) rotated so that ``frame.view_yaw`` (the road's heading there)
    points right: x ahead along the road, y to the left, so the lanes run left to right. ``view`` [m]: the
    window covers every drawn policy and at least view/4 behind and view ahead of the ego.
    """
    from matplotlib import colormaps
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D

    ex, ey, eyaw, ev, el, ew = frame.ego
    vyaw0 = eyaw if frame.view_yaw is None else frame.view_yaw
    c, s = math.cos(vyaw0), math.sin(vyaw0)

    def local(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # world -> view frame (x along the road, y left), so the road runs left to right
        dx, dy = np.asarray(x, dtype=np.float64) - ex, np.asarray(y, dtype=np.float64) - ey
        return c * dx + s * dy, -s * dx + c * dy

    for kind, xy in frame.lines:
        st = LINE_STYLE.get(kind, LINE_STYLE["edge"])
        lx, ly = local(xy[:, 0], xy[:, 1])
        ax.plot(lx, ly, color=st["color"], lw=st["lw"], ls=st["ls"], zorder=1)
    px, py = local(frame.x, frame.y)
    segs = np.stack([px, py], axis=-1)  # [P, T, 2]
    cmap = colormaps["RdYlGn"]
    order = np.argsort(frame.value_rank, kind="stable")  # high values drawn last (on top)
    ax.add_collection(
        LineCollection(
            list(segs[order]), colors=cmap(frame.value_rank[order]), linewidths=0.7, alpha=0.8, zorder=2
        )
    )
    top = np.flatnonzero(frame.top_attention)
    if len(top):
        ax.add_collection(
            LineCollection(list(segs[top]), colors="tab:blue", linewidths=1.6, alpha=0.95, zorder=3)
        )
    ch = segs[frame.chosen]
    ax.plot(ch[:, 0], ch[:, 1], color="white", lw=4.0, zorder=4, solid_capstyle="round")
    ax.plot(ch[:, 0], ch[:, 1], color="black", lw=2.0, zorder=5, solid_capstyle="round")
    for vx, vy, vyaw, vl, vw in frame.vehicles:
        lx, ly = local(vx, vy)
        b = _box(float(lx), float(ly), vyaw - vyaw0, vl, vw)
        ax.fill(b[:, 0], b[:, 1], color="0.45", ec="0.15", lw=0.6, zorder=6)
    b = _box(0.0, 0.0, eyaw - vyaw0, el, ew)
    ax.fill(b[:, 0], b[:, 1], color="tab:orange", ec="black", lw=0.8, zorder=7)
    # window: every drawn policy, at least view/4 behind and view ahead, +-view/4 sideways
    x0 = min(float(px.min()), -view / 4) - 5.0
    x1 = max(float(px.max()), view) + 5.0
    yh = max(float(np.abs(py).max()), 8.0) + 4.0
    ax.set_xlim(x0, x1)
    ax.set_ylim(-yh, yh)
    ax.set_aspect("equal")
    ax.set_xlabel("along the road from the ego [m]", fontsize=7)
    ax.set_ylabel("left [m]", fontsize=7)
    ax.tick_params(labelsize=6)
    ax.set_title(
        f"{frame.model}  cycle {frame.cycle}  t = {frame.t:.1f} s  v = {3.6 * ev:.0f} km/h", fontsize=8
    )
    if legend:
        handles = [
            Line2D([], [], color=cmap(1.0), lw=1.5, label="high value"),
            Line2D([], [], color=cmap(0.0), lw=1.5, label="low value"),
            Line2D([], [], color="black", lw=2.0, label="executed"),
        ]
        if len(top):
            handles.insert(2, Line2D([], [], color="tab:blue", lw=1.6, label=f"top-{len(top)} attention"))
        ax.legend(handles=handles, loc="upper right", fontsize=6, framealpha=0.8)


def draw_temporal(ax: Any, weights: np.ndarray | None, model: str = "") -> None:
    """Bar chart of the temporal attention weights [H] (oldest first; the last bar is the current cycle)."""
    ax.set_title("temporal attention", fontsize=8)
    if weights is None or len(weights) == 0:
        ax.text(
            0.5,
            0.5,
            f"no temporal attention\n({model or 'this model'} has none)",
            ha="center",
            va="center",
            fontsize=7,
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
    ax.set_xticklabels([str(k) if k else "t" for k in lags], fontsize=6)
    ax.set_xlabel("history [cycles before now]", fontsize=7)
    ax.set_ylabel("weight", fontsize=7)
    ax.set_ylim(0.0, max(1.0 / h * 1.5, float(w.max()) * 1.1))
    ax.axhline(1.0 / h, color="0.5", lw=0.8, ls="--")  # uniform weights
    ax.tick_params(labelsize=6)


# ------------------------------------------------------------------------------------------ files


def save_cycle(path: str | Path, frame: CycleFrame, dpi: int = 100) -> Path:
    """``cycle_XXXX.png``: the policy set from above (10 x 3.6 in)."""
    fig = new_figure((10.0, 3.6))
    draw_cycle(fig.add_subplot(111), frame)
    fig.tight_layout()
    return save_figure(fig, path, dpi)


def save_temporal(path: str | Path, frame: CycleFrame, dpi: int = 100) -> Path:
    """``temporal_XXXX.png``: the temporal attention weights (5 x 3 in)."""
    fig = new_figure((5.0, 3.0))
    draw_temporal(fig.add_subplot(111), frame.temporal_weights, frame.model)
    fig.tight_layout()
    return save_figure(fig, path, dpi)


def save_frame_pictures(
    out_dir: str | Path, frame: CycleFrame, reference: np.ndarray | None = None, dpi: int = 100
) -> list[Path]:
    """The three stills of one cycle: cycle_XXXX.png, radar_XXXX.png, temporal_XXXX.png (XXXX = cycle)."""
    from irlsim.viz.radar import save_radar

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


def draw_panels(fig: Any, frame: CycleFrame, reference: np.ndarray | None = None) -> None:
    """The animation's layout on ``fig``: the cycle from above (top, full width), radar of theta (bottom
    left), temporal attention (bottom right)."""
    from irlsim.viz.radar import draw_radar

    fig.clear()
    gs = fig.add_gridspec(2, 2, width_ratios=(1.5, 1.0), height_ratios=(1.0, 1.0))
    draw_cycle(fig.add_subplot(gs[0, :]), frame)
    draw_radar(fig.add_subplot(gs[1, 0], projection="polar"), frame.theta, reference=reference, title="theta")
    draw_temporal(fig.add_subplot(gs[1, 1]), frame.temporal_weights, frame.model)
    fig.tight_layout()


def save_animation(
    path: str | Path,
    frames: Sequence[CycleFrame],
    reference: np.ndarray | None = None,
    fps: int = 5,
    dpi: int = 70,
    size: tuple[float, float] = (10.0, 8.0),
) -> Path:
    """``episode.gif``: the panels of every frame, ``fps`` frames per second (matplotlib PillowWriter).

    Written to a temporary ``.gif`` beside ``path`` and renamed, so a killed run leaves no half file.
    """
    from matplotlib.animation import PillowWriter

    if not frames:
        raise ValueError("save_animation needs at least one frame")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.partial.gif")
    fig = new_figure(size)
    writer = PillowWriter(fps=fps)
    try:
        with writer.saving(fig, str(tmp), dpi):
            for fr in frames:
                draw_panels(fig, fr, reference)
                writer.grab_frame()
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path
