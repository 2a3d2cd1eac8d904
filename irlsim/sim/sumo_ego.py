"""SUMO's own driver model at the ego's wheel: the reference the planner's speed is measured against on
a scenario (``irlsim sim --driver sumo``, :class:`irlsim.sim.drivers.SumoDriver`). Its car following,
lane changes and junction rules, the road's speed limits, at most the ego's target speed."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from irlsim.road import Road, wrap_angle
from irlsim.sim.traffic import wrap_route
from irlsim.sim.types import EgoState

EGO_SPEED_FACTOR = 2.0  # the ego type's speedFactor (sumo_net/vtypes.add.xml)


def add_ego(
    api: Any, ego: str, road: Road, eid: str, pos: float, lane: int, v0: float, vtype: str = "ego"
) -> None:
    """Insert the ego at lane position ``pos`` [m] of route edge ``eid`` in route lane ``lane``, on the
    rest of the route, of type ``vtype`` (a demonstrator's placed type, :data:`irlsim.sim.vtype.PLACED_TYPE`:
    the lane-change model SUMO builds at insertion is then the demonstrator's). Its departure speed is
    ``v0`` [m/s] below the lane's limit x the ego type's speedFactor (SUMO refuses a faster departure, on a
    10 km/h street); the ego's own state keeps ``v0`` (it is placed by moveToXY every step)."""
    k = road.layout.edge_lane(road.edges.index(eid), lane)
    depart = min(v0, EGO_SPEED_FACTOR * float(road.net.getEdge(eid).getLane(k).getSpeed()) - 0.01)
    api.vehicle.add(
        ego,
        f"loop@{eid}",
        typeID=vtype,
        departLane=str(k),
        departPos=f"{pos:.3f}",
        departSpeed=f"{depart:.3f}",
    )


def lane_of(api: Any, vid: str) -> tuple[str, int]:
    """(edge, lane index) of vehicle ``vid``'s lane in SUMO, ("", -1) off the network: read from its lane's
    id, as libsumo 1.28's ``getRoadID`` crashed the process (SIGSEGV) for an ego placed off its lanes right
    after its insertion, on a sweep's random network. Raises TraCIException for a vehicle gone."""
    edge, _, index = api.vehicle.getLaneID(vid).rpartition("_")
    return (edge, int(index)) if edge else ("", -1)


class EgoRoute:
    """The placed ego's route in SUMO, kept whole. ``moveToXY`` in mode 2 (the ego's exact pose, counted on
    the lane it is on, whatever edge that is: SUMO's drivers see it where it is) replaces a moved vehicle's
    route by the edge it maps it onto when that edge is not on the route, as inside a junction where
    another connection's lane lies nearer than the ego's own. SUMO's drivers see a moved vehicle coming
    through a junction only by its route's next edges (eclipse-sumo/sumo#6140), so once the ego is back on
    an edge of its route, a cut route is replaced by the rest of irlsim's (the ``loop@<edge>`` route the
    traffic defines from each route edge). Asked only when the ego's edge changes; a route never cut (the
    oval's) is never touched."""

    def __init__(self, road: Road):
        n = len(road.edges)
        #: per route edge, the fewest edges a whole route has left from it (a loop: at least one more lap)
        self.rest = {e: (n if road.closed else n - i) for i, e in enumerate(road.edges)}
        self._on = ""

    def keep(self, api: Any, ego: str) -> None:
        """After a step: the ego on a new route edge with less of its route left than a whole one has, its
        route set to the rest of irlsim's from there. Only for an ego SUMO has inserted."""
        try:
            edge = lane_of(api, ego)[0]
            if edge == self._on:
                return
            self._on = edge
            if (
                edge in self.rest
                and len(api.vehicle.getRoute(ego)) - api.vehicle.getRouteIndex(ego) < self.rest[edge]
            ):
                api.vehicle.setRoute(ego, api.route.getEdges(f"loop@{edge}"))
        except api.TraCIException:  # off the network (arrived at its route's end)
            pass


def take_over(api: Any, ego: str, target_speed: float, vtype: str | None = None) -> None:
    """Hand the ego to SUMO: every safety check of its driver model, the road's limits, ``target_speed``.
    ``vtype``: a demonstrator's vehicle type (:mod:`irlsim.sim.vtype`), whose models and attributes,
    ``maxSpeed`` and ``speedFactor`` included, then drive the ego."""
    api.vehicle.setSpeedMode(ego, 31)
    if vtype is not None:
        api.vehicle.setType(ego, vtype)
        return
    api.vehicle.setSpeedFactor(ego, 1.0)
    api.vehicle.setMaxSpeed(ego, target_speed)


def sumo_step(api: Any, ego: str, road: Road, prev: EgoState) -> EgoState:
    """One SUMO step with SUMO driving the ego, and where it got to (route frame, unwrapped s). SUMO takes
    the ego off at its route's end: then the state is the route's end, which ends the episode."""
    api.simulationStep()
    if ego not in api.vehicle.getIDList():
        return dataclasses.replace(prev, t=float(api.simulation.getTime()), s=max(prev.s, road.route_end_s))
    x, y = api.vehicle.getPosition(ego)
    yaw = float(wrap_angle(np.radians(90.0 - api.vehicle.getAngle(ego))))
    # by progress from the step before, where the route comes back near itself
    s, d = road.to_frenet(np.array([x]), np.array([y]), near=prev.s)
    return EgoState(
        t=float(api.simulation.getTime()),
        x=float(x),
        y=float(y),
        yaw=yaw,
        v=float(api.vehicle.getSpeed(ego)),
        a=float(api.vehicle.getAcceleration(ego)),
        s=prev.s + float(wrap_route(float(s[0]) - prev.s, road.lap_length)),
        d=float(d[0]),
        d_dot=0.0,
        d_ddot=0.0,
        lane=int(road.lane_of_d(d)[0]),
    )
