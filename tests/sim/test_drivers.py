"""SimpleDriver on hand-made observations (no SUMO): continuity, following, stop lines, shapes."""

from __future__ import annotations

import numpy as np
import pytest

from irlsim.rollout import DRIVERS, make_driver
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.drivers import SimpleDriver
from irlsim.sim.types import EgoState, Observation, VehicleStates

CFG = EpisodeConfig()


def _obs(road, v=15.0, s=20.0, d=0.0, vehicles=None, stop_s=np.inf) -> Observation:
    x, y = road.to_xy(np.array(s), np.array(d))
    ego = EgoState(3.0, float(x), float(y), float(road.heading(np.array(s))), v, 0.0, s, d, 0.0, 0.0, 1)
    return Observation(ego, vehicles or VehicleStates.empty(), 0, 105.0, stop_s, road.lap_length)


def _one(s, d, v):
    a = np.array
    return VehicleStates(("bg0",), a([0.0]), a([0.0]), a([0.0]), a([v]), a([s]), a([d]), a([4.5]), a([1.8]))


def test_free_road_accelerates_and_keeps_lane(road):
    drv = SimpleDriver(road, CFG)
    obs = _obs(road)
    tr = drv.plan(obs)
    assert len(tr.x) == CFG.horizon_steps + 1 and tr.dt == CFG.step and tr.t0 == obs.ego.t
    assert tr.state(0) == obs.ego  # continuity: index 0 is the ego's state
    assert np.all(np.diff(tr.v) >= 0) and tr.v.max() <= CFG.ego_target_speed + 1e-9
    np.testing.assert_allclose(tr.d, 0.0, atol=1e-9)
    # positions follow the speeds: step lengths match v dt on the straight
    steps = np.hypot(np.diff(tr.x), np.diff(tr.y))
    np.testing.assert_allclose(steps, 0.5 * (tr.v[1:] + tr.v[:-1]) * CFG.step, rtol=1e-3)


def test_follows_a_slower_leader(road):
    drv = SimpleDriver(road, CFG)
    assert drv.acceleration(_obs(road, v=15.0, vehicles=_one(45.0, 0.0, 5.0))) < -1.0
    # a vehicle two lanes away is ignored
    assert drv.acceleration(_obs(road, v=15.0, vehicles=_one(45.0, 6.4, 5.0))) > 0.0


def test_brakes_to_stop_exactly_before_the_line(road):
    drv = SimpleDriver(road, CFG)
    obs = _obs(road, v=10.0, s=181.0, stop_s=201.0)  # 20 m to the line, stops 1 m before it
    assert drv.acceleration(obs) == pytest.approx(-100.0 / (2 * 19.0))
    tr = drv.plan(obs)
    assert tr.v[-1] == 0.0 and tr.s[-1] <= 201.0 - 0.9
    stand = _obs(road, v=0.0, s=200.0, stop_s=201.0)
    assert drv.plan(stand).v.max() == 0.0


def test_registry(road):
    assert "simple" in DRIVERS
    assert isinstance(make_driver("simple", road, CFG), SimpleDriver)
    from irlsim.errors import IrlsimError

    with pytest.raises(IrlsimError, match="unknown driver"):
        make_driver("nope", road, CFG)
