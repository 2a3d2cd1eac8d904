"""Log replay: a :class:`~irlsim.sim.simulation.Simulation` whose other vehicles replay recorded motion
(non-reactive, as nuPlan's non-reactive agents) instead of irlsim's background traffic.

Every step, before SUMO steps, each recorded vehicle present at that time of the recording is inserted
(once, the background type ``bg`` of a class every lane a vehicle may use allows, SUMO's speed and
lane-change control off) and moved to its recorded pose with ``moveToXY(keepRoute=2)``, on the lane SUMO
finds there (a bicycle's lane too, never a sidewalk, crossing or walking area); a vehicle whose recording
has ended is removed. SUMO reports the speed of the move, so the observation's vehicles carry their
recorded position, heading and speed. The ego is driven as in any simulation (a recording demonstrator
places it at its own recorded poses).

Reactive (``reactive=True``, closed-loop evaluation): a recorded vehicle with recorded edges is inserted
by SUMO at its first recorded position on one of its edges (``simulation.convertRoad``, on the nearest
lane a car may use; a vehicle first recorded within a junction enters when it has left it) and speed on
the rest of the route of its edges (a route SUMO refuses for a car: replayed instead),
and from then on SUMO drives it (SUMO's default vehicle type, speed factor 1, at most its
recorded top speed): it follows, brakes for, changes lanes around and yields to the ego.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from irlsim.road import Road
from irlsim.road.route import CAR_CLASS
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
from irlsim.sim.traffic import BG_TYPE
from irlsim.sim.types import EgoState, Observation

#: SUMO ids of the replayed vehicles: this prefix and the recorded id (the ego is 'ego')
PREFIX = "rec/"
ROUTE = "replay"
#: the type of the vehicles SUMO drives in a reactive replay: SUMO's default (Krauss, LC2013), speedFactor 1
REACTIVE_TYPE = "replay-reactive"
#: the type of the replayed vehicles: the background traffic's, of a class that every lane a vehicle may use
#: allows (:data:`REPLAY_CLASS`), so that SUMO puts a replayed bicycle on its bicycle lane (a car's class
#: would take the car lane beside it, and the cars SUMO drives in a reactive replay would queue behind it)
REPLAY_TYPE = "replay-recorded"
#: the replayed vehicles' class, added to every lane some vehicle may use: not to the lanes of pedestrians
#: alone (sidewalks, crossings, walking areas). SUMO's class 'ignoring', which may use every lane, had a
#: replayed bicycle whose noisy recorded pose stood at a junction mapped onto a walking area, and SUMO
#: (1.28) crashed with a segmentation fault in the next step
REPLAY_CLASS = "custom1"
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
    v: np.ndarray  # [R] [m/s]
    step: float
    #: per vehicle, the edges it drove (empty: none recorded); reactive vehicles drive this route
    edges: tuple[tuple[str, ...], ...] = ()
    #: [V] [m] per vehicle, its recorded 'length' and 'width' where recorded (else its SUMO type's)
    size: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)

    @property
    def top(self) -> np.ndarray:
        """[V] [m/s] each vehicle's highest recorded speed."""
        n = np.diff(self.start)
        out = np.zeros(len(n))
        some = n > 0
        out[some] = np.maximum.reduceat(self.v, self.start[:-1][some])
        return out

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
        cfg: EpisodeConfig,
        tracks: Tracks,
        t_begin: float,
        start: EgoState | None = None,
        reactive: bool = False,
        **kwargs: Any,
    ):
        super().__init__(road, dataclasses.replace(cfg, n_vehicles=0, recycle_behind=NEVER), **kwargs)
        self.tracks, self.t_begin = tracks, t_begin
        #: the ego's recorded state at reset (None: the scenario's start, on its lane's centre)
        self.recorded_start = start
        #: SUMO drives each recorded vehicle with recorded edges from its first recorded pose on
        self.reactive = reactive
        self._t_reset: float | None = None  # simulation time of the ego's first state
        self._driven: set[str] = set()  # reactive: the vehicles SUMO drives

    def reset(self, seed: int) -> Observation:
        self._t_reset, self._driven = None, set()
        return super().reset(seed)

    def command(self, seed: int) -> list[str]:
        """SUMO's command line, begun so that its clock is the recording's from the ego's first state on:
        a traffic light's program runs by SUMO's time, so the lights show what the recorded drivers saw
        (they had been ``t_begin`` seconds off: a recorded ego stopped at a light green in the replay)."""
        cmd = super().command(seed)
        cmd[cmd.index("--begin") + 1] = f"{max(self.t_begin - self.cfg.step, 0.0):.6f}"
        return cmd

    def _advance(self, state: EgoState, bookkeeping: bool = True, placed: bool = False) -> None:
        if not placed:
            t_next = float(self._api.simulation.getTime()) + self.cfg.step
            if self._t_reset is None:  # the first step after SUMO (re)loaded: the ego's start
                self._t_reset = t_next
                self._api.route.add(ROUTE, [self.road.edges[0]])
                types = self._api.vehicletype
                types.copy("DEFAULT_VEHTYPE", REACTIVE_TYPE)  # SUMO's default driver, at its own speed
                types.setSpeedFactor(REACTIVE_TYPE, 1.0)
                types.setSpeedDeviation(REACTIVE_TYPE, 0.0)
                types.copy(BG_TYPE, REPLAY_TYPE)
                types.setVehicleClass(REPLAY_TYPE, REPLAY_CLASS)
                self._allow_replayed()
                state = state if self.recorded_start is None else self.recorded_start
            self.place_others(self.t_begin + t_next - self._t_reset)
        super()._advance(state, bookkeeping, placed)

    def _allow_replayed(self) -> None:
        """:data:`REPLAY_CLASS` allowed on every lane some vehicle may use (a lane that allows none but
        pedestrians, or none at all, stays as it is)."""
        lanes = self._api.lane
        for lane in lanes.getIDList():
            allowed = lanes.getAllowed(lane)
            if allowed and set(allowed) != {"pedestrian"} and REPLAY_CLASS not in allowed:
                lanes.setAllowed(lane, [*allowed, REPLAY_CLASS])

    def place_others(self, t: float) -> None:
        """Insert, move and remove the replayed vehicles for recording time ``t`` (the next step's)."""
        api, tr = self._api.vehicle, self.tracks
        idx, rows = tr.at(t)
        live = set(api.getIDList()) | set(self._api.simulation.getPendingVehicles())
        want = [PREFIX + tr.ids[i] for i in idx]
        for vid in live - set(want) - self._driven:
            if vid.startswith(PREFIX):
                api.remove(vid)
        angles = 90.0 - np.degrees(tr.heading[rows])
        for vid, i, r, a in zip(want, idx, rows, angles, strict=True):
            if vid in self._driven or (vid not in live and self._insert(vid, int(i), int(r))):
                continue  # reactive: SUMO drives it (or has driven it off at its route's end)
            api.moveToXY(vid, "", -1, float(tr.x[r]), float(tr.y[r]), float(a) % 360.0, keepRoute=2)

    def _insert(self, vid: str, i: int, r: int) -> bool:
        """Add recorded vehicle ``i`` at its row ``r``; True where SUMO drives it from then on (reactive,
        with recorded edges, its pose on one of them: inserted there at its recorded speed on the rest of
        its route) or where it waits (reactive, its pose within a junction: inserted at the first step
        its pose is on one of its edges, a few steps later; inserted at once and replayed, it would drive
        blind to the ego for the rest of the drive), else it is replayed (SUMO's control off) and moved to
        its pose."""
        tr, sim = self.tracks, self._api.simulation
        edges = tr.edges[i] if self.reactive and tr.edges else ()
        # the nearest lane a car may use (a car's pose is never taken for the bicycle lane beside it)
        xy = (float(tr.x[r]), float(tr.y[r]))
        edge, pos, lane = sim.convertRoad(*xy, False, CAR_CLASS) if edges else ("", 0.0, 0)
        if edge.startswith(":") and edge not in edges:
            return True  # within a junction: not yet
        if edge in edges and self._drive(vid, i, r, edges[edges.index(edge) :], pos, lane):
            return True
        api = self._api.vehicle
        api.add(vid, ROUTE, typeID=REPLAY_TYPE)
        self._resize(vid, i)
        api.setSpeedMode(vid, 0)
        api.setLaneChangeMode(vid, 0)
        return False

    def _drive(self, vid: str, i: int, r: int, route: tuple[str, ...], pos: float, lane: int) -> bool:
        """Hand recorded vehicle ``i`` to SUMO at its row ``r``, at lane position ``pos`` of lane ``lane``
        of the first edge of ``route``; False where SUMO refuses the route (a turn its connections allow
        only buses), and the vehicle is then replayed."""
        api, tr = self._api.vehicle, self.tracks
        self._api.route.add(f"{ROUTE}@{vid}", list(route))
        # SUMO refuses a departure faster than the lane's limit
        limit = float(self._api.lane.getMaxSpeed(f"{route[0]}_{lane}")) - 0.01
        speed = f"{min(float(tr.v[r]), limit):.3f}"
        try:
            api.add(
                vid,
                f"{ROUTE}@{vid}",
                typeID=REACTIVE_TYPE,
                departLane=str(lane),
                departPos=f"{pos:.3f}",
                departSpeed=speed,
            )
        except self._api.TraCIException:
            return False
        api.setMaxSpeed(vid, max(float(tr.top[i]), 0.1))
        self._resize(vid, i)
        self._driven.add(vid)
        return True

    def _resize(self, vid: str, i: int) -> None:
        """Recorded vehicle ``i`` at its recorded size, where the recording has one (SUMO then drives and
        collides it, and the observation reports it, at that size)."""
        api, size = self._api.vehicle, self.tracks.size
        if "length" in size:
            api.setLength(vid, float(size["length"][i]))
        if "width" in size:
            api.setWidth(vid, float(size["width"][i]))
