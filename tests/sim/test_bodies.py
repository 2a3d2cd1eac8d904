"""Vehicle bodies in the ego's collision check: another car is one box along its heading, a long vehicle
and the ego a chain of boxes along the path its front drove. Closed-form cases: on a straight path the
chain is the rigid box (the same overlaps with any box); where the front has turned through a lane's
shift (SUMO's game crossing: a 16.25 m truck-trailer whose front turned 14-21 degrees) the chain stays in
its lane where the rigid box swings its rear across into the oncoming truck; and a car ego in a tight
turn does not swing its rear into the car turning beside it."""

from __future__ import annotations

import math

import numpy as np

from irlsim.sim.bodies import LONG_VEHICLE, Bodies, chain
from irlsim.sim.collision import obb_collide
from irlsim.sim.types import EgoState, VehicleStates

TRUCK = (16.25, 2.6)  # SUMO's game "truck/trailer": length, width [m]


def bend() -> tuple[list[tuple[float, float]], float, float, float]:
    """A front that drove north up x = 0 and then shifted 3 m east over 8 m (the lane's shift at a node):
    its trail (every 0.5 m), and its front and heading now."""
    north = [(0.0, y) for y in np.arange(-40.0, 0.0, 0.5)]
    shift = math.atan2(8.0, 3.0)  # ENU yaw of the shift: 21 degrees east of north
    on = [(3.0 * t, 8.0 * t) for t in np.linspace(0.0, 1.0, 17)]
    return north + on[:-1], on[-1][0], on[-1][1], shift


def state(x: float, y: float, yaw: float) -> EgoState:
    return EgoState(t=0.0, x=x, y=y, yaw=yaw, v=10.0, a=0.0, s=0.0, d=0.0, d_dot=0.0, d_ddot=0.0, lane=0)


def test_a_car_is_one_box_along_its_heading():
    parts = chain([(0.0, -30.0)], 1.0, 2.0, 0.3, LONG_VEHICLE, 1.8)
    assert [p.tolist() for p in parts] == [[1.0], [2.0], [0.3], [LONG_VEHICLE], [1.8]]


def test_on_a_straight_path_the_chain_is_the_rigid_box():
    length, width = TRUCK
    yaw = 0.7
    trail = [(-s * math.cos(yaw), -s * math.sin(yaw)) for s in np.arange(30.0, 0.0, -0.25)]
    x, y, pyaw, plen, pwid = chain(trail, 0.0, 0.0, yaw, length, width)
    assert len(x) == 4 and np.allclose(pyaw, yaw) and np.allclose(plen, length / 4) and plen.sum() == length
    assert np.allclose(np.hypot(x, y), [0.0, length / 4, length / 2, 3 * length / 4])
    # any box overlaps the chain exactly where it overlaps the rigid box (none straddles a joint only)
    rng = np.random.default_rng(0)
    ox, oy = rng.uniform(-25.0, 10.0, 400), rng.uniform(-20.0, 10.0, 400)
    oyaw = rng.uniform(-math.pi, math.pi, 400)
    rigid = obb_collide(0.0, 0.0, yaw, length, width, ox, oy, oyaw, 4.5, 1.8)
    parts = obb_collide(x[:, None], y[:, None], pyaw[:, None], plen[:, None], width, ox, oy, oyaw, 4.5, 1.8)
    assert rigid.sum() > 20 and np.array_equal(rigid, parts.any(axis=0))
    # without a trail (just appeared) it goes straight back along the heading: the same boxes
    assert np.allclose(chain([], 0.0, 0.0, yaw, length, width)[0], x)


def test_through_a_lanes_shift_the_chain_stays_in_its_lane():
    length, width = TRUCK
    trail, x, y, yaw = bend()
    # the oncoming truck in the next lane to the west (3.2 m), heading south, alongside the trailer
    other = (-3.2, -8.0, -math.pi / 2, length, width)
    assert obb_collide(x, y, yaw, length, width, *other)  # the rigid box swings its rear across
    px, py, pyaw, plen, pwid = chain(trail, x, y, yaw, length, width)
    assert not obb_collide(px, py, pyaw, plen, pwid, *other).any()
    assert abs(px[-1] - plen[-1] * math.cos(pyaw[-1])) < 0.01  # the rear part is back on x = 0
    # a car run into the trailer's rear on its own lane is hit by the chain
    assert obb_collide(px, py, pyaw, plen, pwid, 0.3, -7.0, math.pi / 2, 4.5, 1.8).any()


def test_the_simulation_check_keeps_each_long_vehicles_path():
    """A truck drives the bend step by step past a car coming south in the next lane: Bodies keeps its
    trail and never sees the car hit, where the rigid boxes would at the last step; the car's own check is
    one box, and a long ego is a chain from its own trail too."""
    length, width = TRUCK
    trail, x, y, yaw = bend()
    bodies = Bodies()
    car = state(-3.2, -9.0, -math.pi / 2)
    path = [*trail, (x, y)]
    for k, (tx, ty) in enumerate(path):
        heading = yaw if k >= len(trail) - 16 else math.pi / 2
        veh = VehicleStates(
            ("truck",), *(np.array([v]) for v in (tx, ty, heading, 10.0, 0.0, 0.0, length, width))
        )
        hit = bodies.hits(car, 4.5, 1.8, veh, np.array([0]))
        assert not hit[0], k
    assert obb_collide(car.x, car.y, car.yaw, 4.5, 1.8, x, y, yaw, length, width)  # rigid: a false hit
    assert len(bodies.trails["truck"]) > 2 and len(bodies.ego_trail) == 1  # the standing car's own trail
    # the truck as the ego, the car as the other: the same chain from the ego's own trail
    ego_bodies = Bodies()
    none = VehicleStates.empty()
    for tx, ty in trail:
        ego_bodies.hits(state(tx, ty, math.pi / 2), length, width, none, np.zeros(0, int))
    ego = state(x, y, yaw)
    oncoming = VehicleStates(
        ("car",), *(np.array([v]) for v in (-3.2, -9.0, -math.pi / 2, 10.0, 0.0, 0.0, 4.5, 1.8))
    )
    assert not ego_bodies.hits(ego, length, width, oncoming, np.array([0]))[0]
    ego_bodies = Bodies()  # a new episode's
    assert ego_bodies.hits(ego, length, width, oncoming, np.array([0]))[0]  # no trail: the rigid box


def test_a_car_ego_turning_tightly_is_a_box_along_its_path():
    """Through a junction's right turn of 6 m radius a 4.5 m car's body lies along the chord from its front
    to where its front was 4.5 m before (its rear follows the path); a box along its front's heading
    swings its rear 1.5 m outwards (sqrt(6^2 + 4.5^2) - 6) into the car turning beside it 3.2 m further
    out and 1 m behind, whose heading SUMO gives from its rear to its front (both on its lane), which its
    body does not touch."""
    r, length, width = 6.0, 4.5, 1.8
    ang = np.arange(0.0, math.pi / 2, 0.25 / r)  # clockwise round (0, 0) from the top: a right turn
    pts = [(r * math.sin(a), r * math.cos(a)) for a in ang]
    bodies = Bodies()
    for px, py in pts[:-1]:
        bodies.hits(state(px, py, 0.0), length, width, VehicleStates.empty(), np.zeros(0, int))
    a = ang[-1]
    x, y, yaw = pts[-1][0], pts[-1][1], -a  # the front, heading along the turn (ENU: east at the top)
    out = r + 3.2  # the car in the next lane's turn, its front 1 m behind the ego's
    ao = a - 1.0 / out
    fx, fy = out * math.sin(ao), out * math.cos(ao)
    back = ao - length / out  # where its rear is on its lane
    chord = math.atan2(fy - out * math.cos(back), fx - out * math.sin(back))
    box = (fx, fy, chord, 4.5, 1.8)
    other = VehicleStates(("car",), *(np.array([v]) for v in (fx, fy, chord, 5.0, 0.0, 0.0, 4.5, 1.8)))
    assert obb_collide(x, y, yaw, length, width, *box)  # along the front's heading: a hit
    assert not bodies.hits(state(x, y, yaw), length, width, other, np.array([0]))[0]  # along its path: none
    # a recorded ego replayed as recorded keeps the box along its (recorded) heading
    rigid = Bodies(ego_along_path=False)
    for px, py in pts[:-1]:
        rigid.hits(state(px, py, 0.0), length, width, VehicleStates.empty(), np.zeros(0, int))
    assert rigid.hits(state(x, y, yaw), length, width, other, np.array([0]))[0]


def test_a_lane_change_in_one_step_does_not_lay_the_body_across_both_lanes():
    """SUMO's instantaneous lane change moves a vehicle 3.2 m sideways in one step: the trail starts again
    there, so the body of the car that stands after it lies in its new lane, not across into the old one,
    where a car passes."""
    bodies = Bodies()
    for y in np.arange(-30.0, 0.0, 0.5):  # north along x = 0, then one step to x = 3.2, and it stands
        bodies.hits(state(0.0, float(y), math.pi / 2), 4.5, 1.8, VehicleStates.empty(), np.zeros(0, int))
    for _ in range(3):
        bodies.hits(state(3.2, 0.0, math.pi / 2), 4.5, 1.8, VehicleStates.empty(), np.zeros(0, int))
    assert bodies.ego_trail == [(3.2, 0.0)]  # begun again in the new lane
    passing = VehicleStates(
        ("car",), *(np.array([v]) for v in (0.0, -1.5, math.pi / 2, 5.0, 0.0, 0.0, 4.5, 1.8))
    )  # in the old lane, its front 1.5 m behind the ego's
    assert not bodies.hits(state(3.2, 0.0, math.pi / 2), 4.5, 1.8, passing, np.array([0]))[0]
