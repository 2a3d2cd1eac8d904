"""A traffic light's red as a replayed recording's ego sees it (real SUMO): the grace of a recording whose
rows are farther apart than the simulation step."""

from __future__ import annotations

import numpy as np
import pytest

from irlsim.rollout.drivers import make_driver
from irlsim.rollout.runner import EpisodeRunner, StepListener
from irlsim.sim.signals import SignalWatch
from irlsim.sim.simulation import EGO, Simulation
from tests.sim.test_yielding import _crossing


class _Both(StepListener):
    """Every step: the light's red for the ego without a grace and with 0.9 s, and SUMO's time of its next
    switch and the state it switches to on the ego's link."""

    def __init__(self, road):
        self.plain, self.graced = SignalWatch(road), SignalWatch(road, grace=0.9)
        self.rows: list[tuple[float, bool, bool, float]] = []

    def on_step(self, sim):
        api = sim._api
        self.plain.read(api, EGO)
        self.graced.read(api, EGO)
        t = api.simulation.getTime()
        switch = api.trafficlight.getNextSwitch("j")
        self.rows.append((t, bool(self.plain.red[0]), bool(self.graced.red[0]), switch))


def test_a_recorded_egos_red_ends_a_row_before_the_light_turns_green(tmp_path):
    road, cfg = _crossing(tmp_path, end=0.0)  # no oncoming car: the ego waits for its green, then turns
    both = _Both(road)
    with Simulation(road, cfg) as sim:
        st = EpisodeRunner(sim, observers=[both]).run(make_driver("expert", road, cfg), 0).stats
        od = sim.odometry_arrays()
    t, plain, graced, switch = (np.array(c) for c in zip(*both.rows, strict=True))
    green = np.flatnonzero(plain[:-1] & ~plain[1:])  # the steps after which the ego's link turns from red
    assert len(green) == 1  # it waited at one red, then had its green
    # the expert stood at the red and passed the light on its green (the fast suite's check of the expert
    # at a red light; the corridor's acceptance run, three lights, is in make test-slow)
    assert st["sim/signals_passed"] == 1 and st["sim/red_crossings"] == 0 and st["sim/collisions"] == 0
    assert ((od["v"] < 0.1) & (od["t"] <= t[green[0]])).sum() * 0.1 >= 5.0
    # with the grace, red all the same but for the readings within 0.9 s of SUMO's switch to the green
    # (44.1-45.0 s; the green is read from 45.1 s): not before the switch from red to the others' yellow
    # (the ego's link red again), nor ever where it was not red
    late = np.flatnonzero(plain & ~graced)
    assert late.tolist() == list(range(green[0] - 9, green[0] + 1))
    assert switch[late] == pytest.approx(t[green[0]])
    assert t[late] == pytest.approx(t[green[0]] - np.arange(0.9, -0.05, -0.1))
    assert not (graced & ~plain).any() and plain[: green[0] - 100].any()
