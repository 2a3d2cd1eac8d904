"""A highD recording (``irlsim scenario from-highd``): its three CSV files become a SUMO network of its
road, a scenario and a recording per carriageway, and configs that collect. The recording is SUMO's own
run on a road of highD's layout (two carriageways of three lanes), written in highD's conventions: the
upper left corner of each box in the image's frame (y down), the box's extent along x as ``width``, at
25 Hz, cars and trucks; imported, it lands where SUMO drove, on SUMO's lanes."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data.demonstrator import collected_egos
from irlsim.data.recorded import open_recording
from irlsim.data.recording_as import ReadAs
from irlsim.data.recording_read import read_rows
from irlsim.road import load_road

#: examples/highd/sample.py: SUMO's run on a road of highD's shape, written as highD's recording 01
_SPEC = importlib.util.spec_from_file_location(
    "sample", Path(__file__).parents[2] / "examples/highd/sample.py"
)
assert _SPEC is not None and _SPEC.loader is not None
sample = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(sample)
HZ = sample.HZ


@pytest.fixture(scope="module")
def highd(tmp_path_factory) -> tuple[Path, Path, Path, dict[str, int]]:
    """(the highD files' folder, SUMO's network, SUMO's FCD, SUMO id -> highD id), and the import."""
    tmp = tmp_path_factory.mktemp("highd")
    net, fcd = sample.sumo_run(tmp)
    folder = tmp / "highD"
    folder.mkdir()
    ids = sample.as_highd(fcd, folder)
    assert main(["scenario", "from-highd", str(folder / "01"), "--out", str(tmp / "hd01")]) == 0
    return tmp, net, fcd, ids


def test_a_highd_recording_lands_where_sumo_drove_on_sumos_lanes(highd):
    """Each carriageway's recording is SUMO's run on it, row for row: the same vehicles, front bumpers
    within a millimetre of SUMO's, the same headings and SUMO's own lane at every row; read as its collect
    config reads it, every car is an ego (every one drove the whole road) and no truck is."""
    tmp, _, fcd, ids = highd
    out = tmp / "hd01"
    ref = read_rows(fcd)
    row_of = {(v, int(round(t * HZ))): i for i, (v, t) in enumerate(zip(ref.id.tolist(), ref.t, strict=True))}
    back = {str(h): v for v, h in ids.items()}
    made = json.loads((out / "highd.json").read_text())
    for side in ("lower", "upper"):
        got = pq.read_table(out / f"{side}.parquet").to_pydict()
        sumo_ids = [back[i] for i in got["id"]]
        assert set(sumo_ids) == {v for v in ref.id.tolist() if v.startswith(side)}
        at = np.array(
            [row_of[(v, int(round(t * HZ)) - 1)] for v, t in zip(sumo_ids, got["t"], strict=True)]
        )  # frames from 1
        x, y, h, length = (np.array(got[c]) for c in ("x", "y", "heading", "length"))
        assert np.abs(x + length / 2 * np.cos(h) - ref.x[at]).max() < 1e-3
        assert np.abs(y + length / 2 * np.sin(h) - ref.y[at]).max() < 1e-3
        assert np.abs(np.angle(np.exp(1j * (h - ref.heading[at])))).max() < 1e-4
        road = load_road(scenario=out / f"{side}.toml")
        lanes = road.lane_of_d(road.to_frenet(x, y)[1])
        assert ref.lane is not None and (lanes == [int(ln.rsplit("_", 1)[1]) for ln in ref.lane[at]]).all()
        assert len(set(lanes.tolist())) == 3  # SUMO drove every lane
        read = ReadAs("centre", (str(out / "vtypes.add.xml"),))
        rec = open_recording(out / f"{side}.parquet", road, 0.1, read)
        cars = sorted(str(ids[v]) for v in set(sumo_ids) if sample.kind_of(v) == "car")
        assert sorted(made[side]["collect_egos"] + made[side]["drive_egos"]) == cars
        assert len(made[side]["drive_egos"]) == 1 and rec.vclass.count("truck") == 4


def test_a_highd_import_collects_its_cars_in_the_order_they_came(highd, tmp_path):
    """The lower carriageway's collect config collects (a smaller planner, the first two cars): its
    episodes are the cars in the order they entered the road, each a recorded car."""
    tmp, _, _, _ = highd
    config = tmp / "hd01" / "lower-collect.toml"
    sets = ["--set", "train_episodes=1", "--set", "validation_episodes=1", "--set", "test_episodes=0"]
    sets += ["--set", "planner.n_policies=100", "--set", "max_cycles=15", "--set", "workers=1"]
    assert main(["collect", "--config", str(config), "--out", str(tmp_path / "data"), *sets]) == 0
    collected = collected_egos(json.loads((tmp_path / "data" / "manifest.json").read_text()))
    first = json.loads((tmp / "hd01" / "highd.json").read_text())["lower"]["collect_egos"][:2]
    assert collected is not None and collected[1] == first == ["1", "3"]  # SUMO's lower0 and lower1


def _copy(src: Path, dst: Path, edit: dict[str, dict[str, object]] | None = None) -> Path:
    """highD recording 01 copied to ``dst``, a file's columns replaced (None: dropped) as ``edit`` says."""
    dst.mkdir()
    for kind in ("tracks", "tracksMeta", "recordingMeta"):
        table = pacsv.read_csv(src / f"01_{kind}.csv")
        for col, value in (edit or {}).get(kind, {}).items():
            i = table.column_names.index(col)
            table = table.remove_column(i)
            if value is not None:
                table = table.add_column(i, col, pa.array([value] * table.num_rows))
        pacsv.write_csv(table, dst / f"01_{kind}.csv")
    return dst / "01"


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        ({"tracks": {"xVelocity": None}}, r"01_tracks.csv: no column 'xVelocity' \(it has frame, id, "),
        ({"tracksMeta": {"class": "Bus"}}, r"vehicle class 'bus' is not one of highD's \(Car, Truck\)"),
        (
            {"recordingMeta": {"lowerLaneMarkings": "216;254;292;330"}},
            r"lowerLaneMarkings '216;254;292;330' "
            r"are not a carriageway's lane markings \(two or more image y in metres",
        ),  # fmt: skip
        ({"tracksMeta": {"drivingDirection": 3}}, r"has drivingDirection 3: highD's are 1 \(upper\) and 2"),
        ({"recordingMeta": {"frameRate": 0}}, r"frameRate 0 is not a rate: give it in Hz"),
        (
            {"recordingMeta": {"speedLimit": 120.0}},
            r"speedLimit 120 is not highD's \(m/s, -1 where .* 432 km/h",
        ),
    ],
)
def test_a_bad_highd_recording_is_one_line_and_writes_nothing(highd, tmp_path, edit, message, capsys):
    """Each before anything is written: --out is not even made."""
    tmp, _, _, _ = highd
    recording = _copy(tmp / "highD", tmp_path / "highD", edit)
    out = tmp_path / "out"
    assert main(["scenario", "from-highd", str(recording), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert re.search(message, err) and "\n" not in err, err
    assert not out.exists()


def test_a_highd_import_that_cannot_finish_leaves_its_folder_as_it_was(highd, tmp_path, capsys):
    """A missing file names the three a recording needs; a carriageway with too few cars for
    --min-duration is one line after the network is built, and nothing of that run is left in --out
    (a previous import there keeps its bytes); the same import again gives the same bytes, and another
    one into the same --out is refused rather than overwrite it."""
    tmp, _, _, _ = highd
    recording = _copy(tmp / "highD", tmp_path / "highD")
    (tmp_path / "highD" / "01_tracksMeta.csv").rename(tmp_path / "meta.csv")
    assert main(["scenario", "from-highd", str(recording), "--out", str(tmp_path / "out")]) == 2
    assert "01_tracksMeta.csv not found: give DIR/NN (or one of its files) where" in capsys.readouterr().err
    (tmp_path / "meta.csv").rename(tmp_path / "highD" / "01_tracksMeta.csv")
    out = tmp_path / "out"
    assert main(["scenario", "from-highd", str(tmp_path / "highD" / "01_tracks.csv"), "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    assert main(["scenario", "from-highd", str(recording), "--out", str(out), "--min-duration", "30"]) == 2
    err = capsys.readouterr().err.strip()
    assert "carriageway has 0 cars on the road for 30 s, too few to collect from and drive" in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    # the same import again is the same bytes; another (here: another --min-duration) does not overwrite it
    assert main(["scenario", "from-highd", str(recording), "--out", str(out)]) == 0
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    capsys.readouterr()
    assert main(["scenario", "from-highd", str(recording), "--out", str(out), "--min-duration", "8"]) == 2
    err = capsys.readouterr().err.strip()
    assert "of another import (or edited): choose another --out" in err and "\n" not in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_highd_import_learns_its_trucks_too_at_their_size(highd, tmp_path):
    """The trucks of a carriageway get configs of their own (egos of SUMO's class truck, each at its
    recorded 12 m): collected, the episodes are trucks and the manifest says how they were taken."""
    tmp, _, _, ids = highd
    made = json.loads((tmp / "hd01" / "highd.json").read_text())["lower"]
    assert made["trucks"] == 4 and len(made["collect_egos-trucks"]) == 3
    config = tmp / "hd01" / "lower-trucks-collect.toml"
    sets = ["--set", "planner.n_policies=100", "--set", "max_cycles=15", "--set", "workers=1"]
    assert main(["collect", "--config", str(config), "--out", str(tmp_path / "data"), *sets]) == 0
    manifest = json.loads((tmp_path / "data" / "manifest.json").read_text())
    record = manifest["demonstrator"]
    assert record["ego_classes"] == ["truck"] and record["ego_size"] == "recorded"
    back = {str(h): v for v, h in ids.items()}
    collected = collected_egos(manifest)
    assert collected is not None and [sample.kind_of(back[e]) for e in collected[1]] == ["truck"] * 3
