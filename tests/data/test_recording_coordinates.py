"""A recording in longitude and latitude (``sumo --fcd-output.geo``, a GPS track) or in a network's
projection before its netOffset (``--fcd-output.utm``) is read with ``demonstrator.coordinates``: SUMO
places geographic points through the network's projection. Real SUMO runs on a real netconvert network
built with a UTM projection; the same run written in the network's coordinates is the reference."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import sumolib

from irlsim.cli import main
from irlsim.data.demonstrator import DemonstratorConfig
from irlsim.data.recording import load_recording
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from tests.data.test_recording_street import _plain_net, _record

VEHICLES = "".join(
    f'<vehicle id="c{i}" type="car" depart="{3 * i}" departLane="{i % 2}" departSpeed="max">'
    '<route edges="ab"/></vehicle>'
    for i in range(3)
)


@pytest.fixture(scope="module")
def geo_road(tmp_path_factory) -> Path:
    """A two-lane road of 600 m near 11 E, 48 N, built by netconvert from nodes in longitude and
    latitude with a UTM projection (as an OpenStreetMap import has one), as a scenario folder, and the
    same SUMO run recorded three ways: the network's coordinates, .geo and .utm, at full precision."""
    tmp = tmp_path_factory.mktemp("geo")
    nodes = {"a": (11.0, 48.0), "b": (11.008, 48.0)}
    net = _plain_net(tmp, "geo", nodes, {"ab": 'numLanes="2" speed="20"'}, "--proj.utm")
    (tmp / "scenario.toml").write_text(
        f'name = "geo"\n[network]\nfile = "{net.name}"\n[route]\nedges = ["ab"]\n'
    )
    precise = ("--precision", "6", "--precision.geo", "9")
    for name, extra in (
        ("net", ()),
        ("geo", ("--fcd-output.geo", "true")),
        ("utm", ("--fcd-output.utm", "true")),
    ):
        shutil.move(_record(tmp, net, VEHICLES, "0.5", "40", *precise, *extra), tmp / f"{name}.xml")
    return tmp


def _read(road_dir: Path, name: str, coordinates: str = "network"):
    road = load_road(scenario=road_dir)
    return load_recording(
        road_dir / f"{name}.xml", road.net, 0.1, coordinates=coordinates, net_file=road.net_file
    )


def test_longitude_and_latitude_land_where_sumo_drove(geo_road):
    """The .geo run read with coordinates = 'geo', and the .utm run with 'utm', are the run recorded in
    the network's coordinates: the same vehicles, routes and headings, positions within a millimetre."""
    ref = _read(geo_road, "net")
    for name in ("geo", "utm"):
        rec = _read(geo_road, name, name)
        assert rec.ids == ref.ids == ("c0", "c1", "c2") and rec.edges == ref.edges
        assert np.abs(rec.x - ref.x).max() < 1e-3 and np.abs(rec.y - ref.y).max() < 1e-3, name
        assert np.abs(rec.heading - ref.heading).max() < 1e-6  # SUMO's angle is the network's either way
    raw = [float(v.x) for v in sumolib.xml.parse_fast(str(geo_road / "geo.xml"), "vehicle", ["x"])]
    assert 10.99 < min(raw) and max(raw) < 11.01  # the file really holds longitudes


def test_coordinates_that_cannot_be_read_are_one_line(geo_road):
    """Each before any work: geographic points read as metres (the fix named), metres read as
    geographic points, geographic points on a network without a projection, an unknown value."""
    with pytest.raises(IrlsimError) as e:
        _read(geo_road, "geo")
    assert "set demonstrator.coordinates = 'geo'" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(IrlsimError) as e:
        _read(geo_road, "utm")
    assert "set demonstrator.coordinates = 'utm'" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(IrlsimError, match=r"are no longitude .* drop demonstrator.coordinates"):
        _read(geo_road, "net", "geo")
    oval = load_road()
    assert not oval.net.hasGeoProj()
    with pytest.raises(IrlsimError, match="has no geographic projection"):
        load_recording(geo_road / "geo.xml", oval.net, 0.1, coordinates="geo", net_file=oval.net_file)
    with pytest.raises(IrlsimError, match="demonstrator.coordinates must be one of network, geo, utm"):
        DemonstratorConfig(kind="recording", file="x.xml", coordinates="wgs84").validate()
    with pytest.raises(IrlsimError, match="belong to kind = 'recording'"):
        DemonstratorConfig(coordinates="geo").validate()


def test_a_geographic_recording_is_collected_and_recorded_as_read(geo_road, tmp_path):
    """Collected from the .geo run: its cars are the egos of the run in the network's coordinates, and
    the manifest and the collection's line say how the file was read."""
    config = tmp_path / "collect.toml"
    base = "seed = 0\ntrain_episodes = 1\nvalidation_episodes = 0\ntest_episodes = 0\nmax_cycles = 10\n"
    config.write_text(
        base
        + '[planner]\nn_policies = 100\n[demonstrator]\nkind = "recording"\n'
        + f'file = "{geo_road / "geo.xml"}"\nmin_duration = 5.0\ncoordinates = "geo"\n'
    )
    out = tmp_path / "data"
    assert main(["collect", "--config", str(config), "--scenario", str(geo_road), "--out", str(out)]) == 0
    record = json.loads((out / "manifest.json").read_text())["demonstrator"]
    assert record["coordinates"] == "geo" and record["egos"] == ["c0", "c1", "c2"]
    assert (out / "train" / "episode_00000.cycles.parquet").is_file()
