"""Distance to the demonstration and its streaming projection (docs/design/demonstrations.md)."""

from __future__ import annotations

import numpy as np
import pytest

from irlsim.data.demos import ALPHA, W_YAW, DemoProjector, policy_distance
from tests.data.conftest import DT, LAP, T, make_policy_set


def test_hand_computed_tiny_case() -> None:
    # 3 steps, alpha 0.5, w_yaw 5: per-step costs 5*0.1^2 = 0.05, hypot(3, 4) = 5, 0
    pol_s, pol_d, pol_yaw = (
        np.array([[0.0, 3.0, 2.0]]),
        np.array([[0.0, 4.0, 1.0]]),
        np.array([[0.1, 0.0, 0.0]]),
    )
    demo_s, demo_d, demo_yaw = np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, 1.0]), np.zeros(3)
    d = policy_distance(
        pol_s, pol_d, pol_yaw, demo_s, demo_d, demo_yaw, alpha=0.5, w_yaw=5.0, lap_length=None
    )
    assert d.dtype == np.float32 and d.shape == (1,)
    assert d[0] == pytest.approx((0.05 + 0.5 * 5.0 + 0.25 * 0.0) / 1.75, rel=1e-6)


def test_constant_lateral_offset_is_exact() -> None:
    rng = np.random.default_rng(0)
    demo_s = np.cumsum(rng.uniform(1, 3, T)) + 500
    demo_yaw = rng.uniform(-3, 3, T)
    demo_d = rng.uniform(-2, 2, T)
    d = policy_distance(
        demo_s[None],
        demo_d[None] + 0.5,
        demo_yaw[None],
        demo_s,
        demo_d,
        demo_yaw,
        alpha=ALPHA,
        w_yaw=W_YAW,
        lap_length=LAP,
    )
    assert d[0] == np.float32(0.5)


def test_wrap_around_at_the_lap_seam() -> None:
    tau = np.arange(T) * DT
    pol_s = (LAP - 1.0 + 20.0 * tau)[None]  # unwrapped, crosses the start line
    demo_s = np.mod(LAP - 1.0 + 20.0 * tau, LAP)  # odometry wrapped at the seam
    zeros = np.zeros((1, T))
    d = policy_distance(pol_s, zeros, zeros, demo_s, zeros[0], zeros[0], lap_length=LAP)
    assert d[0] == pytest.approx(0.0, abs=1e-9)
    # heading across +-pi: 0.1 rad apart, not 2 pi - 0.1
    d = policy_distance(
        zeros, zeros, zeros + np.pi - 0.05, zeros[0], zeros[0], zeros[0] - np.pi + 0.05, lap_length=LAP
    )
    assert d[0] == pytest.approx(W_YAW * 0.1**2, rel=1e-5)


def test_batch_dimensions_match_single_calls() -> None:
    rng = np.random.default_rng(1)
    b, n = 4, 7
    pol = [rng.normal(size=(b, n, T)) * 3 for _ in range(3)]
    demo = [rng.normal(size=(b, T)) * 3 for _ in range(3)]
    batched = policy_distance(*pol, *demo, lap_length=LAP)
    assert batched.shape == (b, n)
    for i in range(b):
        single = policy_distance(*(p[i] for p in pol), *(q[i] for q in demo), lap_length=LAP)
        np.testing.assert_array_equal(batched[i], single)


def _drive(push_cycle_late: bool) -> tuple[dict[int, tuple[np.ndarray, int, float]], dict, list]:
    """A wobbly ego; cycles every 2 steps. Returns projections, the policy sets and the odometry."""
    rng = np.random.default_rng(2)
    proj = DemoProjector(lap_length=LAP, horizon=5.0, dt=DT)
    sets, odo, out = {}, [], {}
    n_steps = 150
    for step in range(n_steps):
        t = step * DT + 1e-9 * rng.normal()  # float drift is matched by rounding
        s, d, yaw = 10.0 + 20.0 * step * DT, 0.3 * np.sin(step / 7), 0.05 * np.cos(step / 5)
        odo.append((s, d, yaw))
        if step % 2 == 0:
            ps = make_policy_set(rng, 30, t, s)
            sets[step // 2] = (ps, step)
            if not push_cycle_late:
                proj.push_cycle(step // 2, t, ps.s, ps.d, ps.yaw)
        proj.push_odometry(t, s, d, yaw)
        if push_cycle_late and step % 2 == 0:
            proj.push_cycle(step // 2, t, ps.s, ps.d, ps.yaw)
        for p in proj.pop_ready():
            out[p.cycle_index] = (p.distances, p.demo_index, p.demo_distance)
        assert proj.n_pending <= 26  # only cycles with incomplete windows are buffered
    for p in proj.finish():
        out[p.cycle_index] = (p.distances, p.demo_index, p.demo_distance)
    return out, sets, odo


@pytest.mark.parametrize("push_cycle_late", [False, True])
def test_projector_matches_batch_distance_and_argmin(push_cycle_late: bool) -> None:
    out, sets, odo = _drive(push_cycle_late)
    assert sorted(out) == sorted(sets)
    odo_arr = np.array(odo)
    n_complete = 0
    for k, (ps, step) in sets.items():
        dist, idx, demo_d = out[k]
        if step + T > len(odo):
            assert idx == -1 and np.isnan(demo_d) and np.isnan(dist).all()
            continue
        n_complete += 1
        win = odo_arr[step : step + T]
        expected = policy_distance(ps.s, ps.d, ps.yaw, win[:, 0], win[:, 1], win[:, 2], lap_length=LAP)
        np.testing.assert_allclose(dist, expected, rtol=1e-5, atol=1e-5)
        best = int(np.argmin(dist))
        if dist[best] <= 1.5:
            assert idx == best and demo_d == pytest.approx(float(dist[best]))
        else:
            assert idx == -1 and np.isnan(demo_d)
    assert n_complete == (150 - T) // 2 + 1


def test_a_window_projected_at_once_is_the_streaming_projection() -> None:
    """``project_window`` (DAgger's SUMO labeller: one cycle's look ahead) gives the streaming projector's
    demonstration of the same odometry, leaves its buffers alone, and none for a look ahead cut short."""
    out, sets, odo = _drive(False)
    proj = DemoProjector(lap_length=LAP, horizon=5.0, dt=DT)
    for k, (ps, step) in list(sets.items())[:30]:
        rows = [(j * DT, *odo[j]) for j in range(step, min(step + T, len(odo)))]
        p = proj.project_window(k, step * DT, (ps.s, ps.d, ps.yaw), rows)
        dist, idx, demo_d = out[k]
        assert p.cycle_index == k and p.demo_index == idx
        np.testing.assert_array_equal(p.distances, dist)
        assert (np.isnan(demo_d) and np.isnan(p.demo_distance)) or p.demo_distance == demo_d
        short = proj.project_window(k, step * DT, (ps.s, ps.d, ps.yaw), rows[:-1])
        assert short.demo_index == -1 and np.isnan(short.distances).all()
    assert proj.n_pending == 0


def test_a_sumo_lane_jump_or_kept_offset_is_labelled_by_the_nearest_policy_into_its_lane() -> None:
    from irlsim.data.demos import Projection, lane_jump_projection

    w = 3.2
    dist = np.array([1.9, 2.6, 2.2, 3.0, np.nan], dtype=np.float32)  # none within the 1.5 m limit
    end_d = np.array([0.0, 3.2, 3.1, -3.2, 3.2])  # keep, left, left, right, left (distance unknown)
    jump = np.r_[np.zeros(3), np.full(48, 3.2)]  # SUMO's driver moved a lane left in one step
    lost = Projection(7, dist, -1, float("nan"))
    p = lane_jump_projection(lost, end_d, jump, w)
    assert (p.cycle_index, p.demo_index) == (7, 2) and p.demo_distance == pytest.approx(2.2)
    # otherwise as it was: no jump, a demonstration found, an incomplete window, no policy in that lane
    assert lane_jump_projection(lost, end_d, np.linspace(0, 3.2, 51), w) is lost
    found = Projection(7, dist, 0, 1.0)
    assert lane_jump_projection(found, end_d, jump, w) is found
    empty = Projection(7, np.full(5, np.nan, np.float32), -1, float("nan"))
    assert lane_jump_projection(empty, end_d, jump, w) is empty
    assert lane_jump_projection(lost, np.zeros(5), jump, w) is lost
    # the look ahead at SUMO's lane's centre, the placed ego 1.2 m to its left: no jump, the lane kept
    centred = np.r_[1.2, np.zeros(50)]
    assert lane_jump_projection(lost, end_d, centred, w) is lost  # the offset not given: as it was
    p = lane_jump_projection(lost, end_d, centred, w, lane_offset=1.2)
    assert p.demo_index == 0 and p.demo_distance == pytest.approx(1.9)  # the nearest keeping the lane
    assert lane_jump_projection(lost, end_d, centred, w, lane_offset=0.01) is lost  # on the centre
    assert lane_jump_projection(found, end_d, centred, w, lane_offset=1.2) is found


def test_threshold_rejects_far_demonstrations() -> None:
    rng = np.random.default_rng(3)
    proj = DemoProjector(lap_length=LAP, max_demo_distance=1.5)
    ps = make_policy_set(rng, 10, 0.0, 0.0, match=False)
    ps.d[:] = 5.0  # every policy 5 m to the left of the ego
    proj.push_cycle(0, 0.0, ps.s, ps.d, ps.yaw)
    for step in range(T):
        proj.push_odometry(step * DT, ps.s[0, step], 0.0, 0.0)
    (p,) = proj.pop_ready()
    assert p.demo_index == -1 and np.isnan(p.demo_distance) and np.isfinite(p.distances).all()
    assert p.distances.min() >= 5.0


def test_missing_odometry_step_means_incomplete_window() -> None:
    rng = np.random.default_rng(4)
    proj = DemoProjector(lap_length=LAP)
    ps = make_policy_set(rng, 10, 0.0, 0.0)
    proj.push_cycle(0, 0.0, ps.s, ps.d, ps.yaw)
    for step in range(T):
        if step != 20:
            proj.push_odometry(step * DT, 20.0 * step * DT, 0.0, 0.0)
    (p,) = proj.pop_ready()
    assert p.demo_index == -1 and np.isnan(p.distances).all()


def test_safe_demo_index_moves_colliding_demonstrations_to_the_closest_safe_policy():
    """Hand-made cycles: (0) demo labelled collision, a safe policy at 0.4 m -> moved there; (1) demo not
    labelled -> unchanged; (2) labelled, the only safe policy 2.0 m away (> 1.5 m) -> no demonstration;
    (3) no demonstration -> stays -1; (4) labelled, the closest safe policy's window is NaN -> the next."""
    from irlsim.data.demos import safe_demo_index

    demo = np.array([0, 1, 0, -1, 2])
    dist = np.array(
        [
            [0.1, 0.5, 0.4, 0.9],
            [0.3, 0.1, 0.2, 0.2],
            [0.1, 2.0, 3.0, 2.5],
            [0.1, 0.2, 0.3, 0.4],
            [np.nan, 0.7, 0.2, 1.0],
        ],
        dtype=np.float32,
    )
    coll = np.array(
        [
            [True, True, False, False],
            [False, False, True, True],
            [True, False, True, True],
            [True, True, True, True],
            [False, False, True, False],
        ]
    )
    out = safe_demo_index(demo, dist, coll)
    np.testing.assert_array_equal(out, [2, 1, -1, -1, 1])
    np.testing.assert_array_equal(demo, [0, 1, 0, -1, 2])  # the input is not modified
    assert out.dtype == np.int64
    # no labelled demonstration: the same indices
    np.testing.assert_array_equal(safe_demo_index(demo, dist, np.zeros_like(coll)), demo)


def test_safe_demo_index_moves_stop_line_crossings_and_combines_the_rules():
    """Hand-made cycles with the stop_line feature: (0) demo crosses (f > 0), a policy at 0.3 m does not ->
    moved there; (1) demo does not cross -> unchanged; (2) crosses, the closest non-crossing policy is
    labelled collision: with the stop rule alone it goes there (0.2 m), with both to the next (0.6 m)."""
    from irlsim.data.demos import safe_demo_index

    demo = np.array([0, 2, 0])
    dist = np.array([[0.1, 0.3, 0.9], [0.5, 0.4, 0.1], [0.1, 0.2, 0.6]], dtype=np.float32)
    stop = np.array([[1.2, 0.0, 0.0], [0.9, 0.0, 0.0], [1.1, 0.0, 0.0]], dtype=np.float32)
    coll = np.array([[False, False, False], [False, False, False], [False, True, False]])
    np.testing.assert_array_equal(safe_demo_index(demo, dist, None, stop_line=stop), [1, 2, 1])
    np.testing.assert_array_equal(safe_demo_index(demo, dist, coll, stop_line=stop), [1, 2, 2])
    # the collision rule alone leaves every crossing demonstration where it was
    np.testing.assert_array_equal(safe_demo_index(demo, dist, coll), demo)
