"""Demonstrations: project the driven odometry onto each cycle's policy set (docs/design/demonstrations.md).

At planning cycle k (time t_k) the demonstration window zeta_k is the odometry over [t_k, t_k + horizon],
sampled on the planner's time grid (T = round(horizon / dt) + 1 states, t = 0 is now). The distance of a
policy pi to the window is

    d(zeta, pi) = sum_t alpha^t (sqrt(dlon_t^2 + dlat_t^2) + w_yaw * dyaw_t^2) / sum_t alpha^t   [m]

with dlon, dlat in the route frame (s, d) and dyaw the heading difference. The demonstration pi^D_k is the
argmin over the policy set; a cycle has no demonstration when its window is incomplete (the episode ended
first) or when the smallest distance exceeds ``MAX_DEMO_DISTANCE``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from irlsim.config import require

if TYPE_CHECKING:
    from irlsim.data.tensors import Rows
    from irlsim.sim.types import EgoState

#: discount of the distance per time step of DT_DEMO = 0.1 s [-]; 0.95^50 ~ 0.08, so the end of the
#: 5 s horizon still counts but the near future, which the driver controls best, dominates
ALPHA = 0.95
#: weight of the squared heading difference [m / rad^2]; 0.1 rad (5.7 deg) costs 0.05 m
W_YAW = 5.0
#: cycles whose best policy is farther than this from the odometry have no demonstration [m]
MAX_DEMO_DISTANCE = 1.5
#: simulation / planner time step [s]
DT_DEMO = 0.1
#: planning horizon [s]
HORIZON = 5.0


def safe_demo_index(
    demo_index: np.ndarray,
    distances: Rows,
    collision: np.ndarray | None,
    max_distance: float = MAX_DEMO_DISTANCE,
    stop_line: np.ndarray | None = None,
) -> np.ndarray:
    """[C] int64: the demonstrations with every one that breaks a rule the demonstrator kept moved to the
    closest policy (by the stored distance to the odometry) that breaks none; -1 (no demonstration)
    where no such policy is within ``max_distance`` [m]. The rules: not labelled as a predicted
    collision (``collision`` [C, N] bool, None = not checked) and not crossing an active stop line
    without having stood (``stop_line`` [C, N], the stop_line feature; > 0 breaks it; None = not
    checked).

    Why (docs/results/closed-loop-fixes.md): the demonstrator never collided and stood at every stop line, but
    the odometry's closest sampled policy need not: near a standing vehicle it can carry the collision
    label of the planner's prediction, and in the last metres before a stop line, where the expert
    brakes to a standstill, it can be a policy that creeps over the line at 0.3-3 m/s. Such a
    demonstration tells max-ent IRL that the broken rule costs nothing there, and the learned weight
    (proximity, stop_line) collapses in exactly the states where it matters.

    ``demo_index`` [C] (-1 = none), ``distances`` [C, N] (NaN = incomplete window); only the rows whose
    demonstration breaks a rule are read in full (memory maps stay unread otherwise)."""
    demo = np.asarray(demo_index, dtype=np.int64).copy()
    rows = np.flatnonzero(demo >= 0)

    def breaks(r: np.ndarray, cols: np.ndarray | slice) -> np.ndarray:
        out = np.asarray(collision[r, cols], dtype=bool) if collision is not None else None
        if stop_line is not None:
            crossing = np.asarray(stop_line[r, cols]) > 0
            out = crossing if out is None else out | crossing
        assert out is not None, "give collision or stop_line"
        return out

    bad = rows[breaks(rows, demo[rows])]
    if len(bad):
        dist = np.asarray(distances[bad], dtype=np.float64)
        dist = np.where(breaks(bad, slice(None)) | np.isnan(dist), np.inf, dist)
        best = np.argmin(dist, axis=1)
        ok = dist[np.arange(len(bad)), best] <= max_distance
        demo[bad] = np.where(ok, best, -1)
    return demo


def wrap_to(x: np.ndarray, period: float) -> np.ndarray:
    """Wrap ``x`` into [-period / 2, period / 2) (same shape and dtype as ``x``)."""
    return np.mod(x + 0.5 * period, period) - 0.5 * period


def _wrap_if_needed(x: np.ndarray, period: float) -> np.ndarray:
    # the wrap is the identity for values already in range, the usual case: skip its cost (~2x the rest)
    half = 0.5 * period
    if x.size == 0 or (x.min() >= -half and x.max() < half):
        return x
    return wrap_to(x, period)


def policy_distance(
    pol_s: np.ndarray,
    pol_d: np.ndarray,
    pol_yaw: np.ndarray,
    demo_s: np.ndarray,
    demo_d: np.ndarray,
    demo_yaw: np.ndarray,
    *,
    alpha: float = ALPHA,
    w_yaw: float = W_YAW,
    lap_length: float | None,
) -> np.ndarray:
    """Discounted mean distance [m] of every policy to the demonstration window.

    Args:
        pol_s, pol_d, pol_yaw: [..., N, T] policy route arc length [m], lateral offset [m], heading [rad].
        demo_s, demo_d, demo_yaw: [..., T] odometry on the same time grid (same units).
        alpha: discount per time step [-].
        w_yaw: weight of the squared heading difference [m / rad^2].
        lap_length: lap length L [m]; dlon is wrapped into [-L/2, L/2) so that a policy and an
            odometry on either side of the start line compare correctly. ``None`` disables wrapping.

    Returns:
        [..., N] float32 distances [m]. Computed in the inputs' precision (float32 at least): pass float64
        absolute arc lengths (several km), or float32 ones relative to a nearby reference (as
        ``DemoProjector`` does, 2x faster).
    """
    dtype = np.result_type(pol_s, demo_s, pol_d, demo_d, pol_yaw, demo_yaw, np.float32)
    pol_s = np.asarray(pol_s, dtype=dtype)
    if pol_s.ndim < 2:
        raise ValueError(f"policy arrays must be [..., N, T], got shape {pol_s.shape}")
    n_steps = pol_s.shape[-1]
    demo_s = np.asarray(demo_s, dtype=dtype)[..., None, :]
    if demo_s.shape[-1] != n_steps:
        raise ValueError(f"demonstration has {demo_s.shape[-1]} steps, policies have {n_steps}")
    dlon = pol_s - demo_s
    if lap_length is not None:
        dlon = _wrap_if_needed(dlon, float(lap_length))
    dlat = np.asarray(pol_d, dtype=dtype) - np.asarray(demo_d, dtype=dtype)[..., None, :]
    dyaw = np.asarray(pol_yaw, dtype=dtype) - np.asarray(demo_yaw, dtype=dtype)[..., None, :]
    dyaw = _wrap_if_needed(dyaw, 2.0 * np.pi)
    weights = float(alpha) ** np.arange(n_steps, dtype=np.float64)  # [T]
    per_step = np.sqrt(dlon * dlon + dlat * dlat)  # [..., N, T]; no overflow risk at metre scale
    per_step += w_yaw * (dyaw * dyaw)
    return (per_step @ (weights / weights.sum()).astype(dtype)).astype(np.float32)


class Projection(NamedTuple):
    """The demonstration of one planning cycle, as ``DemoProjector`` returns it.

    ``distances`` [N] float32 [m] are all NaN when the window is incomplete; ``demo_index`` is the
    progress-sorted index of pi^D or -1 (no demonstration); ``demo_distance`` is d(zeta, pi^D) [m] or NaN
    when there is no demonstration (a complete window whose best policy is too far keeps its finite
    ``distances``, so the minimum can still be recovered from them).
    """

    cycle_index: int
    distances: np.ndarray
    demo_index: int
    demo_distance: float


class _Pending(NamedTuple):
    cycle_index: int
    step: int  # round(t_k / dt)
    s_ref: float  # arc length subtracted from ``s`` so it fits float32 precisely [m]
    s: np.ndarray  # [N, T] float32, s - s_ref
    d: np.ndarray  # [N, T] float32
    yaw: np.ndarray  # [N, T] float32


class DemoProjector:
    """Streaming projection of the odometry onto the policy sets of one episode.

    Keeps the trajectories of the cycles whose window is not complete yet (horizon / planning period
    cycles, about 25 x 2,500 x 51 x 3 float32 = 38 MB at paper size) and the odometry those windows need.

    Usage, per simulation step (any order within a step)::

        proj.push_odometry(t, s, d, yaw)                  # every step, dt apart
        proj.push_cycle(k, t, ps.s, ps.d, ps.yaw)         # on planning steps
        for p in proj.pop_ready(): writer.add_demo(p)
        ...
        for p in proj.finish(): writer.add_demo(p)        # at the end of the episode

    Times are matched by rounding t / dt to integer steps, so float drift in ``t`` is harmless.
    """

    def __init__(
        self,
        *,
        lap_length: float | None,
        horizon: float = HORIZON,
        dt: float = DT_DEMO,
        alpha: float = ALPHA,
        w_yaw: float = W_YAW,
        max_demo_distance: float = MAX_DEMO_DISTANCE,
    ) -> None:
        if dt <= 0 or horizon <= 0:
            raise ValueError(f"horizon and dt must be > 0, got horizon={horizon}, dt={dt}")
        self.lap_length = lap_length
        self.dt = float(dt)
        self.n_steps = int(round(horizon / dt)) + 1
        self.alpha = float(alpha)
        self.w_yaw = float(w_yaw)
        self.max_demo_distance = float(max_demo_distance)
        self._pending: list[_Pending] = []
        self._odo: dict[int, tuple[float, float, float]] = {}
        self._last_odo_step: int | None = None

    def _step(self, t: float) -> int:
        return int(round(float(t) / self.dt))

    def push_cycle(self, cycle_index: int, t: float, s: np.ndarray, d: np.ndarray, yaw: np.ndarray) -> None:
        """Buffer one cycle's policy trajectories. s, d, yaw: [N, T] route frame [m, m, rad], t [s]."""
        s = np.asarray(s, dtype=np.float64)
        if s.ndim != 2 or s.shape[1] != self.n_steps:
            raise ValueError(f"cycle {cycle_index}: expected [N, {self.n_steps}] trajectories, got {s.shape}")
        if np.shape(d) != s.shape or np.shape(yaw) != s.shape:
            raise ValueError(f"cycle {cycle_index}: s, d, yaw shapes differ: {s.shape}, {np.shape(d)}")
        s_ref = float(s[0, 0])
        self._pending.append(
            _Pending(
                int(cycle_index),
                self._step(t),
                s_ref,
                (s - s_ref).astype(np.float32),
                np.asarray(d, dtype=np.float32),
                np.asarray(yaw, dtype=np.float32),
            )
        )

    def push_odometry(self, t: float, s: float, d: float, yaw: float) -> None:
        """Record the ego state at time t [s]: route arc length s (unwrapped) [m], offset d [m], yaw [rad]."""
        step = self._step(t)
        self._odo[step] = (float(s), float(d), float(yaw))
        self._last_odo_step = step if self._last_odo_step is None else max(step, self._last_odo_step)

    def _project(self, p: _Pending) -> Projection:
        steps = np.arange(p.step, p.step + self.n_steps)
        rows = [self._odo.get(int(k)) for k in steps]  # T lookups, not a loop over policies
        n = p.s.shape[0]
        if any(r is None for r in rows):
            return Projection(p.cycle_index, np.full(n, np.nan, dtype=np.float32), -1, float("nan"))
        demo = np.asarray(rows, dtype=np.float64)  # [T, 3]
        dist = policy_distance(
            p.s,
            p.d,
            p.yaw,
            (demo[:, 0] - p.s_ref).astype(np.float32),
            demo[:, 1].astype(np.float32),
            demo[:, 2].astype(np.float32),
            alpha=self.alpha,
            w_yaw=self.w_yaw,
            lap_length=self.lap_length,
        )
        best = int(np.argmin(dist))
        best_d = float(dist[best])
        if not np.isfinite(best_d) or best_d > self.max_demo_distance:
            return Projection(p.cycle_index, dist, -1, float("nan"))
        return Projection(p.cycle_index, dist, best, best_d)

    def _prune_odometry(self) -> None:
        # keep what pending windows need and the last T steps (a cycle may be pushed after its odometry)
        if self._last_odo_step is None:
            return
        keep_from = self._last_odo_step - self.n_steps
        if self._pending:
            keep_from = min(keep_from, min(p.step for p in self._pending))
        for k in [k for k in self._odo if k < keep_from]:
            del self._odo[k]

    def pop_ready(self) -> list[Projection]:
        """Projections of the buffered cycles whose window [t_k, t_k + horizon] is driven, in push order.

        A window with a missing odometry step inside it counts as incomplete (no demonstration).
        """
        if self._last_odo_step is None:
            return []
        last = self._last_odo_step
        ready = [p for p in self._pending if p.step + self.n_steps - 1 <= last]
        if not ready:
            return []
        self._pending = [p for p in self._pending if p.step + self.n_steps - 1 > last]
        out = [self._project(p) for p in ready]
        self._prune_odometry()
        return out

    def finish(self) -> list[Projection]:
        """End of episode: the ready cycles, then the rest with incomplete windows (distances NaN, -1)."""
        out = self.pop_ready()
        n_missing = [p.s.shape[0] for p in self._pending]
        out += [
            Projection(p.cycle_index, np.full(n, np.nan, dtype=np.float32), -1, float("nan"))
            for p, n in zip(self._pending, n_missing, strict=True)
        ]
        self._pending = []
        self._odo.clear()
        self._last_odo_step = None
        return out

    def project_window(
        self,
        cycle_index: int,
        t: float,
        policies: tuple[np.ndarray, np.ndarray, np.ndarray],
        odometry: Sequence[tuple[float, float, float, float]],
    ) -> Projection:
        """One cycle's demonstration at once: its policies (s, d, yaw: [N, T] route frame) at time ``t``
        [s] projected onto ``odometry`` [(t, s, d, yaw)] that covers the window (a look ahead: DAgger's
        SUMO labeller), with this projector's metric and rules; its own streaming buffers untouched. An
        odometry that ends before the window does gives no demonstration."""
        one = DemoProjector(
            lap_length=self.lap_length,
            horizon=(self.n_steps - 1) * self.dt,
            dt=self.dt,
            alpha=self.alpha,
            w_yaw=self.w_yaw,
            max_demo_distance=self.max_demo_distance,
        )
        one.push_cycle(cycle_index, t, *policies)
        for row in odometry:
            one.push_odometry(*row)
        return one.finish()[0]

    @property
    def n_pending(self) -> int:
        """Number of buffered cycles whose window is not complete yet."""
        return len(self._pending)


def look_ahead_odometry(ego: EgoState, ahead: Sequence[EgoState]) -> list[tuple[float, float, float, float]]:
    """A look ahead from ``ego`` (the states SUMO's driver drove on from it) as
    :meth:`DemoProjector.project_window`'s odometry: (t, s, d, yaw) of the ego, then of each state."""
    return [(x.t, x.s, x.d, x.yaw) for x in (ego, *ahead)]


#: [m] a placed ego's offset from its SUMO lane's centre beyond which a look ahead read at that centre
#: starts elsewhere than the policies (``lane_jump_projection``)
RECENTRE = 0.05


def lane_jump_projection(
    p: Projection, end_d: np.ndarray, odometry_d: np.ndarray, lane_width: float, lane_offset: float = 0.0
) -> Projection:
    """A look ahead's demonstration (DAgger's SUMO labeller) where SUMO's lateral path is no path: SUMO's
    driver changed lanes within one simulation step (SUMO's lane-based models move a car a lane width at
    once), or the look ahead is read at SUMO's lanes' centres while the placed ego starts ``lane_offset``
    [m] off it (:meth:`irlsim.sim.branch.BranchingSimulation.lane_offset`; beyond ``RECENTRE``). No smooth
    policy follows either, so where the projection ``p`` found no policy within the distance, the
    demonstration is the nearest policy (by ``p.distances``) that ends in the lane SUMO's driver ends in
    (``end_d`` [N]: each policy's last lateral offset; ``odometry_d`` [T]: the look ahead's) -- the
    driver's decision of lane, driven as the planner can. ``p`` as it is otherwise: a demonstration
    found, an incomplete window, neither of the two, or no policy ending in that lane."""
    d = np.asarray(odometry_d, dtype=np.float64)
    jumped = len(d) > 1 and bool((np.abs(np.diff(d)) > 0.5 * lane_width).any())
    if p.demo_index >= 0 or not (jumped or abs(lane_offset) > RECENTRE) or not np.isfinite(p.distances).any():
        return p
    there = (np.abs(np.asarray(end_d, dtype=np.float64) - d[-1]) < 0.5 * lane_width) & np.isfinite(
        p.distances
    )
    if not there.any():
        return p
    k = int(np.argmin(np.where(there, p.distances, np.inf)))
    return Projection(p.cycle_index, p.distances, k, float(p.distances[k]))


def expert_projection(
    cycle_index: int,
    s: np.ndarray,
    d: np.ndarray,
    yaw: np.ndarray,
    expert_index: int,
    *,
    alpha: float = ALPHA,
    w_yaw: float = W_YAW,
    lap_length: float | None,
) -> Projection:
    """The demonstration of a DAgger cycle: the expert's own selection ``expert_index`` in the cycle's
    policy set (s, d, yaw: [N, T] route frame), not projected odometry.

    ``distances`` are d(pi^E, pi) of every policy to the expert's policy with the odometry projection's
    metric (:func:`policy_distance`), so the stored per-policy distances keep their meaning ('how far from
    the demonstration'); ``demo_distance`` is 0 by construction (the demonstration is in the set). Unlike
    an odometry window it is complete at once, also in an episode's last cycles.
    """
    s = np.asarray(s, dtype=np.float64)
    n = s.shape[0]
    if not 0 <= expert_index < n:
        raise ValueError(f"cycle {cycle_index}: expert index {expert_index} outside 0..{n - 1}")
    s_ref = float(s[0, 0])
    rel = (s - s_ref).astype(np.float32)
    d32, yaw32 = np.asarray(d, np.float32), np.asarray(yaw, np.float32)
    dist = policy_distance(
        rel,
        d32,
        yaw32,
        rel[expert_index],
        d32[expert_index],
        yaw32[expert_index],
        alpha=alpha,
        w_yaw=w_yaw,
        lap_length=lap_length,
    )
    dist[expert_index] = 0.0  # exactly: float rounding of (a - a) is 0 already; stated, not relied on
    return Projection(int(cycle_index), dist, int(expert_index), 0.0)


@dataclass(frozen=True)
class DemoConfig:
    """Projection of the odometry onto the policy set (docs/design/demonstrations.md)."""

    alpha: float = ALPHA
    """discount per 0.1 s step of the distance's time weights alpha^t"""
    w_yaw: float = W_YAW
    """[m/rad^2] weight of the squared yaw difference"""
    max_distance: float = MAX_DEMO_DISTANCE
    """[m] cycles whose closest policy is farther than this have no demonstration"""

    def validate(self) -> None:
        require(0 < self.alpha <= 1, f"demo.alpha must be in (0, 1], got {self.alpha}")
        require(self.w_yaw >= 0, "demo.w_yaw must be >= 0")
        require(self.max_distance > 0, "demo.max_distance must be > 0 m")
