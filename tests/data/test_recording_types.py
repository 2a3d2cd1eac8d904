"""A recording's vehicle types, with real SUMO: SUMO's FCD names each vehicle's type and carries no size
or class. With ``demonstrator.vehicle_types`` the files that define the types are loaded by SUMO, and
each recorded vehicle gets its type's length, width and class as SUMO makes them (an attribute the file
leaves out at SUMO's default for the class); only vehicles of a car's class are egos, the others replay at
their size. What cannot be read so is one line before any work."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from irlsim.cli import main
from irlsim.data.recorded import egos, open_recording
from irlsim.data.recording_as import ReadAs
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import sumo_binary
from irlsim.sim.vehicle_types import vehicle_types
from tests.data.conftest import record_fcd
from tests.data.test_recording import COLLECT

#: the recording's types: a car with its size given, a lorry and a bicycle at SUMO's defaults
TYPES = """<additional>
    <vType id="car" length="4.2" width="1.7" sigma="0" maxSpeed="12.5" lcStrategic="0" lcSpeedGain="0"
           lcKeepRight="0"/>
    <vType id="lorry" vClass="truck" sigma="0" maxSpeed="12.5" lcStrategic="0" lcSpeedGain="0"
           lcKeepRight="0"/>
    <vType id="bike" vClass="bicycle" sigma="0" lcStrategic="0" lcSpeedGain="0" lcKeepRight="0"/>
</additional>
"""
#: each recorded vehicle's type
KINDS = {"veh0": "car", "veh1": "lorry", "veh2": "car", "veh3": "bike", "veh4": "car"}


@pytest.fixture(scope="module")
def typed(tmp_path_factory) -> tuple[Path, Path]:
    """(the types file, SUMO's FCD of five vehicles of those types on the oval)."""
    tmp = tmp_path_factory.mktemp("types")
    road = load_road()
    types = tmp / "types.add.xml"
    types.write_text(TYPES)
    cars = "".join(
        f'<vehicle id="{vid}" type="{kind}" route="loop" depart="{2 * i}" departLane="{i % 3}" '
        f'departPos="{40 * i}" departSpeed="max"/>'
        for i, (vid, kind) in enumerate(KINDS.items())
    )
    routes = tmp / "cars.rou.xml"
    routes.write_text(f'<routes><route id="loop" edges="{" ".join(road.edges * 2)}"/>{cars}</routes>')
    return types, record_fcd(routes, tmp / "fcd.xml", "-a", str(types))


def test_each_vehicle_takes_its_types_size_and_class_as_sumo_makes_them(typed):
    types_file, fcd = typed
    road = load_road()
    sumo_types = vehicle_types(road.net_file, (str(types_file),))
    assert (sumo_types["car"].length, sumo_types["car"].width) == (4.2, 1.7)  # as the file gives them
    lorry, bike = sumo_types["lorry"], sumo_types["bike"]
    assert (lorry.vclass, bike.vclass) == ("truck", "bicycle")
    assert lorry.length > 4.2 > bike.length and lorry.width > 1.7 > bike.width  # SUMO's class defaults
    assert "DEFAULT_VEHTYPE" in sumo_types  # SUMO's own types too
    rec = open_recording(fcd, road, 0.1, ReadAs(vehicle_types=(str(types_file),)))
    for k, vid in enumerate(rec.ids):
        want = sumo_types[KINDS[vid]]
        got = (rec.size["length"][k], rec.size["width"][k], rec.vclass[k])
        assert got == (want.length, want.width, want.vclass)
    plain = open_recording(fcd, road, 0.1)
    assert plain.size == {} and plain.vclass == ()  # without the option as before
    assert np.array_equal(plain.x, rec.x) and plain.edges == rec.edges
    refused: dict[str, int] = {}
    assert egos(rec, road, (), 20.0, refused) == ["veh0", "veh2", "veh4"]
    assert refused == {"of another class than a car": 2}
    assert egos(plain, road, (), 20.0) == list(KINDS)
    with pytest.raises(IrlsimError, match=r"veh1 cannot be an ego: it is of class truck \(its type's\)"):
        egos(rec, road, ("veh1",), 20.0)


def test_a_route_file_with_open_flows_gives_its_types(tmp_path):
    # The route file a recording's SUMO run loaded is where its types are (SUMO's game scenarios define
    # them beside flows that begin after 0 s and have no end): SUMO loads it whole, flows and all, and
    # with a simulation ending at 0 s such a flow "ends before its begin time".
    road = load_road()
    routes = tmp_path / "traffic.rou.xml"
    routes.write_text(
        f'<routes><vType id="van" length="5.5" width="2.0"/><route id="loop" edges="{road.edges[0]}"/>'
        '<flow id="f" type="van" route="loop" begin="3.00" period="exp(0.15)"/></routes>'
    )
    van = vehicle_types(road.net_file, (str(routes),))["van"]
    assert (van.length, van.width, van.vclass) == (5.5, 2.0, "passenger")


def test_what_cannot_be_typed_is_one_line(typed, tmp_path):
    types_file, fcd = typed
    road = load_road()
    untyped = tmp_path / "untyped.xml"  # SUMO's FCD without the type attribute
    cmd = [sumo_binary("sumo"), "-n", str(road.net_file), "-r", str(fcd.parent / "cars.rou.xml")]
    cmd += ["-a", str(types_file), "--end", "30", "--fcd-output", str(untyped), "--no-step-log", "true"]
    subprocess.run([*cmd, "--fcd-output.attributes", "x,y,angle,speed,lane"], check=True, capture_output=True)
    cars_only = tmp_path / "cars.add.xml"
    lines = TYPES.split("\n")
    cars_only.write_text("\n".join(lines[:3]) + "\n</additional>\n")  # the car's type alone
    broken = tmp_path / "broken.add.xml"
    broken.write_text('<additional><vType id="car" length="long"/></additional>')
    cases = {
        "names no vehicle types": (untyped, types_file),
        "type 'lorry' is not defined in demonstrator.vehicle_types (it defines car)": (fcd, cars_only),
        "not found": (fcd, tmp_path / "missing.add.xml"),
        "SUMO refuses demonstrator.vehicle_types": (fcd, broken),
    }
    for needle, (recording, types) in cases.items():
        with pytest.raises(IrlsimError) as e:
            open_recording(recording, road, 0.1, ReadAs(vehicle_types=(str(types),)))
        assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_a_collection_records_the_types_files_by_content(typed, tmp_path, capsys):
    types_file, fcd = typed
    cfg = tmp_path / "typed.toml"
    cfg.write_text(
        COLLECT.replace("train_episodes = 2", "train_episodes = 3")
        + f'file = "{fcd}"\nvehicle_types = ["{types_file}"]\n'
    )
    out = tmp_path / "typed"
    assert main(["collect", "--config", str(cfg), "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "3 of 5 vehicles are egos; not: 2 of another class than a car" in said
    assert "3 egos, types of 1 file(s))" in said  # the collection names how it read the recording
    man = json.loads((out / "manifest.json").read_text())
    assert man["demonstrator"]["egos"] == ["veh0", "veh2", "veh4"]
    digest = man["demonstrator"]["vehicle_types"][0]
    assert digest["path"] == str(types_file) and len(digest["sha256"]) == 64
    assert man["config"]["demonstrator"]["vehicle_types"] == [str(types_file)]


def test_a_columnar_files_type_column_is_read_as_fcds_type_attribute(typed, tmp_path):
    from tests.data.test_recording import _columns, _csv

    types_file, fcd = typed
    road, read = load_road(), ReadAs(vehicle_types=(str(types_file),))
    cols = _columns(fcd)
    cols["type"] = [KINDS[v] for v in cols["id"]]
    rec = open_recording(_csv(tmp_path / "typed.csv", cols), road, 0.1, read)
    assert (
        rec.vclass
        == open_recording(fcd, road, 0.1, read).vclass
        == ("passenger", "truck", "passenger", "bicycle", "passenger")
    )
    cols["type"][7] = None  # a row without its type
    with pytest.raises(IrlsimError) as e:
        open_recording(_csv(tmp_path / "gap.csv", cols), road, 0.1, read)
    assert "row 9: vehicle veh" in str(e.value) and "has no type" in str(e.value)
