"""Errors name the file at fault: a broken vehicle-type file (or a scenario's route file) is named as
such before SUMO starts, instead of being blamed on the network with advice ('irlsim net --force') that
cannot help."""

from __future__ import annotations

import pytest

from irlsim.errors import IrlsimError
from irlsim.road.network import VTYPES_PATH
from irlsim.sim.config import ScenarioConfig
from irlsim.sim.simulation import Simulation


def test_a_broken_vtypes_file_is_named_not_blamed_on_the_net(road, tmp_path):
    broken = tmp_path / "vtypes.add.xml"
    broken.write_text(VTYPES_PATH.read_text().replace("</additional>", ""))  # truncated: not XML
    sim = Simulation(road, ScenarioConfig(n_vehicles=0), vtypes_file=broken)
    with pytest.raises(IrlsimError) as e:
        sim.reset(1)
    msg = str(e.value)
    assert "\n" not in msg and str(broken) in msg and "vehicle types" in msg
    assert "net --force" not in msg and str(road.net_file) not in msg
    sim.close()
