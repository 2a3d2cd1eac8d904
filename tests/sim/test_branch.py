"""The look ahead of DAgger's SUMO labeller, with real SUMO (libsumo): a branch drives exactly what SUMO's
driver drives from the same state, the simulation comes back to where it was, the episode's books never
see the branch, and the same seed gives the same bytes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from irlsim.planner.config import PlannerConfig
from irlsim.planner.expert import ExpertDriver
from irlsim.road import load_road
from irlsim.sim.branch import BranchingSimulation
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.drivers import SumoDriver
from irlsim.sim.simulation import EGO
from irlsim.sim.vtype import vtype_attributes

CFG = EpisodeConfig(n_vehicles=4, laps=1, max_time=60.0)
IDM = vtype_attributes({"carFollowModel": "IDM", "tau": 0.6, "accel": 3.0}, CFG.ego_target_speed)
CYCLES, AHEAD = 12, 30


@pytest.fixture(scope="module")
def road():
    return load_road()


def _drive(road, cycles: int, ahead: int = 0):
    """A simulation after the expert drove ``cycles`` cycles (a branch of ``ahead`` steps every cycle)."""
    sim = BranchingSimulation(road, CFG, demo_vtype=IDM)
    expert = ExpertDriver(road, PlannerConfig(n_policies=60))
    obs = sim.reset(3)
    seen = []
    for _ in range(cycles):
        if ahead:
            seen.append(sim.branch(ahead))
        sim.execute(expert.plan(obs))
        obs = sim.observe()
    return sim, obs, seen


def test_a_branch_is_what_sumos_driver_drives_from_that_state(road):
    sim, obs, _ = _drive(road, CYCLES)
    before = sim.ego
    api = sim._api
    xy, t = api.vehicle.getPosition(EGO), api.simulation.getTime()
    branch = sim.branch(AHEAD)
    # back where it was: the time, the ego's place (SUMO recomputes it from the lane: within a nanometre)
    assert api.simulation.getTime() == t and sim.ego is before
    np.testing.assert_allclose(api.vehicle.getPosition(EGO), xy, atol=1e-9)
    assert len(branch) == AHEAD and branch[0].t == pytest.approx(t + CFG.step)
    sim.close()
    # the same state, SUMO's driver at the wheel for real: the branch's states to the last bit
    sim, obs, _ = _drive(road, CYCLES)
    assert sim.ego == before
    sim.execute(SumoDriver(road, CFG).plan(obs), n_steps=AHEAD)
    assert sim.odometry[-AHEAD:] == branch
    sim.close()


def test_the_books_never_see_a_branch_and_the_same_seed_gives_the_same_bytes(road):
    sim, _, seen = _drive(road, CYCLES, AHEAD)
    books = dict(sim.stats), list(sim.odometry)
    sim.close()
    # a branch moved the ego along SUMO's road (the IDM driver keeps going), the episode did not
    assert all(len(b) == AHEAD and b[-1].s > b[0].s for b in seen)
    assert len(books[1]) == CYCLES * CFG.steps_per_cycle + 1
    again, _, seen2 = _drive(road, CYCLES, AHEAD)
    assert again.odometry == books[1] and seen2 == seen
    timing = ("sim/steps_per_s", "sim/sumo_steps_per_s")
    assert {k: v for k, v in again.stats.items() if k not in timing} == {
        k: v for k, v in books[0].items() if k not in timing
    }
    again.close()
    # without branches the ego drives the same policies' states (the traffic's random streams differ)
    plain, _, _ = _drive(road, 1)
    first = [dataclasses.replace(s, t=0.0) for s in plain.odometry[:2]]
    assert first == [dataclasses.replace(s, t=0.0) for s in books[1][:2]]
    plain.close()


def test_a_branch_needs_a_placed_ego(road):
    sim, obs, _ = _drive(road, 1)
    sim.execute(SumoDriver(road, CFG).plan(obs), n_steps=2)
    with pytest.raises(RuntimeError, match="SUMO drives the ego already"):
        sim.branch(3)
    sim.close()


def test_sumos_driver_keeps_a_placed_egos_offset_from_its_lane_and_lane_offset_reads_it(road):
    # SUMO's lane-based driver has no lateral position of its own: off its lane's centre (the expert's
    # lane change under way), the ego stays that far off it through the look ahead and across a change
    sim = BranchingSimulation(road, CFG, demo_vtype=IDM)
    expert = ExpertDriver(road, PlannerConfig(n_policies=500))
    obs, w = sim.reset(2_000_000_001), road.lane_width
    for _ in range(200):
        if abs(obs.ego.d / w - round(obs.ego.d / w)) > 0.2:
            break
        sim.execute(expert.plan(obs))
        obs = sim.observe()
    off = sim.lane_offset()
    assert 0.2 * w < abs(off) < 0.5 * w and abs(obs.ego.d / w - round(obs.ego.d / w)) > 0.2
    centres = (np.array([s.d for s in sim.branch(AHEAD)]) - off) / w  # at SUMO's lanes' centres
    np.testing.assert_allclose(centres, np.round(centres), atol=0.02)
    assert sim.lane_offset() == off  # the branch came back to the placed ego
    read = np.array([s.d for s in sim.look_ahead(AHEAD)]) / w  # what a labeller projects: at the centres
    np.testing.assert_allclose(read, np.round(read), atol=0.02)
    assert sim.look_ahead_offset() == off
    sim.close()


def test_a_look_ahead_completes_a_lane_change_that_takes_time_from_where_the_ego_is(road):
    # with --lanechange.duration a SUMO driver straddling a line is in a maneuver it completes; a look ahead
    # from a placed ego straddling one (the expert's lane change under way) completes it, read as driven:
    # from the ego's place to the next lane's centre, never past it, with no offset taken off
    sim = BranchingSimulation(road, CFG, demo_vtype=IDM, lane_change_duration=3.0)
    expert = ExpertDriver(road, PlannerConfig(n_policies=500))
    obs, w = sim.reset(2_000_000_001), road.lane_width
    api = sim._api
    for _ in range(300):
        off = sim.lane_offset()
        if abs(off) > 0.5 * (w - api.vehicle.getWidth(EGO)) and off * obs.ego.d_dot > 0:
            break
        sim.execute(expert.plan(obs))
        obs = sim.observe()
    else:
        pytest.fail("the expert changed no lane")
    mode, side = api.vehicle.getLaneChangeMode(EGO), np.sign(off)
    target = road.lane_center(road.lane_of_d(np.array(obs.ego.d - off)) + int(side))
    d = np.array([s.d for s in sim.look_ahead(50)])
    assert sim.look_ahead_offset() == 0.0
    assert abs(d[0] - obs.ego.d) < 0.15 and d[-1] == pytest.approx(target)
    assert np.all(side * np.diff(d) >= -1e-9) and np.all(side * (d - target) <= 1e-9)  # on, never past
    assert api.vehicle.getLaneChangeMode(EGO) == mode and sim.lane_offset() == off  # back where it was
    sim.close()


@pytest.mark.parametrize("model", ["LC2013", "SL2015"])
def test_sumos_driver_at_the_wheel_has_the_demonstrators_lane_change_model_and_attributes(road, model):
    # SUMO builds a vehicle's lane-change model at insertion: an ego inserted with irlsim's ego type kept
    # LC2013 and its default lcSpeedGain 1 after setType to the demonstrator's (measured), so the ego is
    # inserted with the demonstrator's placed type
    attrs = vtype_attributes({**IDM, "laneChangeModel": model, "lcSpeedGain": 7.0, "lcKeepRight": 0.1}, 20.0)
    sim = BranchingSimulation(road, CFG, demo_vtype=attrs)
    obs = sim.reset(3)
    sim.execute(SumoDriver(road, CFG).plan(obs), n_steps=2)
    get = sim._api.vehicle.getParameter
    assert [float(get(EGO, f"laneChangeModel.{k}")) for k in ("lcSpeedGain", "lcKeepRight")] == [7.0, 0.1]
    assert sim._api.vehicle.getTypeID(EGO) == "irlsim_demo" and sim._api.vehicle.getTau(EGO) == 0.6
    if model == "SL2015":  # a parameter only the sublane model has
        assert float(get(EGO, "laneChangeModel.lcSublane")) == 1.0
    else:
        with pytest.raises(Exception, match="does not support"):
            get(EGO, "laneChangeModel.lcSublane")
    sim.close()
