"""The SUMO episode, headless with libsumo: traffic, ego placement, collisions, bookkeeping, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from irlsim.sim.config import EpisodeConfig
from irlsim.sim.drivers import SimpleDriver, frenet_trajectory
from irlsim.sim.simulation import TIMING_KEYS, Simulation
from irlsim.sim.types import Trajectory


def _drive(sim, driver, seed, min_steps=0, laps=None):
    obs = sim.reset(seed)
    while not sim.done:
        sim.execute(driver.plan(obs))
        obs = sim.observe()
        if len(sim.odometry) > min_steps and (laps is None or sim.episode.laps_completed >= laps):
            break
    return obs


@pytest.fixture(scope="module")
def lap_run(sim, road):
    """SimpleDriver with 15 background vehicles: at least 3,000 steps and one lap."""
    _drive(sim, SimpleDriver(road, sim.cfg), seed=7, min_steps=3000, laps=1)
    return dict(sim.stats), list(sim.traffic.failures), sim.odometry_arrays()


def test_simple_driver_lap_without_collision_stopping_at_both_lines(lap_run):
    st, _, odo = lap_run
    assert st["sim/steps"] >= 3000 and st["sim/laps"] >= 1
    assert st["sim/collisions"] == 0 and st["sim/sumo_collisions"] == 0
    assert st["sim/exits"] == 0 and st["sim/offroad_steps"] == 0
    assert st["sim/stop_lines_passed"] >= 2
    assert st["sim/stop_lines_compliant"] == st["sim/stop_lines_passed"]
    assert st["sim/checkpoints_passed"] >= 4
    assert len(odo["t"]) == st["sim/steps"] + 1
    np.testing.assert_allclose(np.diff(odo["t"]), 0.1, atol=1e-9)


def test_background_traffic_over_3000_steps(lap_run):
    st, failures, _ = lap_run
    assert st["sim/teleports"] == 0  # 0 by construction (--time-to-teleport -1): bg_stuck is the check
    assert st["sim/bg_stuck"] == 0, "background vehicles stood still > 10 s outside a stop-line queue"
    assert st["sim/bg_stop_lines_passed"] >= 15
    assert failures == [], f"background vehicles passed stop lines without stopping: {failures[:3]}"
    assert st["sim/bg_stop_lines_compliant"] == st["sim/bg_stop_lines_passed"]
    assert st["sim/bg_off_loop"] == 0
    assert st["sim/bg_collisions"] == 0


def test_traffic_is_kept_full_and_recycled_ahead(sim, road):
    """A ghost ego 12 m inside the loop at 20 m/s overtakes everyone: vehicles that fall behind are
    recycled ahead, the count stays at n_vehicles, none ends up far behind."""
    obs = sim.reset(1)
    assert obs.vehicles.count == 15
    for k in range(300):
        n = 51
        d = np.linspace(obs.ego.d, 12.0, n) if k == 0 else np.full(n, 12.0)
        sim.execute(frenet_trajectory(road, obs.ego, 0.1, np.full(n, 20.0), d))
        obs = sim.observe()
    st = sim.stats
    assert st["sim/bg_recycled"] > 10 and st["sim/collisions"] == 0 and st["sim/teleports"] == 0
    assert obs.vehicles.count >= 14  # one may be between removal and insertion
    rel = (obs.vehicles.s - obs.ego.s + road.lap_length / 2) % road.lap_length - road.lap_length / 2
    assert rel.min() >= -sim.cfg.recycle_behind - 5.0
    assert rel.max() <= sim.cfg.spawn_distance + sim.cfg.spawn_jitter + 5.0


def _jump(road, obs, s1, d1) -> Trajectory:
    """A 3-state trajectory that puts the ego at (s1, d1) at the next step."""
    e = obs.ego
    s = np.array([e.s, s1, s1 + 1.0])
    d = np.array([e.d, d1, d1])
    x, y = road.to_xy(s, d)
    z = np.zeros(3)
    return Trajectory(e.t, 0.1, x, y, road.heading(s), np.full(3, 5.0), z, s, d, z, z, road.lane_of_d(d))


def _target(road, obs, lane):
    veh = obs.vehicles
    lanes = road.lane_of_d(veh.d)
    i = int(np.flatnonzero(lanes == lane)[0])
    s1 = obs.ego.s + (veh.s[i] - obs.ego.s) % road.lap_length + veh.v[i] * 0.1  # where it is after the step
    return i, s1, float(veh.d[i])


def test_ego_placed_through_a_vehicle_is_a_collision(sim, road):
    obs = sim.reset(3)
    _, s1, d1 = _target(road, obs, lane=0)
    sim.execute(_jump(road, obs, s1, d1), n_steps=1)
    st = sim.stats
    assert st["sim/collisions"] == 1 and st["end_reason"] == "collision"
    assert st["sim/sumo_collisions"] >= 1
    # what it was: the ego put onto the vehicle in its own lane, on the loop's lanes, not at a junction
    c = sim.first_collision
    assert c is not None and c["other"] in obs.vehicles.ids and c["where"] == "lane"
    assert abs(c["dd_m"]) < road.lane_width / 2 and c["kind"] in ("ran-into", "rear-ended", "side")
    assert not c["ego_lane"].startswith(":") and c["angle_deg"] < 30


def test_ego_two_lanes_away_is_no_collision(sim, road):
    obs = sim.reset(3)
    _, s1, d1 = _target(road, obs, lane=0)
    assert not np.any(
        (np.abs((obs.vehicles.s - s1 + 1000) % road.lap_length - 1000) < 15)
        & (road.lane_of_d(obs.vehicles.d) == 2)
    ), "seed 3 should leave lane 2 free beside the target"
    sim.execute(_jump(road, obs, s1, d1 + 6.4), n_steps=1)
    st = sim.stats
    assert st["sim/collisions"] == 0 and st["end_reason"] is None
    assert sim.first_collision is None


def test_same_seed_same_figures(sim, road):
    drv = SimpleDriver(road, sim.cfg)
    runs = []
    for seed in (11, 11, 12):
        _drive(sim, drv, seed, min_steps=400)
        st = {k: v for k, v in sim.stats.items() if k not in TIMING_KEYS}
        runs.append((st, sim.odometry_arrays(), sim.observe().vehicles))
    (a, oa, va), (b, ob, vb), (_, oc, vc) = runs
    assert a == b
    for k in oa:
        np.testing.assert_array_equal(oa[k], ob[k])
    np.testing.assert_array_equal(va.x, vb.x)
    assert va.ids == vb.ids
    assert not (len(va.x) == len(vc.x) and np.array_equal(va.x, vc.x))


def test_executed_state_is_the_trajectory_state(sim, road):
    obs = sim.reset(5)
    tr = SimpleDriver(road, sim.cfg).plan(obs)
    sim.execute(tr)
    e = sim.observe().ego
    want = tr.state(2)
    assert (e.x, e.y, e.v, e.s, e.d) == (want.x, want.y, want.v, want.s, want.d)
    assert e.t == pytest.approx(want.t)
    with pytest.raises(ValueError, match="does not start"):
        sim.execute(tr)  # stale plan


def test_lifecycle(road):
    s = Simulation(road, EpisodeConfig(n_vehicles=2))
    with pytest.raises(RuntimeError, match="reset"):
        s.observe()
    with s:
        obs = s.reset(0)
        assert obs.vehicles.count == 2 and obs.stop_s > obs.ego.s and obs.target_s > obs.ego.s
        s.step()
    s.close()
    s.close()  # safe twice
    from irlsim.errors import IrlsimError

    with pytest.raises(IrlsimError, match="seed"):
        s.reset(-1)
    with pytest.raises(IrlsimError, match="0..2147483647"):
        s.reset(2**31)


def test_random_start_is_a_function_of_the_seed(sim, road):
    """Same seed, same start (and traffic); another seed, another start; traffic laid out around it."""
    a, b, c = (sim.reset(seed) for seed in (21, 21, 22))
    key = [(o.ego.s, o.ego.d, o.ego.v, o.ego.lane, o.ego.x, o.ego.y) for o in (a, b, c)]
    assert key[0] == key[1] and key[0][0] != key[2][0]
    np.testing.assert_array_equal(a.vehicles.s, b.vehicles.s)
    lap = road.lap_length
    rel = (c.vehicles.s - c.ego.s + lap / 2) % lap - lap / 2
    assert c.vehicles.count == 15
    assert rel.min() >= -sim.cfg.recycle_behind - 1.0
    assert rel.max() <= sim.cfg.spawn_distance + sim.cfg.spawn_jitter + 1.0
    assert np.abs(rel).min() >= sim.cfg.spawn_clearance


def test_random_start_keeps_clear_of_stop_lines_exits_and_checkpoints(road):
    from irlsim.errors import IrlsimError

    cfg = EpisodeConfig()
    s_, lane, v = np.array([Simulation(road, cfg).ego_start(seed) for seed in range(300)]).T
    lap = road.lap_length
    for m in [sl.s for sl in road.stop_lines] + [ex.s_start for ex in road.exits]:
        assert np.abs((s_ - m + lap / 2) % lap - lap / 2).min() >= cfg.ego_start_clearance
    for cp in road.checkpoints:
        assert ((cp.s - s_) % lap).min() >= cfg.ego_start_checkpoint_clearance
    edges = Simulation(road, cfg)._edges
    assert all(edges.locate(float(s), lap) is not None for s in s_)
    assert set(lane.astype(int).tolist()) == {0, 1, 2}
    assert cfg.ego_start_speed_min <= v.min() and v.max() <= cfg.ego_start_speed_max
    assert len(np.unique(s_)) == 300 and (s_ < lap / 2).any() and (s_ > lap / 2).any()
    fixed = Simulation(road, EpisodeConfig(ego_start_random=False))
    assert {fixed.ego_start(seed) for seed in (0, 1, 99)} == {(10.0, 1, 10.0)}
    # clearances the loop cannot meet are scaled down (by halves) until a start fits; where none does,
    # the simulation is refused when it is made, before any episode
    wide = Simulation(road, EpisodeConfig(ego_start_clearance=600.0))
    assert wide.start_scale == 0.5
    s0 = wide.ego_start(0)[0]
    for m in [sl.s for sl in road.stop_lines] + [ex.s_start for ex in road.exits]:
        assert abs((s0 - m + lap / 2) % lap - lap / 2) >= 300.0
    with pytest.raises(IrlsimError, match="leaves no start for the ego"):
        Simulation(road, EpisodeConfig(ego_start_clearance=5000.0))


def test_laps_counted_from_a_start_late_in_the_lap(road):
    """A ghost ego at 25 m/s from a random start that crosses s = 0 (the lap seam): exactly one lap,
    every checkpoint and stop line passed once."""
    s = Simulation(road, EpisodeConfig(n_vehicles=0, laps=1, max_time=300.0))
    seed = next(k for k in range(200) if s.ego_start(k)[0] > road.lap_length - 700.0)
    with s:
        obs = s.reset(seed)
        while not s.done:
            n = s.cfg.horizon_steps + 1
            s.execute(frenet_trajectory(road, obs.ego, 0.1, np.full(n, 25.0), np.full(n, obs.ego.d)))
            obs = s.observe()
        st = s.stats
    assert st["end_reason"] == "laps" and st["sim/laps"] == 1
    assert road.lap_length <= st["sim/distance_m"] < road.lap_length + 25.0 * s.cfg.cycle
    assert st["sim/checkpoints_passed"] == 4 and st["sim/stop_lines_passed"] == 2
    assert obs.ego.s > road.lap_length  # unwrapped: it went over the seam


def test_vehicles_held_up_behind_a_standing_ego_count_as_stuck(sim, road):
    """The ego stops dead at its start (>= 150 m from any stop line): the background vehicles that come
    up behind it in its lane stand still, and after bg_stuck_time each counts once in sim/bg_stuck."""
    obs = sim.reset(4)
    lap = road.lap_length
    rel = (obs.vehicles.s - obs.ego.s + lap / 2) % lap - lap / 2
    behind = (rel < 0) & (road.lane_of_d(obs.vehicles.d) == obs.ego.lane)
    assert behind.any(), "seed 4 should have traffic behind the ego in its lane"
    for _ in range(600):
        sim.step()  # the ego stands where it is
    st = sim.stats
    assert 1 <= st["sim/bg_stuck"] <= behind.sum()
    assert st["sim/collisions"] == 0 and st["end_reason"] is None
