"""Errors name the file at fault: a broken vehicle-type file (or a scenario's route file) is named as
such before SUMO starts, instead of being blamed on the network with advice ('irlsim net --force') that
cannot help."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import SUMO_NET_DIR, VTYPES_PATH
from irlsim.road.scenario import load_scenario
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.simulation import Simulation
from pipelines.commands import main

OVAL_DIR = SUMO_NET_DIR / "oval"

OVAL_NET = OVAL_DIR / "oval.net.xml"


def test_a_broken_vtypes_file_is_named_not_blamed_on_the_net(road, tmp_path):
    broken = tmp_path / "vtypes.add.xml"
    broken.write_text(VTYPES_PATH.read_text().replace("</additional>", ""))  # truncated: not XML
    sim = Simulation(road, EpisodeConfig(n_vehicles=0), vtypes_file=broken)
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
    sim = Simulation(road, EpisodeConfig(n_vehicles=0), vtypes_file=lacking)
    with pytest.raises(IrlsimError) as e:
        sim.reset(1)
    assert str(e.value) == (
        f"vehicle types {lacking} lacks vType '{vtype}', which irlsim inserts (it needs ego, bg): add it or "
        "restore it ('git checkout sumo_net/vtypes.add.xml' or reinstall irlsim)"
    )
    assert sim._api is None  # SUMO never started
    sim.close()


def _user_scenario(folder: Path, network: str, traffic: str = "") -> Path:
    """The oval's route and checkpoints as a user's scenario file, on the network ``network`` names."""
    folder.mkdir(exist_ok=True)
    text = (OVAL_DIR / "scenario.toml").read_text().replace('netconvert = "netconvert.cfg"', network)
    path = folder / "scenario.toml"
    path.write_text(text + traffic)
    return path


def _one_line(e: pytest.ExceptionInfo[IrlsimError]) -> str:
    msg = str(e.value)
    assert "\n" not in msg and "net --force" not in msg
    return msg


def test_a_vtype_sumo_refuses_is_named_with_sumos_message(road, tmp_path, capfd):
    """Well-formed XML with a value SUMO refuses (libsumo says only 'Process Error' and writes its reason
    to stderr): the vehicle-types file is named with SUMO's reason, SUMO's own lines are not printed."""
    bad = tmp_path / "vtypes.add.xml"
    text = VTYPES_PATH.read_text()
    start = text.index('<vType id="ego"')
    bad.write_text(text[:start] + text[start:].replace('accel="3.0"', 'accel="fast"', 1))
    sim = Simulation(road, EpisodeConfig(n_vehicles=0), vtypes_file=bad)
    with pytest.raises(IrlsimError) as e:
        sim.reset(1)
    assert _one_line(e) == (
        f"vehicle types {bad}: SUMO refused it (Invalid Car-Following-Model Attribute accel. Cannot be "
        "parsed to float): fix it or restore it ('git checkout sumo_net/vtypes.add.xml' or reinstall irlsim)"
    )
    assert "Error:" not in capfd.readouterr().err
    sim.close()


def test_a_route_file_sumo_refuses_is_named_before_any_episode(tmp_path, capsys):
    """A scenario's [traffic] route file with an edge the network lacks: collect and drive name it in one
    line before any work (exit 2, nothing written), not an episode's error retried and marked failed."""
    (tmp_path / "road").mkdir()
    routes = tmp_path / "road" / "demand.rou.xml"
    routes.write_text(
        '<routes>\n  <route id="r0" edges="A_S1"/>\n  <vehicle id="v0" route="r0" depart="0"/>\n'
        '  <route id="r1" edges="no_such_edge"/>\n  <vehicle id="v1" route="r1" depart="900"/>\n</routes>\n'
    )
    scn = _user_scenario(
        tmp_path / "road", f'file = "{OVAL_NET}"', '\n[traffic]\nroutes = ["demand.rou.xml"]\n'
    )
    expected = (
        f"irlsim: error: route file {routes}: SUMO refused it (The edge 'no_such_edge' within the route 'r1' "
        f"is not known.): fix it or the [traffic] routes of {scn}"
    )
    tiny = ["--config", "configs/collect/tiny.toml", "--scenario", str(scn)]
    for command in (["collect"], ["drive", "--model", "expert"]):
        out = tmp_path / command[0]
        assert main([*command, *tiny, "--out", str(out)]) == 2
        assert capsys.readouterr().err.strip() == expected
        assert not out.exists()


def test_a_broken_network_of_another_scenario_gets_advice_that_fits(road, tmp_path):
    """A network SUMO refuses (sumolib reads it) is named with SUMO's reason and the fix that fits how
    it was made: a scenario's own network file is the user's to fix (never 'irlsim net --force', which
    rebuilds only the oval); the oval's built network is rebuilt with 'irlsim net --force'."""
    text = OVAL_NET.read_text()
    start = text.index("<junction ")
    end = text.index(">", start)
    head = re.sub(r'type="[a-z_]+"', 'type="no_such_type"', text[start:end], count=1)
    (tmp_path / "road").mkdir()
    bad = tmp_path / "road" / "bad.net.xml"
    bad.write_text(text[:start] + head + text[end:])
    junction = re.search(r'id="([^"]+)"', head).group(1)  # type: ignore[union-attr]
    scn = _user_scenario(tmp_path / "road", 'file = "bad.net.xml"')
    sim = Simulation(load_road(scenario=scn), EpisodeConfig(n_vehicles=0))
    with pytest.raises(IrlsimError) as e:
        sim.reset(1)
    assert _one_line(e) == (
        f"network {bad}: SUMO refused it (Attribute 'type' in definition of junction '{junction}' is not a "
        f"valid node type.): fix or regenerate it (the [network] of {scn})"
    )
    sim.close()
    # malformed XML (sumolib fails while the road is built): the same fitting advice
    bad.write_text(text[: len(text) // 2])
    with pytest.raises(IrlsimError) as e:
        load_road(scenario=scn)
    assert str(e.value).endswith(f"fix or regenerate it (the [network] of {scn})")
    from irlsim.road.scenario import network_advice  # the fix that fits how the network was made

    assert network_advice(OVAL_NET, OVAL_DIR / "scenario.toml") == "rebuild it with 'irlsim net --force'"
    grid = SUMO_NET_DIR / "grid" / "scenario.toml"  # netgenerate: irlsim made it, deleting it remakes it
    advice = network_advice(load_scenario("grid").net_file, grid)
    assert advice.startswith(f"delete it: it is made again from {grid.parent / 'grid.netgcfg'} ")


def test_a_scenarios_additional_file_is_named_when_missing_broken_or_refused(tmp_path, capsys):
    """A scenario's [network] additional file (signal programs): missing, not XML, or a program SUMO
    refuses (a traffic light the network lacks) is one line naming it, before any work (exit 2, nothing
    written)."""
    (tmp_path / "road").mkdir()
    lights = tmp_path / "road" / "lights.add.xml"
    scn = _user_scenario(tmp_path / "road", f'file = "{OVAL_NET}"\nadditional = ["lights.add.xml"]', "")
    tiny = ["collect", "--config", "configs/collect/tiny.toml", "--scenario", str(scn)]
    refused = (
        '<additional><tlLogic id="no_such_light" type="static" programID="x" offset="0">'
        '<phase duration="10" state="G"/></tlLogic></additional>'
    )
    for text, words in (
        (None, f"scenario {scn}: file {lights} not found: fix [network] additional"),
        ("<additional>", f"additional file {lights} is not valid XML"),
        (refused, f"additional file {lights}: SUMO refused it ("),
    ):
        if text is not None:
            lights.write_text(text)
        out = tmp_path / "out"
        assert main([*tiny, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert words in err and "\n" not in err, err
        assert not out.exists()
