"""The expert on every shipped scenario against SUMO's own driver model on the same seeds (real SUMO):
a short version (one seed each: the safety bounds) in the fast suite for the ramp and in the slow one
for the others, the full bar on 10 seeds in the
slow one (``make test-slow``), where the mean speed must be within 15 % of SUMO's driver's."""

from __future__ import annotations

import pytest

from irlsim.road.scenario import shipped_scenarios
from irlsim.rollout.acceptance import MISSION_MIN, check_scenario
from irlsim.sim.config import EpisodeConfig

OTHER_ROADS = [s for s in shipped_scenarios() if s != "oval"]


def test_every_shipped_scenario_is_covered():
    assert {"oval", "motorway", "ramp", "corridor", "grid"} <= set(shipped_scenarios())


#: the fast suite drives the ramp (lanes added and dropped, an off-ramp trap); the other roads' short runs
#: are acceptance runs of make test-slow (the suite's time budget). The expert at a red light keeps a fast
#: test of its own (tests/sim/test_signals.py: it stands at the red, passes on its green, no red crossing),
#: and at a light's minor green (tests/sim/test_yielding.py), for the corridor's three lights
FAST_ROADS = ("ramp",)


@pytest.mark.parametrize(
    "scenario", [s if s in FAST_ROADS else pytest.param(s, marks=pytest.mark.slow) for s in OTHER_ROADS]
)
def test_expert_drives_each_scenario_safely(scenario):
    acc = check_scenario(scenario, (7,), EpisodeConfig(max_time=120.0))
    e = acc.expert
    assert e["collisions"] == 0 and e["exits"] == 0 and e["red_crossings"] == 0
    assert e["stops_compliant"] == e["stops_passed"]
    assert e["checkpoints_in_lane"] >= MISSION_MIN * e["checkpoints_passed"]
    assert e["mean_speed_kmh"] > 10.0 and acc.sumo["mean_speed_kmh"] > 10.0  # both drove


@pytest.mark.slow
@pytest.mark.parametrize("scenario", shipped_scenarios())
def test_expert_meets_the_bar_on_ten_seeds(scenario):
    acc = check_scenario(scenario, tuple(range(1000, 1010)))
    assert acc.failures == [], acc.row()
