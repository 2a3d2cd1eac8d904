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


@pytest.mark.parametrize("vtype", ["ego", "bg"])
def test_a_vtypes_file_that_lacks_a_type_irlsim_inserts_is_one_line(road, tmp_path, vtype):
    """A vehicle-types file without the ego's or the background's type is named, with the type, before
    SUMO starts (SUMO would refuse the insertion mid-episode)."""
    text = VTYPES_PATH.read_text()
    start = text.index(f'<vType id="{vtype}"')
    lacking = tmp_path / "vtypes.add.xml"
    lacking.write_text(text[:start] + text[text.index("/>", start) + 2 :])
    sim = Simulation(road, ScenarioConfig(n_vehicles=0), vtypes_file=lacking)
    with pytest.raises(IrlsimError) as e:
        sim.reset(1)
    assert str(e.value) == (
        f"vehicle types {lacking} lacks vType '{vtype}', which irlsim inserts (it needs ego, bg): add it or "
        "restore it ('git checkout sumo_net/vtypes.add.xml' or reinstall irlsim)"
    )
    assert sim._api is None  # SUMO never started
    sim.close()
