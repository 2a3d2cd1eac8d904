"""A recording's reference point: public datasets give the centre of a vehicle's box where SUMO (and
irlsim) take the front bumper's centre. With ``demonstrator.position = 'centre'`` and a length column each
row moves half its vehicle's length along its heading; the same tracks given at the centre and at the
front are then one recording, and what cannot be read so is refused in one line before any work."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from irlsim.data.demonstrator import DemonstratorConfig
from irlsim.data.recording import load_recording
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from tests.data.test_recording import _collect, _columns, _csv
from tests.data.test_recording_sizes import _sized


def _centred(cols: dict[str, list]) -> dict[str, list]:
    """The same rows at the centre of each vehicle's box: half its length back along its heading."""
    half = 0.5 * np.asarray(cols["length"])
    h = np.asarray(cols["heading"])
    return cols | {
        "x": (np.asarray(cols["x"]) - half * np.cos(h)).tolist(),
        "y": (np.asarray(cols["y"]) - half * np.sin(h)).tolist(),
    }


@pytest.fixture(scope="module")
def files(fcd, tmp_path_factory) -> tuple[Path, Path, Path]:
    """(the fixture's tracks with sizes at the front bumper, the same at the centre, and at the centre
    without the heading column)."""
    tmp = tmp_path_factory.mktemp("position")
    front = _sized(fcd, tmp)
    centre = _centred(front)
    no_heading = {k: v for k, v in centre.items() if k != "heading"}
    return (
        _csv(tmp / "front.csv", front),
        _csv(tmp / "centre.csv", centre),
        _csv(tmp / "centre_no_heading.csv", no_heading),
    )


def test_centre_positions_are_read_at_the_front_bumper(files):
    net = load_road().net
    front_file, centre_file, no_heading_file = files
    front = load_recording(front_file, net, 0.1)
    centre = load_recording(centre_file, net, 0.1, position="centre")
    assert centre.ids == front.ids and np.array_equal(centre.start, front.start)
    assert np.allclose(centre.x, front.x, atol=1e-6) and np.allclose(centre.y, front.y, atol=1e-6)
    assert centre.edges == front.edges and centre.sha256 != front.sha256
    # read as front bumpers, the centres lie half a length behind (between rows in a curve the
    # interpolated chords a little less): the reference point matters
    as_front = load_recording(centre_file, net, 0.1)
    half = 0.5 * np.repeat(front.size["length"], np.diff(front.start))
    assert np.allclose(np.hypot(as_front.x - front.x, as_front.y - front.y), half, rtol=0.01)
    # without headings the direction of motion turns the centre to the front, within its own error (a
    # tenth of a radian at most, where a track ends in a curve: a metre for an 18 m bus)
    derived = load_recording(no_heading_file, net, 0.1, position="centre")
    miss = np.hypot(derived.x - front.x, derived.y - front.y)
    assert np.median(miss) < 0.01 and (miss <= 0.11 * half).all()


def test_what_cannot_be_read_at_the_centre_is_one_line(fcd, files, tmp_path):
    net = load_road().net
    cases = {
        "SUMO's FCD output": (fcd, "centre"),
        "no length column": (_csv(tmp_path / "plain.csv", _columns(fcd)), "centre"),
        "is not one of front, centre": (files[0], "middle"),
    }
    for needle, (path, position) in cases.items():
        with pytest.raises(IrlsimError) as e:
            load_recording(path, net, 0.1, position=position)
        assert needle in str(e.value) and str(path) in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(IrlsimError, match="must be one of front, centre"):
        DemonstratorConfig(kind="recording", file="r.csv", position="middle").validate()
    with pytest.raises(IrlsimError, match="belong to kind = 'recording'"):
        DemonstratorConfig(kind="sumo", position="centre").validate()


def test_a_collection_from_centres_is_the_collection_from_front_bumpers(files, tmp_path):
    front_file, centre_file, _ = files
    ego = 'ego = "veh1"\n'
    rc_f, front = _collect(tmp_path, "front", f'file = "{front_file}"\n{ego}', train=1)
    at_centre = f'file = "{centre_file}"\nposition = "centre"\n{ego}'
    rc_c, centre = _collect(tmp_path, "centre", at_centre, train=1)
    assert rc_f == rc_c == 0
    a = pq.read_table(front / "train" / "episode_00000.cycles.parquet").to_pandas()
    b = pq.read_table(centre / "train" / "episode_00000.cycles.parquet").to_pandas()
    assert len(a) == len(b) and a["has_demo"].sum() >= 10
    assert np.array_equal(a["demo_index"], b["demo_index"])
    assert np.allclose(a["ego_x"], b["ego_x"], atol=1e-4) and np.allclose(a["ego_y"], b["ego_y"], atol=1e-4)
    # the manifest says how the file was read; a front-bumper recording's manifest is as before
    man_c, man_f = (json.loads((d / "manifest.json").read_text()) for d in (centre, front))
    assert man_c["config"]["demonstrator"]["position"] == "centre"
    assert "position" not in man_f["config"]["demonstrator"]
    assert man_c["demonstrator"]["position"] == "centre" and "position" not in man_f["demonstrator"]
