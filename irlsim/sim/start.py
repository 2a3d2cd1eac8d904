"""Where the ego starts an episode: a draw from the seed alone (or the config's fixed start), on the
route's edges, clear of stop lines, exits, the junctions where the route yields and the checkpoints that
require a lane, with room to stop before a traffic light, with room ahead on an open route and clear of a
scenario's own traffic.

On a route too short for the configured clearances (an urban route of a few hundred metres, a small
circuit) the clearances and the room ahead are scaled down together, by halves, until some start
remains (:func:`start_scale`); a route too short for any start is refused in one line before any work
(:func:`check_start`)."""

from __future__ import annotations

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.road import Road, junctions
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.traffic import LoopEdges, wrap_route
from irlsim.sim.types import VehicleStates

#: the ego's random start draws from default_rng([seed, 1]), the traffic from default_rng(seed): a start
#: of its own, and the traffic of a fixed start as before
START_STREAM = 1
#: [m] a random start on an open route leaves at least this much of the route ahead
OPEN_START_RESERVE = 300.0
#: [m] with a scenario's own demand, the ego starts at least this far (route frame) from every vehicle
DEMAND_START_CLEARANCE = 20.0
#: the factors tried, in order, on the start clearances and the room ahead of a short route
START_SCALES = (1.0, 0.5, 0.25, 0.125)
#: [m] the grid on which start_scale looks for a start, and the least length of route it must leave
START_GRID = 1.0
MIN_START_SPAN = 5.0
#: [m/s^2] the braking a start before a traffic light must leave room for, at the start's top speed, and
#: [m] a margin: a start just before a light that shows red crossed it in the first cycle (a sweep found
#: it on SUMO's grid6); unscaled on short routes, since a car's stopping distance does not shrink with them
SIGNAL_START_DECEL = 3.0
SIGNAL_START_MARGIN = 5.0


def _start_ok(road: Road, cfg: EpisodeConfig, e: LoopEdges, s: np.ndarray, scale: float) -> np.ndarray:
    """[C] bool: route positions ``s`` [C] where a random start may lie, at clearances x ``scale``."""
    lap = road.lap_length
    # stop lines, exits and the junctions where the route yields (SUMO refuses a start too close to one)
    yields = [float(e.s1[i]) % lap for i in junctions.yield_ends(road.net, road.edges, road.closed)]
    marks = np.array([sl.s for sl in road.stop_lines] + [ex.s_start for ex in road.exits] + yields)
    # an any-lane checkpoint (an open route's end, a loop without a mission) needs no room before it
    cps = np.array([c.s for c in road.checkpoints if c.lane >= 0 or c.lanes])
    u = np.stack([s, s + lap], axis=1)[:, :, None]  # [C, 2, 1] e.s0 / e.s1 may exceed lap
    on_edge = ((u >= e.s0 + 1.0) & (u <= e.s1 - 1.0)).any(axis=(1, 2))
    gap = np.abs(wrap_route(s[:, None] - marks, lap))  # [C, marks]
    clear = (gap >= cfg.ego_start_clearance * scale).all(axis=1)
    before_cp = ((cps - s[:, None]) % lap < cfg.ego_start_checkpoint_clearance * scale).any(axis=1)
    room = s <= road.route_end_s - OPEN_START_RESERVE * scale  # always on a loop (inf)
    signals = np.array([g.s for g in road.signals])
    stop = cfg.ego_start_speed_max**2 / (2 * SIGNAL_START_DECEL) + SIGNAL_START_MARGIN
    before_signal = ((signals - s[:, None]) % lap < stop).any(axis=1)
    return on_edge & clear & ~before_cp & room & ~before_signal


def start_scale(road: Road, cfg: EpisodeConfig, e: LoopEdges) -> float:
    """The factor on the start clearances (``ego_start_clearance``, ``ego_start_checkpoint_clearance``)
    and the room ahead of an open route's start: 1 where the route leaves a start at the configured
    values (every shipped scenario), else the first of START_SCALES that leaves at least MIN_START_SPAN
    metres of it; a one-line IrlsimError where none does."""
    if not cfg.ego_start_random:
        return 1.0
    s = np.arange(0.0, road.lap_length, START_GRID)
    for scale in START_SCALES:
        if _start_ok(road, cfg, e, s, scale).sum() * START_GRID >= MIN_START_SPAN:
            return scale
    length = road.route_end_s - road.route_begin_s if not road.closed else road.lap_length
    raise IrlsimError(
        f"route of scenario '{road.name}' ({length:.0f} m) leaves no start for the ego clear of its stop "
        f"lines, exits and checkpoints, even at {START_SCALES[-1]} x ego_start_clearance = "
        f"{cfg.ego_start_clearance} m and ego_start_checkpoint_clearance = "
        f"{cfg.ego_start_checkpoint_clearance} m: choose a longer route or lower them"
    )


def check_start(road: Road, cfg: EpisodeConfig) -> float:
    """:func:`start_scale` of ``road`` (a one-line IrlsimError where it leaves no start): what a command
    checks once before any work."""
    return start_scale(road, cfg, LoopEdges.from_road(road))


def draw_start(
    road: Road,
    cfg: EpisodeConfig,
    e: LoopEdges,
    seed: int,
    occupied: VehicleStates | None = None,
    scale: float = 1.0,
) -> tuple[float, int, float]:
    """(route position s [m], lane, speed [m/s]) of the ego's start for ``seed``.

    With ``cfg.ego_start_random`` a function of the seed (and, with a scenario's own demand, of the
    vehicles ``occupied`` already there): s is drawn uniformly from the route's edges (1 m clear of their
    ends, where insertion is fragile) outside the stop-line / exit and checkpoint clearances (times
    ``scale``, see :func:`start_scale`), by rejection from batches of uniform draws.
    """
    lap = road.lap_length
    if not cfg.ego_start_random:
        return cfg.ego_start_s, cfg.ego_start_lane, cfg.ego_start_speed
    rng = np.random.default_rng([int(seed), START_STREAM])
    for _ in range(8):
        s = rng.uniform(0.0, lap, 256)
        ok = _start_ok(road, cfg, e, s, scale)
        if occupied is not None and occupied.count:  # keep clear of the traffic already there
            near = np.abs(wrap_route(s[:, None] - occupied.s[None, :], lap)) < DEMAND_START_CLEARANCE
            ok &= ~(near & (np.abs(occupied.d) <= road.half_road + 1.0)[None, :]).any(axis=1)
        idx = np.flatnonzero(ok)
        if len(idx):
            s0 = float(s[idx[0]])
            lane = int(rng.integers(0, road.n_lanes))
            speed = float(rng.uniform(cfg.ego_start_speed_min, cfg.ego_start_speed_max))
            return s0, lane, speed
    raise IrlsimError(
        f"ego_start_clearance = {cfg.ego_start_clearance} m and ego_start_checkpoint_clearance = "
        f"{cfg.ego_start_checkpoint_clearance} m leave no start on the route: lower them"
    )
