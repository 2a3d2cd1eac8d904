"""Recordings as users bring them, with real SUMO: SUMO's gzipped FCD, an FCD without speeds, time in
milliseconds, a recording given with another scenario whose lanes pass near its points."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
import sumolib

from irlsim.data.recording import load_recording
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import sumo_binary
from irlsim.road.scenario import Scenarios
from tests.data.conftest import record_fcd
from tests.data.test_recording import _bad, _columns, _csv
from tests.data.test_recording_street import _plain_net


def test_sumos_gzipped_fcd_is_the_same_recording(fcd, tmp_path):
    routes = fcd.parent / "cars.rou.xml"  # the fixture's run again, written gzipped (the name ends in .gz)
    gz = record_fcd(routes, tmp_path / "fcd.xml.gz")
    assert gz.read_bytes()[:2] == b"\x1f\x8b"
    net = load_road().net
    plain, packed = load_recording(fcd, net, 0.1), load_recording(gz, net, 0.1)
    assert packed.ids == plain.ids and packed.edges == plain.edges
    for vid in plain.ids:
        a, b = plain.track(vid), packed.track(vid)
        assert all(np.array_equal(a[k], b[k]) for k in ("t", "x", "y", "v", "heading"))
    broken = tmp_path / "cut.xml.gz"
    broken.write_bytes(gz.read_bytes()[: len(gz.read_bytes()) // 2])
    with pytest.raises(IrlsimError, match=r"cut\.xml\.gz cannot be read .*give SUMO's FCD output unchanged"):
        load_recording(broken, net, 0.1)


def test_an_fcd_without_speeds_names_the_attribute(fcd, tmp_path):
    routes = fcd.parent / "cars.rou.xml"
    bare = record_fcd(routes, tmp_path / "bare.xml", "--fcd-output.attributes", "x,y,angle")
    with pytest.raises(IrlsimError) as e:
        load_recording(bare, load_road().net, 0.1)
    msg = str(e.value)
    assert "vehicle record 1 has no 'speed' attribute" in msg and "--fcd-output.attributes" in msg, msg
    assert "\n" not in msg


def test_a_recording_on_a_network_whose_lanes_pass_near_it_is_told_to_check_the_scenario(fcd, tmp_path):
    # the own-driver example's oval recording against the grid: the grid's dense lanes pass within 5 m of
    # 90 % of its points, too few off for "another network's coordinates", too many vehicles for one's fault
    grid = load_road(scenario=Scenarios()("grid")).net
    with pytest.raises(IrlsimError) as e:
        load_recording("examples/mydriver/recording.csv", grid, 0.1)
    msg = str(e.value)
    assert "so are 10% of the points, of 5 of its 6 vehicles" in msg, msg
    assert msg.endswith("or give the scenario the recording was made on")
    one = _csv(tmp_path / "one.csv", _bad(_columns(fcd), "off the network"))  # one vehicle's one point
    with pytest.raises(IrlsimError) as e:
        load_recording(one, load_road().net, 0.1)
    assert "veh1" in str(e.value) and "scenario" not in str(e.value)


def test_time_in_milliseconds_is_named_as_such(fcd, tmp_path):
    cols = _columns(fcd)
    cols["t"] = [1000.0 * t for t in cols["t"]]  # 0.5 s rows written as 500 ms
    path = _csv(tmp_path / "ms.csv", cols)
    with pytest.raises(IrlsimError) as e:
        load_recording(path, load_road().net, 0.1)
    msg = str(e.value)
    assert "rows are 500 apart: t looks like milliseconds" in msg and "\n" not in msg, msg
    cols["t"] = [t / 1000.0 * 3.0 for t in cols["t"]]  # rows 1.5 s apart: a slow rate, not milliseconds
    with pytest.raises(IrlsimError, match=r"rows are 1.5 s apart \(the median\)"):
        load_recording(_csv(tmp_path / "slow.csv", cols), load_road().net, 0.1)


@pytest.mark.parametrize("mistake", ["north, clockwise", "x and y swapped"])
def test_headings_in_another_convention_are_refused_before_any_work(fcd, tmp_path, mistake):
    cols = _columns(fcd)  # ENU headings, as the format asks: accepted (the columnar format's own test)
    if mistake == "north, clockwise":  # SUMO's angle convention in radians: every cycle had lost its label
        cols["heading"] = [float(np.mod(np.pi / 2 - h, 2 * np.pi)) for h in cols["heading"]]
    else:
        cols["x"], cols["y"] = cols["y"], cols["x"]
    with pytest.raises(IrlsimError) as e:
        load_recording(_csv(tmp_path / "h.csv", cols), load_road().net, 0.1)
    msg = str(e.value)
    assert "headings differ from the direction its positions move in" in msg and "\n" not in msg, msg
    assert "radians(90 - angle)" in msg and "x and y are swapped" in msg


@pytest.mark.parametrize("convention", ["ENU", "north, clockwise"])
def test_standing_cars_position_noise_is_no_heading_convention(fcd, tmp_path, convention):
    """SUMO's five cars (0.5 s rows), each standing 240 s where it starts before it drives, every position
    with 0.5 m of noise: row to row a standing car seems to move 0.7 m in any direction, which over most
    rows had been read as headings in SUMO's convention; the convention itself is still named."""
    cols = _columns(fcd)
    ids = list(dict.fromkeys(cols["id"]))
    first = {vid: cols["id"].index(vid) for vid in ids}
    stand: dict[str, list] = {k: [] for k in cols}
    for vid in ids:
        i = first[vid]
        for j in range(480, 0, -1):
            for k in cols:
                stand[k].append(cols[k][i] - 0.5 * j if k == "t" else 0.0 if k == "v" else cols[k][i])
    both = {k: stand[k] + cols[k] for k in cols}
    rng = np.random.default_rng(3)
    for k in ("x", "y"):
        both[k] = list(np.asarray(both[k]) + rng.normal(0.0, 0.5, len(both[k])))
    if convention != "ENU":
        both["heading"] = [float(np.mod(np.pi / 2 - h, 2 * np.pi)) for h in both["heading"]]
    path = _csv(tmp_path / "standing.csv", both)
    if convention == "ENU":
        assert load_recording(path, load_road().net, 0.1).ids == tuple(sorted(ids))
    else:
        with pytest.raises(IrlsimError, match="headings differ from the direction its positions move in"):
            load_recording(path, load_road().net, 0.1)


def _angle(a, b) -> np.ndarray:
    return np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))


def test_without_headings_a_recording_takes_the_direction_of_motion(fcd, tmp_path):
    """The columnar format without ``heading`` (public datasets' tracks often have none): each row's is
    the direction the positions move in over about 1 s, close to SUMO's own on the oval's straights and
    curves; a car standing before it drives holds its first heading; a car that never moves takes its
    lane's direction; the routes are those of the recorded headings; a missing column is still named."""
    cols = _columns(fcd)
    first = {vid: cols["id"].index(vid) for vid in dict.fromkeys(cols["id"])}
    extra: dict[str, list] = {k: [] for k in cols}
    for j in range(40, 0, -1):  # veh1 stands 20 s where it starts; 'parked' stands where veh0 starts
        for vid, as_id in (("veh1", "veh1"), ("veh0", "parked")):
            i = first[vid]
            for k in cols:
                value = cols[k][i] - 0.5 * j if k == "t" else 0.0 if k == "v" else cols[k][i]
                extra[k].append(as_id if k == "id" else value)
    both = {k: extra[k] + cols[k] for k in cols}
    given = load_recording(_csv(tmp_path / "given.csv", both), load_road().net, 0.1)
    without = {k: v for k, v in both.items() if k != "heading"}
    derived = load_recording(_csv(tmp_path / "derived.csv", without), load_road().net, 0.1)
    assert derived.ids == given.ids and derived.edges == given.edges
    err = _angle(derived.heading, given.heading)
    assert err.max() < 0.1 and err.mean() < 0.01, (err.max(), err.mean())
    parked = given.ids.index("parked")
    assert np.ptp(derived.heading[derived.start[parked] : derived.start[parked + 1]]) == 0.0
    del without["x"]
    with pytest.raises(IrlsimError, match=r"lacks the column\(s\) x: give id, t \[s\], x, y \[m\], v"):
        load_recording(_csv(tmp_path / "nox.csv", without), load_road().net, 0.1)


def test_a_recording_at_a_slower_rate_than_a_second_is_named_as_such(fcd, tmp_path):
    """Every row 2 s apart is the recording's rate, not a gap of each vehicle's to split or fill."""
    cols = _columns(fcd)  # 0.5 s rows
    keep = [i for i, t in enumerate(cols["t"]) if t % 2.0 == 0.0]
    path = _csv(tmp_path / "slow.csv", {k: [v[i] for i in keep] for k, v in cols.items()})
    with pytest.raises(IrlsimError) as e:
        load_recording(path, load_road().net, 0.1)
    msg = str(e.value)
    assert "a vehicle's rows are 2 s apart (the median)" in msg and "record at least every 1 s" in msg, msg
    assert "\n" not in msg and "gap" not in msg


def test_the_networks_original_projection_is_named_as_such(tmp_path):
    """SUMO's ``--fcd-output.utm`` writes a network's original coordinates, its netOffset taken off (a
    netconvert network of nodes half a million metres east, as a UTM zone's are): named with the offset to
    add, not as another network's coordinates; the same run without .utm is read."""
    nodes = {"a": (500000, 5400000), "b": (500600, 5400000)}
    net = _plain_net(tmp_path, "u", nodes, {"ab": 'numLanes="2" speed="20"'})
    (tmp_path / "r.rou.xml").write_text(
        '<routes><vehicle id="c" depart="0" departSpeed="max"><route edges="ab"/></vehicle></routes>'
    )
    fcd = {}
    for name, extra in (("net", []), ("utm", ["--fcd-output.utm", "true"])):
        fcd[name] = tmp_path / f"{name}.xml"
        run = [sumo_binary("sumo"), "-n", str(net), "-r", str(tmp_path / "r.rou.xml"), "--end", "20"]
        subprocess.run([*run, "--fcd-output", str(fcd[name]), *extra], check=True, capture_output=True)
    network = sumolib.net.readNet(str(net), withInternal=True)
    assert load_recording(fcd["net"], network, 0.1).ids == ("c",)
    with pytest.raises(IrlsimError) as e:
        load_recording(fcd["utm"], network, 0.1)
    msg = str(e.value)
    assert "once its netOffset (-500000.00, -5400000.00) is added" in msg and "--fcd-output.utm" in msg, msg
    assert "\n" not in msg
