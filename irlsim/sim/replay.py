"""Log replay: a :class:`~irlsim.sim.simulation.Simulation` whose other vehicles replay recorded motion
(non-reactive, as nuPlan's non-reactive agents) instead of irlsim's background traffic.

Every step, before SUMO steps, each recorded vehicle present at that time of the recording is inserted
(once, type ``bg``, SUMO's speed and lane-change control off) and moved to its recorded pose with
``moveToXY(keepRoute=2)``; a vehicle whose recording has ended is removed. SUMO reports the speed of the
move, so the observation's vehicles carry their recorded position, heading and speed. The ego is driven
as in any simulation (a recording demonstrator places it at its own recorded poses).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from irlsim.road import Road
from irlsim.sim.config import ScenarioConfig
from irlsim.sim.simulation import Simulation
from irlsim.sim.traffic import BG_TYPE
from irlsim.sim.types import EgoState, Observation

#: SUMO ids of the replayed vehicles: this prefix and the recorded id (the ego is 'ego')
PREFIX = "rec/"
ROUTE = "replay"
#: [m] background vehicles are recycled this far behind the ego: never, in a replay
NEVER = 1e12


@dataclass(frozen=True)
class Tracks:
    """Recorded vehicles at the step: vehicle ``k`` owns rows ``start[k]:start[k + 1]``, at times
    ``t0[k] + j * step`` of the recording."""

    ids: tuple[str, ...]
    start: np.ndarray  # [V + 1]
    t0: np.ndarray  # [V] [s]
    x: np.ndarray  # [R] [m] front bumper
    y: np.ndarray
    heading: np.ndarray  # [R] [rad] ENU
    step: float

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(vehicle indices present at recording time ``t``, their rows)."""
        k = np.rint((t - self.t0) / self.step).astype(np.int64)
        on = (k >= 0) & (k < np.diff(self.start))
        return np.flatnonzero(on), self.start[:-1][on] + k[on]


class ReplaySimulation(Simulation):
    """A simulation of ``road`` whose other vehicles are ``tracks`` (no background traffic). The ego's
    state at reset is the recording's at time ``t_begin``; the others follow the recording's clock from
    there."""

    def __init__(
        self,
        road: Road,
        cfg: ScenarioConfig,
        tracks: Tracks,
        t_begin: float,
        start: EgoState | None = None,
        **kwargs: Any,
    ):
        super().__init__(road, dataclasses.replace(cfg, n_vehicles=0, recycle_behind=NEVER), **kwargs)
        self.tracks, self.t_begin = tracks, t_begin
        #: the ego's recorded state at reset (None: the scenario's start, on its lane's centre)
        self.recorded_start = start
        self._t_reset: float | None = None  # simulation time of the ego's first state

    def reset(self, seed: int) -> Observation:
        self._t_reset = None
        return super().reset(seed)

    def _advance(self, state: EgoState, bookkeeping: bool = True, placed: bool = False) -> None:
        if not placed:
            t_next = float(self._api.simulation.getTime()) + self.cfg.step
            if self._t_reset is None:  # the first step after SUMO (re)loaded: the ego's start
                self._t_reset = t_next
                self._api.route.add(ROUTE, [self.road.edges[0]])
                state = state if self.recorded_start is None else self.recorded_start
            self.place_others(self.t_begin + t_next - self._t_reset)
        super()._advance(state, bookkeeping, placed)

    def place_others(self, t: float) -> None:
        """Insert, move and remove the replayed vehicles for recording time ``t`` (the next step's)."""
        api, tr = self._api.vehicle, self.tracks
        idx, rows = tr.at(t)
        want = [PREFIX + tr.ids[i] for i in idx]
        live = set(api.getIDList()) | set(self._api.simulation.getPendingVehicles())
        for vid in live - set(want) - {"ego"}:
            if vid.startswith(PREFIX):
                api.remove(vid)
        angles = 90.0 - np.degrees(tr.heading[rows])
        for vid, x, y, a in zip(want, tr.x[rows], tr.y[rows], angles, strict=True):
            if vid not in live:
                api.add(vid, ROUTE, typeID=BG_TYPE)
                api.setSpeedMode(vid, 0)
                api.setLaneChangeMode(vid, 0)
            api.moveToXY(vid, "", -1, float(x), float(y), float(a) % 360.0, keepRoute=2)
