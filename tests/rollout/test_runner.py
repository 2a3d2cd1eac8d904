"""The one episode runner on real SUMO: driven and stepwise modes agree, facts add up to the episode's
figures, observers are called in order, the end flags and misuse are reported."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from irlsim.planner.config import PlannerConfig
from irlsim.planner.expert import THETA_EXPERT, ThetaDriver
from irlsim.planner.planner import Planner
from irlsim.rollout import FACT_COUNTS, Cycle, EpisodeResult, EpisodeRunner, ObserverBase
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.drivers import SimpleDriver
from irlsim.sim.simulation import TIMING_KEYS, Simulation

SCENARIO = EpisodeConfig(n_vehicles=4, laps=1, max_time=600.0)
PLANNER = PlannerConfig(n_policies=120)


class Log(ObserverBase):
    def __init__(self) -> None:
        self.calls: list[str] = []
        self.cycles: list[Cycle] = []
        self.result: EpisodeResult | None = None

    def on_reset(self, sim, obs) -> None:
        self.calls.append("reset")

    def on_cycle(self, sim, cycle) -> None:
        self.calls.append("cycle")
        self.cycles.append(cycle)

    def on_end(self, sim, result) -> None:
        self.calls.append("end")
        self.result = result


def _figures(stats: dict) -> dict:
    return {k: v for k, v in stats.items() if k not in TIMING_KEYS}


@pytest.fixture(scope="module")
def scenario_sim(road):
    with Simulation(road, SCENARIO) as s:
        yield s


def test_driven_run_calls_observers_and_facts_add_up(road, scenario_sim):
    log = Log()
    res = EpisodeRunner(scenario_sim, observers=[log], max_cycles=60).run(SimpleDriver(road, SCENARIO), 3)
    assert log.calls == ["reset"] + ["cycle"] * res.cycles + ["end"] and log.result is res
    assert res.cycles == 60 and res.end_reason == "max_cycles" and res.truncated and not res.terminated
    assert [c.index for c in log.cycles] == list(range(60))
    st = res.stats
    for k in FACT_COUNTS:
        assert sum(c.facts[k] for c in log.cycles) == st[f"sim/{k}"], k
    assert sum(c.driven for c in log.cycles) == st["sim/steps"] == 60 * SCENARIO.steps_per_cycle
    assert sum(c.facts["progress_m"] for c in log.cycles) == pytest.approx(st["sim/distance_m"], abs=1e-3)
    # every cycle starts where the last one ended (the time is SUMO's clock)
    for a, b in zip(log.cycles, log.cycles[1:], strict=False):
        end = a.trajectory.state(a.driven)
        assert b.obs.ego == dataclasses.replace(end, t=b.obs.ego.t) and b.obs.ego.t == pytest.approx(end.t)


def test_same_seed_same_episode(road, scenario_sim):
    runs = [
        EpisodeRunner(scenario_sim, max_cycles=40).run(SimpleDriver(road, SCENARIO), 11) for _ in range(2)
    ]
    assert _figures(runs[0].stats) == _figures(runs[1].stats)


def test_stepwise_equals_driven_with_the_same_choices(road, scenario_sim):
    """Stepping with argmax V under the expert's theta drives the episode a ThetaDriver drives."""
    driven = EpisodeRunner(scenario_sim, max_cycles=30).run(
        ThetaDriver(Planner(road, PLANNER), lambda ps, obs: THETA_EXPERT), 5
    )
    odo_driven = scenario_sim.odometry_arrays()

    runner = EpisodeRunner(scenario_sim, planner=Planner(road, PLANNER), max_cycles=30)
    obs, ps = runner.reset(5)
    assert ps is not None and ps.n_policies > 0 and obs.ego.t == pytest.approx(odo_driven["t"][0])
    steps = 0
    while True:
        r = runner.step(int(np.argmax(ps.value(THETA_EXPERT))))
        steps += 1
        assert r.cycle.chosen >= 0 and r.facts["steps"] == r.cycle.driven
        if r.terminated or r.truncated:
            break
        assert r.policy_set is not None
        ps = r.policy_set
    assert r.policy_set is None and r.truncated and steps == driven.cycles == 30
    assert _figures(runner.result.stats) == _figures(driven.stats)
    for k, v in scenario_sim.odometry_arrays().items():
        np.testing.assert_array_equal(v, odo_driven[k], err_msg=k)
    with pytest.raises(RuntimeError, match="reset"):
        runner.step(0)


def test_stepwise_trajectory_and_misuse(road, scenario_sim):
    runner = EpisodeRunner(scenario_sim)
    obs, ps = runner.reset(7)
    assert ps is None  # no planner: the caller brings trajectories
    with pytest.raises(RuntimeError, match="planner"):
        runner.step(0)
    r = runner.step(SimpleDriver(road, SCENARIO).plan(obs))
    assert r.cycle.chosen == -1 and r.cycle.policy_set is None and not (r.terminated or r.truncated)
    assert r.obs.ego.t == pytest.approx(obs.ego.t + SCENARIO.cycle)
    planned = EpisodeRunner(scenario_sim, planner=Planner(road, PLANNER))
    _, ps = planned.reset(7)
    assert ps is not None
    with pytest.raises(IndexError):
        planned.step(ps.n_policies)
    with pytest.raises(ValueError):
        EpisodeRunner(scenario_sim, max_cycles=-1)


def test_collision_terminates(road, scenario_sim):
    """Driving blind at full speed into traffic ends in a collision (terminated), reported in the facts."""

    class Blind(SimpleDriver):
        def acceleration(self, obs):  # ignores the leader and the stop lines
            return self.a_max

    runner = EpisodeRunner(scenario_sim, max_cycles=1500)
    for seed in range(20):
        res = runner.run(Blind(road, SCENARIO), seed)
        if res.end_reason == "collision":
            break
    assert res.end_reason == "collision" and res.terminated and not res.truncated
