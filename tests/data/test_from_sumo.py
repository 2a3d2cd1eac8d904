"""A SUMO scenario of the user's own (``irlsim scenario from-sumo``): SUMO runs its configuration alone
(the wheel's binary, the configuration's routes, drivers and signals) and records it; the network, the
vehicle types and the signal programs become a scenario and configs that collect its cars as egos in turn.
The scenario here is SUMO's own game crossing (cars, buses and trucks under signals), named by a
configuration of its own as a user writes one: relative paths, SUMO's option synonyms."""

from __future__ import annotations

import gzip
import json
import os
import re
from pathlib import Path

import pytest

from irlsim.cli import main
from irlsim.data.demonstrator import collected_egos
from irlsim.data.recorded import open_recording
from irlsim.data.recording_as import ReadAs
from irlsim.data.sumocfg import read_sumocfg, sumo_time, vtypes_xml
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import sumo_home
from irlsim.sim.vehicle_types import vehicle_types
from irlsim.workflows.from_sumo import split_at_gaps

CROSS = Path(sumo_home()) / "tools" / "game" / "cross"


def write_config(folder: Path, end: str = "150", extra: str = "") -> Path:
    """A configuration of SUMO's game crossing in ``folder``, its files named relative to it."""
    rel = os.path.relpath(CROSS, folder)
    cfg = folder / "cross.sumocfg"
    cfg.write_text(
        f'<configuration><input><n v="{rel}/cross.net.xml"/><route-files value="{rel}/cross.rou.xml"/>'
        f'<additional-files value="{rel}/cross.tls.add.xml"/></input>'
        f'<time><begin value="0"/><end value="{end}"/><step-length value="0.2"/></time>{extra}'
        "</configuration>"
    )
    return cfg


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> tuple[Path, Path]:
    """(the configuration, the folder it was imported into)."""
    tmp = tmp_path_factory.mktemp("from-sumo")
    cfg = write_config(tmp)
    assert main(["scenario", "from-sumo", str(cfg), "--out", str(tmp / "out")]) == 0
    return cfg, tmp / "out"


def test_a_configuration_is_read_as_sumo_reads_it(tmp_path):
    cfg = read_sumocfg(write_config(tmp_path))
    assert cfg.net == (CROSS / "cross.net.xml").resolve()  # a synonym of net-file, relative to the file
    assert cfg.routes == ((CROSS / "cross.rou.xml").resolve(),)
    assert (cfg.begin, cfg.end, cfg.step) == (0.0, 150.0, 0.2)
    assert sumo_time("15:00:00", "t") == 54000.0 and sumo_time("1:00:00:30", "t") == 86430.0
    assert sumo_time("2:30", "t") == 150.0 and sumo_time(" 7.5 ", "t") == 7.5
    assert read_sumocfg(write_config(tmp_path, end="-1")).end is None  # SUMO's "no end"
    with pytest.raises(IrlsimError, match="'noon' is no time"):
        sumo_time("noon", "end")


def test_a_vehicle_sumo_teleported_is_one_vehicle_per_stretch():
    # SUMO teleports a vehicle stuck in a jam: it leaves the FCD output and comes back further on; a
    # recording refuses a gap over 1 s, so each stretch after one gets an id of its own
    fcd = [b"<fcd-export>\n"]
    for t in (0.0, 0.5, 1.0, 4.0, 4.5, 9.0):
        fcd.append(b'    <timestep time="%.2f">\n' % t)
        fcd.append(b'        <vehicle id="a" x="%.1f" y="0.00" angle="90.00"/>\n' % t)
        if t < 1.2:
            fcd.append(b'        <vehicle id="b" x="1.0" y="3.00" angle="90.00"/>\n')
        fcd.append(b"    </timestep>\n")
    out = b"".join(split_at_gaps(fcd + [b"</fcd-export>\n"])).decode()
    ids = re.findall(r'<vehicle id="([^"]+)"', out)
    assert ids == ["a", "b", "a", "b", "a", "b", "a#1", "a#1", "a#2"]
    assert out.count("<timestep") == 6 and 'x="4.0"' in out  # nothing else changes


def test_every_vehicle_type_of_the_files_is_one_file_sumo_loads(tmp_path):
    # types inside a distribution are what FCD names; a type defined twice is kept as first defined
    a, b = tmp_path / "a.rou.xml", tmp_path / "b.add.xml"
    a.write_text(
        '<routes><vTypeDistribution id="mix"><vType id="small" length="3.5" probability="2"/>'
        '<vType id="van" length="6.0" width="2.1"/></vTypeDistribution><route id="r" edges="x"/></routes>'
    )
    b.write_text('<additional><vType id="van" length="9.0"/><vType id="lorry" vClass="truck"/></additional>')
    text, n = vtypes_xml((a, b))
    assert n == 3 and text.count("<vType") == 3 and 'length="9.0"' not in text
    (tmp_path / "types.add.xml").write_text(text)
    types = vehicle_types(CROSS / "cross.net.xml", (str(tmp_path / "types.add.xml"),))
    assert (types["small"].length, types["van"].length, types["van"].width) == (3.5, 6.0, 2.1)
    assert types["lorry"].vclass == "truck"


def test_a_configuration_becomes_a_scenario_whose_cars_collect_in_the_order_they_came(imported, tmp_path):
    cfg, out = imported
    made = json.loads((out / "from-sumo.json").read_text())
    scenario = (out / "scenario.toml").read_text()
    assert 'sumo_tools = "game/cross/cross.net.xml"' in scenario  # inside the wheel: named portably
    assert 'additional = ["sumo_tools/game/cross/cross.tls.add.xml"]' in scenario  # its signals
    road = load_road(scenario=out / "scenario.toml")
    assert road.additional and road.edges
    with gzip.open(out / "recording.fcd.xml.gz", "rt") as f:
        assert "generated on" not in f.read(4096)  # SUMO's header (its time) left out
    rec = open_recording(
        out / "recording.fcd.xml.gz", road, 0.1, ReadAs(vehicle_types=(str(out / "vtypes.add.xml"),))
    )
    egos = made["collect_egos"] + made["drive_egos"]
    assert len(egos) == made["egos"] >= 4 and len(made["drive_egos"]) == max(1, len(egos) // 10)
    entered = [float(rec.t0[rec.ids.index(v)]) for v in egos]
    assert entered == sorted(entered)  # collected first, driven last, in the order they came
    # no ego is a car still driving when SUMO stopped (its route's end would be where the recording ends)
    ends = {v: rec.t0[k] + (rec.start[k + 1] - rec.start[k] - 1) * rec.step for k, v in enumerate(rec.ids)}
    last = max(ends.values())
    assert made["unfinished"] == sum(1 for t in ends.values() if t > last - 0.05) > 0
    assert all(ends[v] < last - 0.05 for v in egos)
    data = tmp_path / "data"
    small = ["--set", "train_episodes=1", "--set", "validation_episodes=1", "--set", "test_episodes=1",
             "--set", "max_cycles=10", "--set", "planner.n_policies=100", "--set", "workers=1"]  # fmt: skip
    assert main(["collect", "--config", made["collect"], "--out", str(data), *small]) == 0
    collected = collected_egos(json.loads((data / "manifest.json").read_text()))
    assert collected is not None and collected[1] == made["collect_egos"][:3]
    # the same configuration imported again is the same bytes (the recording included): nothing refused
    before = {f.name: f.read_bytes() for f in out.iterdir() if f.is_file()}
    assert main(["scenario", "from-sumo", str(cfg), "--out", str(out)]) == 0
    assert {f.name: f.read_bytes() for f in out.iterdir() if f.is_file()} == before


def test_a_recording_made_with_the_configuration_is_imported_as_given(imported, tmp_path):
    cfg, out = imported
    given = tmp_path / "mine.fcd.xml.gz"
    given.write_bytes((out / "recording.fcd.xml.gz").read_bytes())
    assert (
        main(["scenario", "from-sumo", str(cfg), "--out", str(tmp_path / "b"), "--recording", str(given)])
        == 0
    )
    assert not (tmp_path / "b" / "recording.fcd.xml.gz").exists()
    assert f'file = "{given}"' in (tmp_path / "b" / "collect.toml").read_text()
    made, again = (json.loads((d / "from-sumo.json").read_text()) for d in (out, tmp_path / "b"))
    assert again["collect_egos"] == made["collect_egos"]


def test_a_configurations_trucks_get_configs_of_their_own(tmp_path):
    # SUMO's class decides: the game's types are all of class passenger; a type of class truck is a truck
    rel = os.path.relpath(CROSS, tmp_path)
    (tmp_path / "lorries.rou.xml").write_text(
        '<routes><vType id="lorry" vClass="truck" length="12.0" width="2.5"/>'
        '<route id="lorry_route" edges="3fi 3si 4o 4fo"/>'
        '<flow id="lorry" type="lorry" route="lorry_route" begin="2" end="70" period="9" departSpeed="10"/>'
        "</routes>"
    )
    cfg = write_config(tmp_path, end="240")
    cfg.write_text(cfg.read_text().replace(f"{rel}/cross.rou.xml", f"{rel}/cross.rou.xml,lorries.rou.xml"))
    out = tmp_path / "out"
    assert main(["scenario", "from-sumo", str(cfg), "--out", str(out)]) == 0
    made = json.loads((out / "from-sumo.json").read_text())
    trucks = made["trucks-collect_egos"] + made["trucks-drive_egos"]
    assert made["trucks"] == len(trucks) >= 4 and all(v.startswith("lorry.") for v in trucks)
    assert not set(trucks) & set(made["collect_egos"] + made["drive_egos"])  # no truck among the cars
    text = (out / "trucks-collect.toml").read_text()
    assert 'ego_classes = ["truck"]' in text and 'ego_size = "recorded"' in text
    data = tmp_path / "data"
    small = ["--set", "train_episodes=1", "--set", "validation_episodes=0", "--set", "test_episodes=0",
             "--set", "max_cycles=10", "--set", "planner.n_policies=100", "--set", "workers=1"]  # fmt: skip
    assert main(["collect", "--config", made["trucks-collect"], "--out", str(data), *small]) == 0
    collected = collected_egos(json.loads((data / "manifest.json").read_text()))
    assert collected is not None and collected[1][:1] == made["trucks-collect_egos"][:1]


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("missing", "SUMO configuration .* not found: give the .sumocfg"),
        ("no network", "names no network"),
        ("missing route file", "route-files nowhere.rou.xml not found"),
        ("bad time", "end: 'soon' is no time"),
        ("gui option", "SUMO stopped on .*No option with the name 'osg-view' exists"),
        ("missing recording", "--recording .* not found"),
        ("too short", r"0 of the recording's \d+ vehicles are cars that drive a route"),
    ],
)
def test_a_bad_configuration_is_one_line_and_writes_nothing(tmp_path, case, message, capsys):
    cfg = write_config(tmp_path, end="soon" if case == "bad time" else "150")
    extra: list[str] = []
    if case == "missing":
        cfg = tmp_path / "none.sumocfg"
    elif case == "no network":
        cfg.write_text('<configuration><input><route-files value="x.rou.xml"/></input></configuration>')
    elif case == "missing route file":
        cfg.write_text(
            cfg.read_text().replace(f"{os.path.relpath(CROSS, tmp_path)}/cross.rou.xml", "nowhere.rou.xml")
        )
    elif case == "gui option":
        cfg = write_config(tmp_path, extra='<gui_only><osg-view value="true"/></gui_only>')
    elif case == "missing recording":
        extra = ["--recording", str(tmp_path / "none.fcd.xml")]
    elif case == "too short":
        extra = ["--duration", "5"]
    out = tmp_path / "out"
    assert main(["scenario", "from-sumo", str(cfg), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    assert re.search(message, err), err
    assert not out.exists()  # a folder the import made is removed with what it held
