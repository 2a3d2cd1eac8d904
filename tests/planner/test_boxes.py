"""Route-frame boxes of turned vehicles (irlsim.planner.planner.route_frame_boxes), against closed forms."""

from __future__ import annotations

import dataclasses

import numpy as np

from irlsim.planner.planner import BOX_TURN_MIN, route_frame_boxes
from tests.planner.conftest import make_vehicles


def turned(road, s: float, d: float, theta: float):
    v = make_vehicles(road, [(s, d, 0.0)])
    return dataclasses.replace(v, yaw=v.yaw + theta)


def test_an_aligned_or_slightly_turned_vehicle_keeps_its_box(road):
    v = make_vehicles(road, [(100.0, 0.0, 5.0), (300.0, 3.2, 0.0)])
    assert route_frame_boxes(road, v) is v
    slight = turned(road, 100.0, 0.0, 0.9 * BOX_TURN_MIN)
    out = route_frame_boxes(road, slight)
    for f in ("s", "d", "length", "width"):
        np.testing.assert_array_equal(getattr(out, f), getattr(slight, f))


def test_a_vehicle_across_the_route_is_as_long_as_it_is_wide_and_centred_on_its_body(road):
    """Turned 90 degrees to the left on a straight stretch: its 4.5 m body lies across the route, its centre
    2.25 m to the right of its front bumper; in the frame 1.8 m long and 4.5 m wide about that centre."""
    s0 = 100.0  # on the oval's straight
    assert abs(float(road.curvature(np.array([s0]))[0])) < 1e-6
    out = route_frame_boxes(road, turned(road, s0, 1.0, np.pi / 2))
    np.testing.assert_allclose(out.length, [1.8], atol=1e-9)
    np.testing.assert_allclose(out.width, [4.5], atol=1e-9)
    np.testing.assert_allclose(out.d, [1.0 - 2.25], atol=1e-9)
    np.testing.assert_allclose(out.s, [s0 + 0.9], atol=1e-9)  # centre s0, front half a length ahead


def test_a_turned_box_is_the_bounding_box_of_the_rotated_body(road):
    theta = np.radians(30.0)
    out = route_frame_boxes(road, turned(road, 100.0, 0.0, -theta))
    c, s = np.cos(theta), np.sin(theta)
    np.testing.assert_allclose(out.length, [4.5 * c + 1.8 * s], atol=1e-9)
    np.testing.assert_allclose(out.width, [4.5 * s + 1.8 * c], atol=1e-9)
    np.testing.assert_allclose(out.d, [0.0 + 2.25 * s], atol=1e-9)  # turned right: the body lies left


def test_on_the_oval_no_vehicle_is_ever_moved_to_the_ego_s_pass(road):
    """The other-pass rule moves a vehicle within OTHER_PASS_REACH of the ego that the frame puts further
    along the route than it is away. On the oval no two places of the road (reference +- its half width)
    are that close in space and that far apart along the route, so the rule never applies there and the
    oval's policy sets keep their bytes."""
    from irlsim.planner.planner import OTHER_PASS_REACH

    xy, s, lap = road.ref_xy, road.ref_s, road.lap_length
    dist = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    along = np.abs((s[:, None] - s[None, :] + lap / 2) % lap - lap / 2)
    slack = 2 * road.half_road  # a vehicle and the ego anywhere across their stretch
    assert not ((dist < OTHER_PASS_REACH + slack) & (along > dist + OTHER_PASS_REACH - slack)).any()
