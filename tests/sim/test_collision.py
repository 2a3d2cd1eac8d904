"""Oriented-box collision test against closed-form cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from irlsim.sim.collision import box_corners, collision_line, describe_collision, obb_collide, obb_penetration


def _pen(a, b):
    return float(obb_penetration(*a, *b))


def test_identical_boxes_collide():
    a = (0.0, 0.0, 0.3, 4.5, 1.8)
    assert obb_collide(*a, *a)
    assert _pen(a, a) == pytest.approx(1.8)  # the smallest extent: full width


def test_end_to_end_touching_is_no_collision():
    a = (0.0, 0.0, 0.0, 4.0, 2.0)  # spans x in [-4, 0]
    b = (4.0, 0.0, 0.0, 4.0, 2.0)  # spans x in [0, 4]
    assert _pen(a, b) == pytest.approx(0.0, abs=1e-12)
    assert not obb_collide(*a, *b)
    assert obb_collide(*a, *(3.99, 0.0, 0.0, 4.0, 2.0))
    assert _pen(a, (3.99, 0.0, 0.0, 4.0, 2.0)) == pytest.approx(0.01)
    assert _pen(a, (5.0, 0.0, 0.0, 4.0, 2.0)) == pytest.approx(-1.0)


def test_side_by_side():
    a = (0.0, 0.0, 0.0, 4.0, 2.0)
    assert not obb_collide(*a, *(0.0, 2.0, 0.0, 4.0, 2.0))  # touching sides
    assert obb_collide(*a, *(0.0, 1.9, 0.0, 4.0, 2.0))
    assert not obb_collide(*a, *(0.0, 3.2, 0.0, 4.0, 2.0))  # the next lane


def test_rotated_45_degrees_closed_form():
    """A 2x2 square at the origin and one rotated 45 deg whose corner points at it: they touch when the
    centres are 1 + sqrt(2) apart; the penetration is 1 + sqrt(2) - distance."""
    a = (1.0, 0.0, 0.0, 2.0, 2.0)  # front at x=1: centre at the origin

    def b(c):  # centre (c, 0), yaw 45 deg: front bumper half a length ahead of the centre
        yaw = math.pi / 4
        return (c + math.cos(yaw), math.sin(yaw), yaw, 2.0, 2.0)

    touch = 1.0 + math.sqrt(2.0)
    assert _pen(a, b(touch)) == pytest.approx(0.0, abs=1e-12)
    assert not obb_collide(*a, *b(touch + 1e-6))
    assert obb_collide(*a, *b(touch - 1e-3))
    assert _pen(a, b(touch - 0.1)) == pytest.approx(0.1)


def test_broadcasting_and_symmetry():
    rng = np.random.default_rng(0)
    ax, ay, ayaw = rng.uniform(-5, 5, (3, 6, 1))
    bx, by, byaw = rng.uniform(-5, 5, (3, 4))
    ab = obb_penetration(ax, ay, ayaw, 4.5, 1.8, bx, by, byaw, 4.0, 2.0)
    ba = obb_penetration(bx, by, byaw, 4.0, 2.0, ax, ay, ayaw, 4.5, 1.8)
    assert ab.shape == (6, 4)
    np.testing.assert_allclose(ab, ba)


def test_corners_from_front_bumper():
    c = box_corners(10.0, 0.0, math.pi / 2, 4.0, 2.0)  # heading north: left is west
    np.testing.assert_allclose(c, [[9.0, 0.0], [11.0, 0.0], [11.0, -4.0], [9.0, -4.0]], atol=1e-12)


@pytest.mark.parametrize(
    ("ds", "dd", "v_ego", "v_other", "dyaw", "lanes", "kind", "where"),
    [
        (-4.0, 0.2, 5.0, 12.0, 0.0, ("e_0", "e_0"), "rear-ended", "lane"),  # came from behind, faster
        (4.5, -0.3, 12.0, 3.0, 0.05, ("e_0", "e_0"), "ran-into", "lane"),  # the leader, in the ego's lane
        (1.0, 3.1, 10.0, 10.0, 0.1, ("e_0", "e_1"), "side", "lane"),  # the next lane: a lane change
        (2.0, 1.0, 8.0, 9.0, math.pi / 2, (":j_0_0", "f_0"), "crossing", "junction"),  # a foe at a junction
        (0.5, 0.0, 8.0, 9.0, 2 * math.pi - 0.1, ("e_0", ":j_1_0"), "ran-into", "junction"),  # wraps 2 pi
    ],
)
def test_a_collision_is_described_by_where_the_other_was(ds, dd, v_ego, v_other, dyaw, lanes, kind, where):
    c = describe_collision(ds, dd, v_ego, v_other, dyaw, *lanes, 3.2)
    assert (c["kind"], c["where"]) == (kind, where)
    deg = abs(math.degrees(dyaw))
    assert c["angle_deg"] == pytest.approx(min(deg, 360 - deg), abs=0.1)
    line = collision_line({"other": "bg7", **c})
    assert line.startswith(f"{kind} at a {where} (bg7,") and lanes[0] in line and lanes[1] in line
