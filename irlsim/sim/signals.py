"""The route's traffic lights as the ego sees them, read from SUMO every step (:class:`SignalWatch`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.road import Road
from irlsim.sim.minor_green import MinorGreen
from irlsim.sim.sumo_ego import lane_of

#: SUMO signal states on a link: red (and red-yellow), and yellow; the stop line binds while either shows
RED_STATES = ("r", "R", "u")
YELLOW_STATES = ("y", "Y")
#: SUMO's permissive green (a minor link: a turn that yields to oncoming traffic on its green)
PERMISSIVE = "g"


class SignalWatch:
    """Each traffic light on the route, read on the ego's own lane's link into the route (lanes of one
    approach may show different signals: a green arrow beside a red): ``red`` (crossing it is a failure)
    and ``binding`` (red or yellow: its stop line binds the ego; on SUMO's minor green 'g' while a foe with
    priority is due: :mod:`irlsim.sim.minor_green`), ``permissive`` (the minor green), and ``violations``
    (lines crossed on a minor green while they bound, last step). The ego's lane on a light's incoming
    edge is the one it drives on there, or drove on last (a crossing is seen a step later, from the
    junction or the next edge); where it has none yet, the route's middle lane's link. ``ego_length``,
    ``v_max``: the ego's, for its time to clear a junction. ``grace`` [s] > 0: a light that turns from red
    to another state for the ego's link within ``grace`` is not ``red`` (a recorded ego replayed between
    rows ``grace`` + a step apart: SUMO moves a vehicle through the step that ends as its light turns
    green, and the recording's row at that time is already past the line)."""

    def __init__(self, road: Road, ego_length: float = 4.5, v_max: float = 13.9, grace: float = 0.0):
        self.signals = road.signals
        self.lap = float(road.lap_length)
        self.minor = MinorGreen(ego_length, min(v_max, road.max_speed_limit))
        self.violations = 0
        self._yielding = np.zeros(len(self.signals), dtype=bool)  # bound by a minor green last step
        self._lines = np.array([g.s for g in self.signals], dtype=np.float64)  # [m] their route positions
        self._s = 0.0  # the ego's route position last step
        self.red = np.zeros(len(self.signals), dtype=bool)
        self.binding = np.zeros(len(self.signals), dtype=bool)
        self.permissive = np.zeros(len(self.signals), dtype=bool)
        self._lanes: tuple[tuple[str, int], ...] = ()  # the ego's lane on its last two edges
        self.grace = float(grace)
        self._programs: dict[tuple[str, str], list[str]] = {}  # (tls, program) -> its phases' states

    def read(self, api: Any, ego: str, ego_v: float = 0.0, ego_s: float | None = None) -> None:
        """The lights' states after a step of ``api`` (libsumo or TraCI) for vehicle ``ego`` (at route
        position ``ego_s`` and speed ``ego_v``: the minor greens are judged where it is given)."""
        self.violations = 0
        if not self.signals:
            return
        try:
            edge, lane = lane_of(api, ego)
            if edge and not edge.startswith(":"):  # a junction's internal lane: the lane it came from counts
                self._lanes = (*[e for e in self._lanes if e[0] != edge][-1:], (edge, lane))
        except api.TraCIException:  # off the network (arrived): as last seen
            pass
        on = dict(self._lanes)
        links = [g.link_of(on.get(g.edge, -1)) for g in self.signals]  # the ego's link at each light
        tl = api.trafficlight
        full = {g.tls: tl.getRedYellowGreenState(g.tls) for g in self.signals}
        states = [full[g.tls][k] for g, k in zip(self.signals, links, strict=True)]
        self.red = np.array([c in RED_STATES for c in states], dtype=bool)
        if self.grace > 0.0 and self.red.any():
            self.red &= ~np.array(
                [self._turns_soon(api, g.tls, k) for g, k in zip(self.signals, links, strict=True)]
            )
        self.binding = np.array([c in RED_STATES + YELLOW_STATES for c in states], dtype=bool)
        self.permissive = np.array([c == PERMISSIVE for c in states], dtype=bool)
        if ego_s is not None:
            self._minor_greens(api, links, full, ego_v, ego_s)

    def _turns_soon(self, api: Any, tls: str, link: int) -> bool:
        """Whether ``tls`` switches within ``grace`` to a phase that shows ``link`` other than red."""
        tl = api.trafficlight
        if tl.getNextSwitch(tls) - api.simulation.getTime() > self.grace + 1e-9:
            return False
        key = (tls, tl.getProgram(tls))
        if key not in self._programs:
            logic = next((lg for lg in tl.getAllProgramLogics(tls) if lg.programID == key[1]), None)
            self._programs[key] = [ph.state for ph in logic.phases] if logic is not None else []
        phases = self._programs[key]
        if not phases:
            return False
        nxt = phases[(tl.getPhase(tls) + 1) % len(phases)]
        return link < len(nxt) and nxt[link] not in RED_STATES

    def _minor_greens(
        self, api: Any, links: list[int], full: dict[str, str], ego_v: float, ego_s: float
    ) -> None:
        """Bind each minor green's line while a foe with priority is due; count a line crossed while it
        bound the step before."""
        yielding = np.zeros(len(self.signals), dtype=bool)
        for i in np.flatnonzero(self.permissive):
            g = self.signals[i]
            to_line = (g.s - ego_s + self.lap / 2) % self.lap - self.lap / 2
            yielding[i] = self.minor.too_soon(api, g.tls, links[i], full[g.tls], to_line, ego_v)
        if self._yielding.any():  # bound last step: crossed since?
            ahead = (self._lines - self._s + self.lap / 2) % self.lap - self.lap / 2
            crossed = (ahead > 0) & (ahead <= ego_s - self._s)
            self.violations = int((crossed & self._yielding).sum())
        self.binding |= yielding
        self._yielding, self._s = yielding, ego_s
