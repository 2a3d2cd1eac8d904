"""Recorded vehicle sizes: the optional length and width columns of the columnar format, checked, kept
per vehicle and driven at in SUMO (replayed and reactive), as the observation reports them."""

from __future__ import annotations

import pytest

from irlsim.data.recording import load_recording
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from tests.data.test_recording import _columns, _csv

#: per recorded vehicle of the fixture: a car, a van, a truck, a bus, a motorbike [m]
SIZES = {
    "veh0": (4.5, 1.8),
    "veh1": (6.0, 2.1),
    "veh2": (12.0, 2.5),
    "veh3": (18.0, 2.55),
    "veh4": (2.2, 0.8),
}


def _sized(fcd_path, tmp_path, sizes=SIZES):
    cols = _columns(fcd_path)
    cols["length"] = [sizes[v][0] for v in cols["id"]]
    cols["width"] = [sizes[v][1] for v in cols["id"]]
    return cols


def test_sizes_are_read_per_vehicle_and_absent_without_the_columns(fcd, tmp_path):
    net = load_road().net
    rec = load_recording(_csv(tmp_path / "sized.csv", _sized(fcd, tmp_path)), net, 0.1)
    assert rec.size["length"].tolist() == [SIZES[v][0] for v in rec.ids]
    assert rec.size["width"].tolist() == [SIZES[v][1] for v in rec.ids]
    assert load_recording(_csv(tmp_path / "plain.csv", _columns(fcd)), net, 0.1).size == {}


@pytest.mark.parametrize("reactive", [False, True])
def test_the_others_are_driven_and_observed_at_their_recorded_size(fcd, tmp_path, reactive):
    from irlsim.data.recorded import recorded_episode
    from irlsim.planner.config import PlannerConfig
    from irlsim.sim.config import EpisodeConfig

    path = _csv(tmp_path / "sized.csv", _sized(fcd, tmp_path))
    _, _, _, sim = recorded_episode(
        str(path), load_road(), EpisodeConfig(), PlannerConfig(n_policies=50), "veh0", reactive=reactive
    )
    seen: dict[str, tuple[float, float]] = {}
    with sim:
        sim.reset(0)
        for _ in range(120):  # the others enter the recording at 2, 4, 6 and 8 s
            sim.step(None)
            obs = sim.observe()
            v = obs.vehicles
            seen |= {i: (float(a), float(b)) for i, a, b in zip(v.ids, v.length, v.width, strict=True)}
            if sim.done:
                break
        api = sim._api.vehicle
        for vid in api.getIDList():
            if vid.startswith("rec/"):
                assert (api.getLength(vid), api.getWidth(vid)) == SIZES[vid.removeprefix("rec/")]
    assert seen == {f"rec/veh{i}": SIZES[f"veh{i}"] for i in range(1, 5)}  # each, at its size


BAD = {
    "centimetres": ({"veh2": (1200.0, 250.0)}, "length 1200 is not a vehicle's length in metres"),
    "narrow": ({"veh4": (2.2, 0.08)}, "width 0.08 is not a vehicle's width in metres"),
}


@pytest.mark.parametrize("kind", list(BAD))
def test_a_size_in_other_units_is_refused_in_one_line(fcd, tmp_path, kind):
    change, words = BAD[kind]
    path = _csv(tmp_path / "bad.csv", _sized(fcd, tmp_path, {**SIZES, **change}))
    with pytest.raises(IrlsimError) as e:
        load_recording(path, load_road().net, 0.1)
    msg = str(e.value)
    assert words in msg and str(path) in msg and "row" in msg and "\n" not in msg, msg


def test_a_vehicle_whose_size_changes_is_refused_in_one_line(fcd, tmp_path):
    cols = _sized(fcd, tmp_path)
    rows = [i for i, v in enumerate(cols["id"]) if v == "veh1"]
    cols["length"][rows[7]] = 6.5
    path = _csv(tmp_path / "bad.csv", cols)
    with pytest.raises(IrlsimError) as e:
        load_recording(path, load_road().net, 0.1)
    msg = str(e.value)
    assert "vehicle veh1 has length 6.5 m after 6 m: a vehicle has one length" in msg, msg
    assert str(path) in msg and "\n" not in msg
    cols["length"][rows[7]] = 6.0 + 0.004  # within a dataset's rounding
    assert load_recording(_csv(tmp_path / "ok.csv", cols), load_road().net, 0.1).size["length"][1] == 6.0
