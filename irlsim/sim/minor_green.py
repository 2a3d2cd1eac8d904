"""Right of way on SUMO's minor green 'g' (a turn that yields to oncoming traffic on its green), at the
route's traffic lights, read from SUMO's lanes (:class:`MinorGreen`, used by
:class:`~irlsim.sim.signals.SignalWatch`).

SUMO's ``vehicle.getJunctionFoes`` lists no foe for the ego (placed by ``moveToXY``) at a signalised
junction, so the foes are read from the junction's lanes: the internal lanes that cross the ego's link
(``lane.getInternalFoes`` of its via lane) whose own link shows the major green 'G', the vehicles on
them (inside: due now) and those on their incoming lanes headed into them (due when they reach the line,
accelerating from their speed at ``FOE_ACCEL``). The ego's line binds while one is due before the ego,
going now, has cleared the junction plus SUMO's gap (:mod:`irlsim.sim.yielding`'s rule with the whole
junction as the conflict area); crossing the line while it binds is a yield violation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from irlsim.sim.yielding import YIELD_ACCEL, YIELD_GAP, YIELD_LOOKAHEAD, clear_time

#: [m/s^2] a foe's acceleration from its speed to the line (a car starting on its green)
FOE_ACCEL = 2.6
#: SUMO's major green: a link with priority
MAJOR = "G"


class MinorGreen:
    """The foes with priority of the ego's link at a light showing it the minor green, from SUMO's lanes;
    the junctions' layout is asked of SUMO once per light and link."""

    def __init__(self, ego_length: float, v_max: float):
        self.ego_length, self.v_max = float(ego_length), float(v_max)
        self._links: dict[str, list[Any]] = {}  # tls -> SUMO's controlled links per index
        self._foes: dict[tuple[str, int], list[tuple[int, str, str]]] = {}  # (tls, link) -> foe links
        self._lanes: dict[str, tuple[float, float]] = {}  # lane -> (length, speed limit)

    def _lane(self, api: Any, lane: str) -> tuple[float, float]:
        if lane not in self._lanes:
            self._lanes[lane] = (float(api.lane.getLength(lane)), float(api.lane.getMaxSpeed(lane)))
        return self._lanes[lane]

    def _foe_links(self, api: Any, tls: str, link: int) -> list[tuple[int, str, str]]:
        """(link index, incoming lane, internal lane) of every link of ``tls`` that crosses ``link``."""
        if (tls, link) not in self._foes:
            if tls not in self._links:
                self._links[tls] = [list(c) for c in api.trafficlight.getControlledLinks(tls)]
            links = self._links[tls]
            mine = {via for _, _, via in links[link]} if link < len(links) else set()
            crossing = {f for via in mine for f in api.lane.getInternalFoes(via)}
            self._foes[(tls, link)] = [
                (k, inc, via) for k, cons in enumerate(links) for inc, _, via in cons if via in crossing
            ]
        return self._foes[(tls, link)]

    def too_soon(self, api: Any, tls: str, link: int, state: str, to_line: float, ego_v: float) -> bool:
        """Whether a foe with priority is in the junction or due there before the ego, ``to_line`` metres
        before its line at ``ego_v``, going now, has cleared it plus ``YIELD_GAP``."""
        if not -self.ego_length <= to_line <= YIELD_LOOKAHEAD:
            return False
        foes = [(inc, via) for k, inc, via in self._foe_links(api, tls, link) if state[k] == MAJOR]
        if not foes:
            return False
        via_len = max((self._lane(api, v)[0] for _, _, v in self._links[tls][link]), default=0.0)
        clear = max(to_line, 0.0) + via_len + self.ego_length
        soon = float(clear_time(np.array([clear]), ego_v, YIELD_ACCEL, self.v_max)[0]) + YIELD_GAP  # [s]
        for inc, via in foes:
            if api.lane.getLastStepVehicleNumber(via):
                return True  # inside the junction, crossing the ego's way
            length, limit = self._lane(api, inc)
            for vid in api.lane.getLastStepVehicleIDs(inc):
                dist = length - api.vehicle.getLanePosition(vid)
                if dist > limit * soon:
                    continue  # cannot be there in time, even at the limit
                v = api.vehicle.getSpeed(vid)
                if clear_time(np.array([dist]), v, FOE_ACCEL, max(v, limit))[0] >= soon:
                    continue
                nxt = api.vehicle.getNextLinks(vid)
                if nxt and nxt[0][4] == via:  # headed into the crossing link (not another lane's, link's)
                    return True
        return False
