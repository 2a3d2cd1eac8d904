"""Where the ego starts an episode: a draw from the seed alone (or the config's fixed start), on the
route's edges, clear of stop lines, exits and checkpoints, with room ahead on an open route and clear of
a scenario's own traffic."""

from __future__ import annotations

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.road import Road, route
from irlsim.sim.config import ScenarioConfig
from irlsim.sim.traffic import LoopEdges, wrap_route
from irlsim.sim.types import VehicleStates

#: the ego's random start draws from default_rng([seed, 1]), the traffic from default_rng(seed): a start
#: of its own, and the traffic of a fixed start as before
START_STREAM = 1
#: [m] a random start on an open route leaves at least this much of the route ahead
OPEN_START_RESERVE = 300.0
#: [m] with a scenario's own demand, the ego starts at least this far (route frame) from every vehicle
DEMAND_START_CLEARANCE = 20.0


def draw_start(
    road: Road, cfg: ScenarioConfig, e: LoopEdges, seed: int, occupied: VehicleStates | None = None
) -> tuple[float, int, float]:
    """(route position s [m], lane, speed [m/s]) of the ego's start for ``seed``.

    With ``cfg.ego_start_random`` a function of the seed (and, with a scenario's own demand, of the
    vehicles ``occupied`` already there): s is drawn uniformly from the route's edges (1 m clear of their
    ends, where insertion is fragile) outside the stop-line / exit and checkpoint clearances, by
    rejection from batches of uniform draws.
    """
    lap = road.lap_length
    if not cfg.ego_start_random:
        return cfg.ego_start_s, cfg.ego_start_lane, cfg.ego_start_speed
    rng = np.random.default_rng([int(seed), START_STREAM])
    # stop lines, exits and the junctions where the route yields (SUMO refuses a start too close to one)
    yields = [float(e.s1[i]) % lap for i in route.yield_ends(road.net, road.edges, road.closed)]
    marks = np.array([sl.s for sl in road.stop_lines] + [ex.s_start for ex in road.exits] + yields)
    cps = np.array([c.s for c in road.checkpoints])
    for _ in range(8):
        s = rng.uniform(0.0, lap, 256)
        u = np.stack([s, s + lap], axis=1)[:, :, None]  # [C, 2, 1] e.s0 / e.s1 may exceed lap
        on_edge = ((u >= e.s0 + 1.0) & (u <= e.s1 - 1.0)).any(axis=(1, 2))
        gap = np.abs(wrap_route(s[:, None] - marks, lap))  # [C, marks]
        clear = (gap >= cfg.ego_start_clearance).all(axis=1)
        before_cp = ((cps - s[:, None]) % lap < cfg.ego_start_checkpoint_clearance).any(axis=1)
        room = s <= road.route_end_s - OPEN_START_RESERVE  # always on a loop (inf)
        if occupied is not None and occupied.count:  # keep clear of the traffic already there
            near = np.abs(wrap_route(s[:, None] - occupied.s[None, :], lap)) < DEMAND_START_CLEARANCE
            room &= ~(near & (np.abs(occupied.d) <= road.half_road + 1.0)[None, :]).any(axis=1)
        ok = np.flatnonzero(on_edge & clear & ~before_cp & room)
        if len(ok):
            s0 = float(s[ok[0]])
            lane = int(rng.integers(0, road.n_lanes))
            speed = float(rng.uniform(cfg.ego_start_speed_min, cfg.ego_start_speed_max))
            return s0, lane, speed
    raise IrlsimError(
        f"ego_start_clearance = {cfg.ego_start_clearance} m and ego_start_checkpoint_clearance = "
        f"{cfg.ego_start_checkpoint_clearance} m leave no start on the route: lower them"
    )
