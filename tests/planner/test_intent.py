"""A vehicle turning into the road inside a junction, predicted along its way into the route (its lanes'
centre line, :mod:`irlsim.sim.intent`): pure logic on the oval's frame, the way given as xy points."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from irlsim.planner.planner import path_motion, route_frame_boxes
from irlsim.sim.intent import PATH_POINTS, along
from irlsim.sim.types import PATH_STEP, VehicleStates
from tests.planner.conftest import make_obs, make_vehicles

T = np.arange(50) * 0.1


def _turning_in(road, d_front: float, v: float = 4.0, path: bool = True) -> VehicleStates:
    """A car 25 m ahead of s = 1000 m at the road's right, turned across it (pointing left); its way goes
    straight across to the right lane's centre, then along it."""
    right = float(road.lane_center(0))
    car = make_vehicles(road, [(1025.0, d_front, v)])
    car = dataclasses.replace(car, yaw=road.heading(car.s) + np.pi / 2)
    if not path:
        return car
    s = np.concatenate([[1025.0], np.arange(1025.0, 1110.0)])  # across, then along the lane's centre
    x, y = road.to_xy(s, np.concatenate([[d_front], np.full(len(s) - 1, right)]))
    way = along(np.stack([x, y], axis=1), np.arange(PATH_POINTS) * PATH_STEP)
    return dataclasses.replace(car, path=way[None])


def test_along_a_polyline_and_straight_on_beyond_it():
    xy = np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 4.0], [3.0, 10.0]])  # 5 m, a repeated point, 6 m
    np.testing.assert_allclose(
        along(xy, np.array([0.0, 2.5, 5.0, 8.0, 11.0, 13.0])),
        [[0, 0], [1.5, 2.0], [3, 4], [3, 7], [3, 10], [3, 12]],
        atol=1e-12,
    )


def test_a_car_turning_in_moves_along_its_way(road):
    right = float(road.lane_center(0))
    car = route_frame_boxes(road, _turning_in(road, right - 4.0), t=T)
    assert car.motion is not None
    ds, dd = car.motion[0, :, 0], car.motion[0, :, 1]
    # 4 m/s: 4 m across to the lane's centre in the first second, then along the lane
    reach = 4.0 * T
    np.testing.assert_allclose(dd, np.minimum(reach, 4.0), atol=0.05)
    # (along the lane, off the reference on a curve, a metre of the lane is 1 / (1 - kappa d) of s)
    np.testing.assert_allclose(ds, np.maximum(reach - 4.0, 0.0), rtol=0.02, atol=0.05)
    # the displacement is the path's, from where the car is now, in the frame's own terms
    s, d = path_motion(road, car.path, car.v, car.s, np.array([0.0, 2.0]))[0].T
    assert (s[0], d[0]) == (0.0, 0.0) and d[1] == pytest.approx(4.0, abs=0.05)


def test_only_a_turned_car_with_a_way_into_the_route_moves_along_it(road):
    right = float(road.lane_center(0))
    # turned, but SUMO gave no way into the route (crossing the junction, turning off it): as before
    assert route_frame_boxes(road, _turning_in(road, right - 4.0, path=False), t=T).motion is None
    # along the road with a way (a car on a junction's lane of the route itself): as before, so the
    # oval's features keep their bytes
    along_road = make_vehicles(road, [(1030.0, right, 10.0)])
    x, y = road.to_xy(1030.0 + np.arange(PATH_POINTS) * PATH_STEP, np.full(PATH_POINTS, right))
    along_road = dataclasses.replace(along_road, path=np.stack([x, y], axis=1)[None])
    assert route_frame_boxes(road, along_road, t=T).motion is None
    # without the horizon's times (a picture's boxes): no motion
    assert route_frame_boxes(road, _turning_in(road, right - 4.0)).motion is None


def test_the_planner_sees_a_car_turning_into_its_lane(road, planner):
    """The ego in the right lane at 10 m/s, a car 25 m ahead still off the road and turning into that lane:
    with its way the policies that keep the lane at speed meet it; without (constant d), none does."""
    right = float(road.lane_center(0))
    labelled = {}
    for way in (False, True):
        car = _turning_in(road, right - 4.0, path=way)
        ps = planner.plan(make_obs(road, 1000.0, right, 10.0, vehicles=car))
        keep = ps.lane[:, -1] == 0
        labelled[way] = ps.labels[keep, 0].mean()
    assert labelled[False] == 0.0 and labelled[True] > 0.2, labelled
