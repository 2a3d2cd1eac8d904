"""What one planning cycle of closed-loop driving looks like as plain arrays: :class:`CycleFrame` (made from
the simulator's observation and the cycle's policy set by :func:`make_frame`), the road's lines around the
ego (:func:`road_lines`), and the view frame and window the pictures draw in (:func:`scene_window`).
No matplotlib here: the drawing is :mod:`irlsim.viz.frames`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.planner.policy_set import PolicySet
from irlsim.road import Road
from irlsim.sim.types import Observation


def value_ranks(value: np.ndarray) -> np.ndarray:
    """[N] float32 rank of each value among all N, 0 = lowest, 1 = highest (ties in index order)."""
    n = len(value)
    rank = np.empty(n, dtype=np.float32)
    rank[np.argsort(np.asarray(value), kind="stable")] = np.arange(n, dtype=np.float32) / max(n - 1, 1)
    return rank


def drawn_subset(n: int, max_drawn: int, always: np.ndarray) -> np.ndarray:
    """Sorted indices of the policies to draw: ``always`` (chosen, highlighted) plus an even spread over
    the N policies (they are sorted by progress), at most ``max_drawn`` of the spread."""
    spread = np.linspace(0, n - 1, min(max_drawn, n)).round().astype(np.int64)
    return np.unique(np.concatenate([np.asarray(always, dtype=np.int64), spread]))


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
    predictions:     [M, K, 3] float64 or None  the planner's prediction of each vehicle (rows of
                     ``vehicles``): front-bumper x [m], y [m], yaw [rad] at K times over the horizon
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
    predictions: np.ndarray | None = None

    def __post_init__(self) -> None:
        p, t = self.x.shape
        assert self.y.shape == (p, t), f"y: {self.y.shape} != {(p, t)}"
        assert self.value_rank.shape == (p,) and self.top_attention.shape == (p,)
        assert 0 <= self.chosen < p, f"chosen {self.chosen} not in [0, {p})"
        assert self.theta.ndim == 1 and len(self.theta) >= len(FEATURE_NAMES), self.theta.shape
        assert self.vehicles.ndim == 2 and self.vehicles.shape[1] == 5, self.vehicles.shape
        if self.attention is not None:
            assert self.attention.shape == (p,), self.attention.shape
        if self.predictions is not None:
            shape = self.predictions.shape
            assert len(shape) == 3 and (shape[0], shape[2]) == (len(self.vehicles), 3), shape

    @property
    def title(self) -> str:
        return f"{self.model}   cycle {self.cycle}   t = {self.t:.1f} s   v = {3.6 * self.ego[3]:.0f} km/h"


@dataclass(frozen=True)
class Window:
    """Axis limits of a cycle picture in the view frame [m]: x along the road from the ego, y to the left."""

    x0: float
    x1: float
    y0: float
    y1: float

    @property
    def aspect(self) -> float:
        """height / width"""
        return (self.y1 - self.y0) / (self.x1 - self.x0)

    def union(self, other: Window) -> Window:
        return Window(
            min(self.x0, other.x0), max(self.x1, other.x1), min(self.y0, other.y0), max(self.y1, other.y1)
        )


def _box(x: float, y: float, yaw: float, length: float, width: float) -> np.ndarray:
    """Corners [5, 2] (closed) of a box whose *front-bumper centre* is (x, y)."""
    c, s = math.cos(yaw), math.sin(yaw)
    cx, cy = x - 0.5 * length * c, y - 0.5 * length * s
    hl, hw = 0.5 * length, 0.5 * width
    local = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw], [hl, hw]])
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.array([cx, cy])


@dataclass
class Scene:
    """A cycle's geometry in the view frame (ego front bumper at the origin, road heading to the right)."""

    px: np.ndarray  # [P, T] policies
    py: np.ndarray
    lines: list[tuple[str, np.ndarray]]  # [Q, 2] each
    boxes: np.ndarray  # [M, 5, 2] vehicle outlines
    ego_box: np.ndarray  # [5, 2]
    pred: np.ndarray | None  # [M, K, 2] predicted front bumpers
    pred_boxes: np.ndarray | None  # [M, 5, 2] predicted outlines at the horizon


def view_scene(
    x: np.ndarray,
    y: np.ndarray,
    ego: Sequence[float],
    vehicles: np.ndarray,
    lines: Sequence[tuple[str, np.ndarray]],
    view_yaw: float | None,
    predictions: np.ndarray | None,
) -> Scene:
    ex, ey, eyaw, _, el, ew = (float(v) for v in ego)
    vyaw0 = eyaw if view_yaw is None else float(view_yaw)
    c, s = math.cos(vyaw0), math.sin(vyaw0)

    def local(xx: np.ndarray, yy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dx, dy = np.asarray(xx, dtype=np.float64) - ex, np.asarray(yy, dtype=np.float64) - ey
        return c * dx + s * dy, -s * dx + c * dy

    px, py = local(x, y)
    out_lines = [(kind, np.stack(local(xy[:, 0], xy[:, 1]), axis=1)) for kind, xy in lines]
    veh = np.asarray(vehicles, dtype=np.float64).reshape(-1, 5)
    vx, vy = local(veh[:, 0], veh[:, 1])
    boxes = np.array(
        [
            _box(float(a), float(b), yaw - vyaw0, ln, wd)
            for a, b, (_, _, yaw, ln, wd) in zip(vx, vy, veh, strict=True)
        ]
    ).reshape(-1, 5, 2)
    pred = pred_boxes = None
    if predictions is not None and len(predictions):
        qx, qy = local(predictions[:, :, 0], predictions[:, :, 1])
        pred = np.stack([qx, qy], axis=-1)
        pred_boxes = np.array(
            [
                _box(float(qx[k, -1]), float(qy[k, -1]), float(predictions[k, -1, 2]) - vyaw0, ln, wd)
                for k, (_, _, _, ln, wd) in enumerate(veh)
            ]
        ).reshape(-1, 5, 2)
    return Scene(px, py, out_lines, boxes, _box(0.0, 0.0, eyaw - vyaw0, el, ew), pred, pred_boxes)


def fit_window(sc: Scene, view: float, margin: float = 1.2) -> Window:
    """The window of one scene: x from a little behind the ego (a follower shows) to the farthest drawn
    policy (at least ``view`` ahead); y over the road's edges, the policies, the vehicles and the
    predictions inside that x range, plus ``margin``."""
    x0 = min(float(sc.px.min()), -(float(np.ptp(sc.ego_box[:, 0])) + 8.0)) - 1.0
    x1 = max(float(sc.px.max()), view) + 4.0
    ys = [sc.py.ravel(), sc.ego_box[:, 1]]
    for kind, xy in sc.lines:
        if kind == "edge":
            ys.append(xy[(xy[:, 0] >= x0) & (xy[:, 0] <= x1), 1])
    for pts in [sc.boxes] + ([sc.pred, sc.pred_boxes] if sc.pred is not None else []):
        flat = np.asarray(pts).reshape(-1, 2)
        ys.append(flat[(flat[:, 0] >= x0) & (flat[:, 0] <= x1), 1])
    yy = np.concatenate(ys)
    return Window(x0, x1, float(yy.min()) - margin, float(yy.max()) + margin)


def scene_window(
    x: np.ndarray,
    y: np.ndarray,
    ego: Sequence[float],
    vehicles: np.ndarray,
    lines: Sequence[tuple[str, np.ndarray]] = (),
    view_yaw: float | None = None,
    predictions: np.ndarray | None = None,
    view: float = 40.0,
) -> Window:
    """The window :func:`draw_policies` fits to these arrays (arguments as there)."""
    return fit_window(view_scene(x, y, ego, vehicles, lines, view_yaw, predictions), view)


def cycle_window(frame: CycleFrame, view: float = 40.0) -> Window:
    """The window of a frame's cycle picture: :func:`scene_window` of its arrays."""
    return scene_window(
        frame.x, frame.y, frame.ego, frame.vehicles, frame.lines, frame.view_yaw, frame.predictions, view
    )


def road_lines(
    road: Road, s0: float, behind: float = 40.0, ahead: float = 160.0
) -> tuple[tuple[str, np.ndarray], ...]:
    """Lane edges, dividers, stop lines and exit ramps within [s0 - behind, s0 + ahead] as world polylines."""
    s = np.arange(s0 - behind, s0 + ahead, 2.0)
    lines: list[tuple[str, np.ndarray]] = []
    half, w = road.half_road, road.lane_width
    for d in (-half, *(road.lane_centres[1:] - w / 2), half):
        x, y = road.to_xy(s, np.full_like(s, d))
        lines.append(("edge" if abs(d) == half else "divider", np.stack([x, y], axis=1)))
    lap = road.lap_length
    for sl in road.stop_lines:
        rel_s = (sl.s - s0 + behind) % lap - behind
        if -behind <= rel_s <= ahead:
            x, y = road.to_xy(np.full(2, s0 + rel_s), np.array([-half, half]))
            lines.append(("stop", np.stack([x, y], axis=1)))
    for ex in road.exits:
        rel = (ex.ramp_s - s0 + behind) % lap - behind
        ok = (rel >= -behind) & (rel <= ahead)
        if ok.sum() >= 2:
            for off in (-w / 2, w / 2):
                x, y = road.to_xy(s0 + rel[ok], ex.ramp_d[ok] + off)
                lines.append(("ramp", np.stack([x, y], axis=1)))
    return tuple(lines)


def make_frame(
    road: Road,
    model: str,
    cycle: int,
    obs: Observation,
    ps: PolicySet,
    chosen: int,
    theta: np.ndarray,
    info: dict[str, Any],
    ego_size: tuple[float, float],
    top_k: int = 10,
    max_policies: int = 300,
) -> CycleFrame:
    """A CycleFrame of one cycle: a subset of ``ps``'s policies (chosen, top-k attention, an even spread
    over the progress order), value ranks over all N policies, the vehicles and the road around the ego."""
    att = info.get("attention")
    top = np.zeros(0, dtype=np.int64)
    if att is not None and top_k > 0:
        top = np.argsort(-np.asarray(att), kind="stable")[:top_k]
    idx = drawn_subset(ps.n_policies, max_policies, np.append(top, chosen))
    rank = value_ranks(ps.value(theta))
    ego = obs.ego
    vehicles = obs.vehicles.boxes()
    tw = info.get("temporal_weights")
    return CycleFrame(
        model=model,
        cycle=cycle,
        t=float(ego.t),
        x=ps.x[idx].astype(np.float32),
        y=ps.y[idx].astype(np.float32),
        value_rank=rank[idx],
        top_attention=np.isin(idx, top),
        chosen=int(np.searchsorted(idx, chosen)),
        theta=np.asarray(theta, dtype=np.float64),
        ego=(
            float(ego.x),
            float(ego.y),
            float(ego.yaw),
            float(ego.v),
            float(ego_size[0]),
            float(ego_size[1]),
        ),
        vehicles=vehicles.astype(np.float64),
        attention=None if att is None else np.asarray(att, dtype=np.float32)[idx],
        temporal_weights=None if tw is None else np.asarray(tw, dtype=np.float64),
        lines=road_lines(road, float(ego.s)),
        info={"lane": int(ego.lane), "target_checkpoint": int(obs.target_checkpoint)},
        view_yaw=float(road.heading(np.array(ego.s))),
    )
