"""The route's traffic lights as the ego sees them, read from SUMO every step (:class:`SignalWatch`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.road import Road

#: SUMO signal states on a link: red (and red-yellow), and yellow; the stop line binds while either shows
RED_STATES = ("r", "R", "u")
YELLOW_STATES = ("y", "Y")


class SignalWatch:
    """Each traffic light on the route, read on the ego's own lane's link into the route (lanes of one
    approach may show different signals: a green arrow beside a red): ``red`` (crossing it is a failure)
    and ``binding`` (red or yellow: its stop line binds the ego). The ego's lane on a light's incoming edge
    is the one it drives on there, or drove on last (a crossing is seen a step later, from the junction or
    the next edge); where it has none yet, the route's middle lane's link."""

    def __init__(self, road: Road):
        self.signals = road.signals
        self.red = np.zeros(len(self.signals), dtype=bool)
        self.binding = np.zeros(len(self.signals), dtype=bool)
        self._lanes: tuple[tuple[str, int], ...] = ()  # the ego's lane on its last two edges

    def read(self, api: Any, ego: str) -> None:
        """The lights' states after a step of ``api`` (libsumo or TraCI) for vehicle ``ego``."""
        if not self.signals:
            return
        try:
            edge, lane = api.vehicle.getRoadID(ego), int(api.vehicle.getLaneIndex(ego))
            if not edge.startswith(":"):  # a junction's internal lane: the lane it came from counts
                self._lanes = (*[e for e in self._lanes if e[0] != edge][-1:], (edge, lane))
        except api.TraCIException:  # off the network (arrived): as last seen
            pass
        on = dict(self._lanes)
        tl = api.trafficlight
        states = [tl.getRedYellowGreenState(g.tls)[g.link_of(on.get(g.edge, -1))] for g in self.signals]
        self.red = np.array([c in RED_STATES for c in states], dtype=bool)
        self.binding = np.array([c in RED_STATES + YELLOW_STATES for c in states], dtype=bool)
