"""Recordings as demonstrations, with real SUMO: an FCD file written by SUMO on the oval is read back as
SUMO wrote it (and the columnar format as the same table), resampled to the step; a recorded vehicle as
ego gives demonstrations close to its odometry, the others replay their recorded poses, the same seed
the same bytes; each bad recording is refused in one line before any work."""

from __future__ import annotations

import json
import math
import re
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data.recording import load_recording
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import sumo_binary


def _sumo_fcd(road, routes: str, out: Path, end: float) -> Path:
    """SUMO run on its own (the wheel's binary) on ``road``'s network with the ``routes`` XML for ``end``
    seconds; its FCD output at ``out``."""
    rou = out.with_suffix(".rou.xml")
    rou.write_text(routes)
    cmd = [sumo_binary("sumo"), "-n", str(road.net_file), "-r", str(rou), "--end", str(end)]
    subprocess.run([*cmd, "--fcd-output", str(out), "--no-step-log", "true"], check=True, capture_output=True)
    return out


def _fcd_rows(path: Path) -> list[tuple[str, float, float, float, float, float]]:
    """(id, t, x, y, speed, angle [deg]) of every <vehicle> as SUMO wrote it."""
    out = []
    for ts in ET.parse(path).getroot().iter("timestep"):
        t = float(ts.get("time"))
        for v in ts.iter("vehicle"):
            out.append((v.get("id"), t, *(float(v.get(k)) for k in ("x", "y", "speed", "angle"))))
    return out


def _columns(path: Path) -> dict[str, list]:
    rows = _fcd_rows(path)
    return {
        "id": [r[0] for r in rows],
        "t": [r[1] for r in rows],
        "x": [r[2] for r in rows],
        "y": [r[3] for r in rows],
        "v": [r[4] for r in rows],
        "heading": [math.atan2(math.cos(math.radians(r[5])), math.sin(math.radians(r[5]))) for r in rows],
    }


def _csv(path: Path, cols: dict[str, list]) -> Path:
    pacsv.write_csv(pa.table(cols), path)
    return path


def test_fcd_round_trip_and_resampling(fcd):
    net = load_road().net
    rec = load_recording(fcd, net, 0.1)
    assert rec.ids == tuple(f"veh{i}" for i in range(5))
    rows = _fcd_rows(fcd)
    for vid, t, x, y, v, angle in rows:  # at SUMO's recorded steps the table is SUMO's
        tr = rec.track(vid)
        j = int(np.flatnonzero(np.isclose(tr["t"], t))[0])
        assert (tr["x"][j], tr["y"][j], tr["v"][j]) == pytest.approx((x, y, v), abs=1e-9)
        yaw = math.radians(90.0 - angle)
        assert math.remainder(tr["heading"][j] - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    tr = rec.track("veh0")
    assert np.allclose(np.diff(tr["t"]), 0.1)  # 0.5 s rows -> 0.1 s, linear in between
    assert rec.step == 0.1 and rec.interval == pytest.approx(0.5)  # and the rows' own interval is kept
    assert tr["x"][2] == pytest.approx(0.6 * tr["x"][0] + 0.4 * tr["x"][5])
    n0 = sum(1 for r in rows if r[0] == "veh0")
    assert len(tr["t"]) == (n0 - 1) * 5 + 1
    assert rec.edges[0][:2] == load_road().edges[:2]  # the lanes' edges, in the order driven


def test_the_columnar_format_is_the_same_table(fcd, tmp_path):
    net = load_road().net
    cols = _columns(fcd)
    a = load_recording(fcd, net, 0.1)
    b = load_recording(_csv(tmp_path / "rec.csv", cols), net, 0.1)
    pq.write_table(pa.table(cols), tmp_path / "rec.parquet")
    c = load_recording(tmp_path / "rec.parquet", net, 0.1)
    for other in (b, c):
        assert other.ids == a.ids and np.array_equal(other.start, a.start)
        for k in ("x", "y", "v"):
            assert np.allclose(getattr(other, k), getattr(a, k), atol=1e-9)
        assert np.allclose(np.sin(other.heading - a.heading), 0.0, atol=1e-9)
        assert other.edges == a.edges  # no lane column: the routes its positions match


def _bad(cols: dict[str, list], kind: str) -> dict[str, list]:
    cols = {k: list(v) for k, v in cols.items()}
    rows = [i for i, vid in enumerate(cols["id"]) if vid == "veh1"]
    if kind == "unsorted":
        i, j = rows[10], rows[11]
        for k in cols:
            cols[k][i], cols[k][j] = cols[k][j], cols[k][i]
    elif kind == "gap":
        for i in reversed(rows[20:26]):  # 3 s missing
            for k in cols:
                del cols[k][i]
    elif kind == "off the network":
        cols["y"][rows[30]] += 40.0
    elif kind == "km/h":
        cols["v"] = [3.6 * v if vid == "veh1" else v for v, vid in zip(cols["v"], cols["id"], strict=True)]
    elif kind == "degrees":
        cols["heading"] = [math.degrees(h) for h in cols["heading"]]
    elif kind == "no id":
        cols["id"][rows[5]] = ""  # an empty cell
    return cols


BAD = {
    "unsorted": "time must increase within each vehicle",
    "gap": "has a gap of 3.5 s",
    "off the network": "is off the network",
    "km/h": "v looks like km/h",
    "degrees": "these look like degrees",
    "no id": "has no vehicle id",
}


@pytest.mark.parametrize("kind", list(BAD))
def test_a_bad_recording_is_one_line_naming_the_row_or_vehicle(fcd, tmp_path, kind):
    path = _csv(tmp_path / "bad.csv", _bad(_columns(fcd), kind))
    with pytest.raises(IrlsimError) as e:
        load_recording(path, load_road().net, 0.1)
    msg = str(e.value)
    assert BAD[kind] in msg and str(path) in msg and "\n" not in msg, msg
    assert ("veh1" in msg) or ("row" in msg)


@pytest.mark.parametrize("column", ["t", "v", "heading"])
def test_a_column_that_is_not_numbers_is_named(fcd, tmp_path, column):
    cols = _columns(fcd)
    cols[column] = [str(x) for x in cols[column]]
    cols[column][7] = "abc"
    path = _csv(tmp_path / "text.csv", cols)
    with pytest.raises(IrlsimError) as e:
        load_recording(path, load_road().net, 0.1)
    msg = str(e.value)
    assert f"the column {column} is not numeric" in msg and str(path) in msg and "\n" not in msg, msg


def test_another_networks_recording_is_named(fcd):
    with pytest.raises(IrlsimError, match="another network's coordinates"):
        load_recording(fcd, load_road(scenario="corridor").net, 0.1)


def test_longitude_and_latitude_are_named(fcd, tmp_path):
    """SUMO's --fcd-output.geo writes longitude and latitude where x and y were: named as such."""
    text = fcd.read_text()
    geo = re.sub(
        r' x="([-\d.]+)" y="([-\d.]+)"',
        lambda m: f' x="{11 + float(m[1]) / 1e5:.7f}" y="{48 + float(m[2]) / 1e5:.7f}"',
        text,
    )
    assert geo != text
    path = tmp_path / "geo.fcd.xml"
    path.write_text(geo)
    with pytest.raises(IrlsimError) as e:
        load_recording(path, load_road().net, 0.1)
    msg = str(e.value)
    assert "longitude and latitude (as sumo --fcd-output.geo writes them)" in msg and str(path) in msg
    assert "\n" not in msg


COLLECT = """
seed = 0
workers = 1
train_episodes = 2
validation_episodes = 0
test_episodes = 0
max_cycles = 40

[planner]
n_policies = 120

[demonstrator]
kind = "recording"
"""


def _collect(tmp: Path, name: str, section: str, train: int = 2) -> tuple[int, Path]:
    cfg = tmp / f"{name}.toml"
    cfg.write_text(COLLECT.replace("train_episodes = 2", f"train_episodes = {train}") + section)
    out = tmp / name
    return main(["collect", "--config", str(cfg), "--out", str(out)]), out


@pytest.fixture(scope="module")
def collected(fcd, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("recorded")
    outs = []
    for name in ("a", "b"):
        rc, out = _collect(tmp, name, f'file = "{fcd}"\nego = "veh1,veh3"\n')
        assert rc == 0
        outs.append(out)
    return outs


def test_a_recorded_vehicle_as_ego_gives_close_demonstrations(fcd, collected):
    out = collected[0]
    rec = load_recording(fcd, load_road().net, 0.1)
    for ep, vid in enumerate(("veh1", "veh3")):
        cyc = pq.read_table(out / "train" / f"episode_{ep:05d}.cycles.parquet").to_pandas()
        has = cyc["has_demo"].to_numpy()
        assert has.sum() >= 10
        pol = pq.read_table(out / "train" / f"episode_{ep:05d}.policies.parquet").to_pandas()
        dist = pol["distance"].to_numpy().reshape(len(cyc), -1)[has]
        # the recorded odometry, projected: the nearest policy, far nearer than a typical one
        np.testing.assert_array_equal(cyc["demo_index"][has], np.argmin(dist, axis=1))
        demo = cyc["demo_distance"].to_numpy()[has]
        assert np.median(demo) < 0.5 and (demo < 0.2 * np.median(dist, axis=1)).all()
        tr = rec.track(vid)
        # from its start on the ego is where the recording has it, 0.2 s per cycle later
        first = np.flatnonzero(np.isclose(tr["x"], cyc["ego_x"][0]) & np.isclose(tr["y"], cyc["ego_y"][0]))
        assert len(first) == 1
        k = first[0] + 2 * np.arange(len(cyc))
        assert np.allclose(cyc["ego_x"], tr["x"][k]) and np.allclose(cyc["ego_y"], tr["y"][k])
        assert np.allclose(np.sin(cyc["ego_yaw"] - tr["heading"][k]), 0.0, atol=1e-6)
    man = json.loads((out / "manifest.json").read_text())
    assert man["demonstrator"]["kind"] == "recording" and man["demonstrator"]["egos"] == ["veh1", "veh3"]
    assert man["demonstrator"]["sha256"] == rec.sha256


def test_same_seed_same_bytes(collected):
    a, b = collected
    files = sorted(p.relative_to(a) for p in a.rglob("*.parquet"))
    assert files and all((a / f).read_bytes() == (b / f).read_bytes() for f in files)


def _during(t: np.ndarray, at: float) -> bool:
    return bool(t[0] - 1e-6 <= at <= t[-1] + 1e-6)


def test_the_others_replay_their_recorded_poses(fcd):
    from irlsim.data.recorded import recorded_episode
    from irlsim.planner.config import PlannerConfig
    from irlsim.sim.config import EpisodeConfig

    rec = load_recording(fcd, load_road().net, 0.1)
    planner = PlannerConfig(n_policies=50)
    driver, _, scn, sim = recorded_episode(str(fcd), load_road(), EpisodeConfig(), planner, "veh0")
    with sim:
        obs = sim.reset(0)
        t_rec = sim.t_begin
        seen: set[str] = set()
        for _ in range(90):  # vehicles enter the recording from 2 s on
            sim.execute(driver.plan(obs), n_steps=1)
            obs = sim.observe()
            t_rec += 0.1
            there = {v for v in rec.ids[1:] if _during(rec.track(v)["t"], t_rec)}
            assert set(obs.vehicles.ids) == {"rec/" + v for v in there}  # as the recording has them
            seen |= there
            for vid, x, y in zip(obs.vehicles.ids, obs.vehicles.x, obs.vehicles.y, strict=True):
                tr = rec.track(vid.removeprefix("rec/"))
                j = int(np.flatnonzero(np.isclose(tr["t"], t_rec))[0])
                assert (x, y) == pytest.approx((tr["x"][j], tr["y"][j]), abs=1e-6)
        assert len(seen) >= 3  # vehicles entered and moved with the recording


@pytest.mark.parametrize("kind", ["km/h", "another network", "ego"])
def test_the_cli_refuses_a_bad_recording_before_any_work(fcd, tmp_path, capsys, kind):
    capsys.readouterr()
    if kind == "km/h":
        section = f'file = "{_csv(tmp_path / "kmh.csv", _bad(_columns(fcd), kind))}"\n'
        needle = BAD[kind]
    elif kind == "another network":
        section, needle = f'file = "{fcd}"\n\n[scenario]\nname = "corridor"\n', "another network"
    else:
        section, needle = f'file = "{fcd}"\nego = "veh9"\n', "has no vehicle 'veh9'"
    rc, out = _collect(tmp_path, "bad", section)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and needle in err[0], err
    assert not out.exists()


def test_a_manifest_records_only_its_own_kinds_fields():
    from irlsim.data.collection import CollectConfig, data_config
    from irlsim.data.demonstrator import DemonstratorConfig

    sumo = data_config(CollectConfig(demonstrator=DemonstratorConfig(kind="sumo")))["demonstrator"]
    assert set(sumo) == {"kind", "car_follow_model", "lane_change_model", "params", "vtype_file"}  # as before
    rec = data_config(CollectConfig(demonstrator=DemonstratorConfig(kind="recording", file="r.xml")))
    # rate_window always: a recording collected before it (finite differences) is another config
    assert set(rec["demonstrator"]) == {"kind", "file", "ego", "min_duration", "rate_window"}
    with pytest.raises(IrlsimError, match="belong to kind = 'recording'"):
        DemonstratorConfig(kind="sumo", file="r.xml").validate()
    with pytest.raises(IrlsimError, match="belong to kind = 'recording'"):
        DemonstratorConfig(kind="sumo", rate_window=1.0).validate()
    with pytest.raises(IrlsimError, match="needs file"):
        DemonstratorConfig(kind="recording").validate()


def test_an_ego_off_the_scenarios_route_drives_its_own(tmp_path, capsys):
    """On the grid: a vehicle recorded on other streets than the scenario's route gets the route of its
    recorded edges; one on the scenario's route gets the scenario's road."""
    from irlsim.data.recorded import ego_track

    road = load_road(scenario="grid")
    path, _ = road.net.getShortestPath(road.net.getEdge("B3B2"), road.net.getEdge("A2A3"))
    own = [e.getID() for e in path]
    routes = (
        f'<routes><route id="own" edges="{" ".join(own)}"/><route id="main" edges="{" ".join(road.edges)}"/>'
        '<vehicle id="side" route="own" depart="0" departSpeed="max"/>'
        '<vehicle id="main" route="main" depart="0" departSpeed="max"/></routes>'
    )
    fcd = _sumo_fcd(road, routes, tmp_path / "grid.fcd.xml", 40)
    rec = load_recording(fcd, road.net, 0.1)
    side, main_ = ego_track(rec, "side", road), ego_track(rec, "main", road)
    assert not isinstance(side, str) and len(side.road.edges) >= 2  # the edges it drove in 40 s
    assert side.road.edges == rec.edges[rec.ids.index("side")] == tuple(own[: len(side.road.edges)])
    assert not isinstance(main_, str) and main_.road is road
    section = f'file = "{fcd}"\nego = "side"\nmin_duration = 10.0\n\n[scenario]\nname = "grid"\n'
    rc, out = _collect(tmp_path, "grid", section, train=1)
    assert rc == 0
    cyc = pq.read_table(out / "train" / "episode_00000.cycles.parquet").to_pandas()
    assert cyc["has_demo"].sum() > 0 and (np.abs(cyc["ego_d"]) < 3.0).all()


@pytest.fixture(scope="module")
def follower(tmp_path_factory) -> Path:
    """A recording of two cars in the oval's rightmost lane, 'follow' 60 m behind 'lead', 12.5 m/s."""
    tmp = tmp_path_factory.mktemp("follower")
    road = load_road()
    routes = (
        f'<routes><vType id="car" sigma="0" maxSpeed="12.5" lcStrategic="0" lcSpeedGain="0"/>'
        f'<route id="loop" edges="{" ".join(road.edges)}"/>'
        + "".join(
            f'<vehicle id="{v}" type="car" route="loop" depart="0" departLane="0" departPos="{pos}" '
            'departSpeed="max"/>'
            for v, pos in (("lead", 100), ("follow", 40))
        )
        + "</routes>"
    )
    return _sumo_fcd(road, routes, tmp / "two.fcd.xml", 30)


@pytest.mark.parametrize("reactive", [False, True])
def test_replayed_others_drive_through_a_standing_ego_reactive_ones_do_not(follower, reactive):
    """The recorded 'lead' is the ego and stands still at its start: replayed, 'follow' drives on as
    recorded, into it (a collision ends the episode); reactive, SUMO drives 'follow' around or behind it."""
    from irlsim.data.recorded import recorded_episode
    from irlsim.planner.config import PlannerConfig
    from irlsim.sim.config import EpisodeConfig

    _, road, _, sim = recorded_episode(
        str(follower), load_road(), EpisodeConfig(), PlannerConfig(n_policies=50), "lead", reactive=reactive
    )
    with sim:
        obs = sim.reset(0)
        for _ in range(100):
            sim.step(None)  # the ego stands where the recording starts it
            if sim.done:
                break
        obs = sim.observe()
    assert sim.stats["sim/collisions"] == (0 if reactive else 1)
    assert sim.done != reactive
    if reactive:  # it passed the ego in another lane, or waits behind it
        v = obs.vehicles
        assert v.ids == ("rec/follow",)
        other_lane = abs(v.d[0] - obs.ego.d) > 0.5 * road.lane_width
        assert other_lane or v.s[0] < obs.ego.s - 4.5


def test_reactive_replay_drives_vehicles_on_routes_matched_from_their_positions(follower, tmp_path):
    """The same recording as a CSV without the lane column: 'follow' gets its route from its positions,
    and SUMO, taking it over on that route, drives it around or behind the standing ego as with the
    recorded lanes (a wrong route would leave it unable to drive on, or send it elsewhere)."""
    from irlsim.data.recorded import recorded_episode
    from irlsim.planner.config import PlannerConfig
    from irlsim.sim.config import EpisodeConfig
    from tests.data.test_recording_routes import _csv_without_lanes

    csv = _csv_without_lanes(follower, tmp_path / "two.csv")
    _, road, _, sim = recorded_episode(
        str(csv), load_road(), EpisodeConfig(), PlannerConfig(n_policies=50), "lead", reactive=True
    )
    with sim:
        sim.reset(0)
        for _ in range(100):
            sim.step(None)
            if sim.done:
                break
        obs = sim.observe()
    assert sim.stats["sim/collisions"] == 0 and not sim.done
    v = obs.vehicles
    assert v.ids == ("rec/follow",)
    assert abs(v.d[0] - obs.ego.d) > 0.5 * road.lane_width or v.s[0] < obs.ego.s - 4.5


def test_a_reactive_vehicle_first_recorded_within_a_junction_is_driven_by_sumo_after_it(tmp_path):
    """'follow' enters the recording within a junction (its rows before that cut off): reactive, it waits
    until its pose is on one of its edges and SUMO drives it from there, as every other; replayed from its
    first pose, it would drive blind to the ego for the rest of the drive."""
    from irlsim.data.recorded import recorded_episode
    from irlsim.planner.config import PlannerConfig
    from irlsim.sim.config import EpisodeConfig
    from tests.data.test_recording_routes import _csv_without_lanes

    road = load_road()
    routes = (
        '<routes><vType id="car" sigma="0" maxSpeed="12.5"/>'
        f'<route id="loop" edges="{" ".join(road.edges)}"/>'
        '<vehicle id="lead" type="car" route="loop" depart="0" departPos="20" departSpeed="max"/>'
        '<vehicle id="follow" type="car" route="loop" depart="0" departPos="60" departSpeed="max"/></routes>'
    )
    fcd = _sumo_fcd(road, routes, tmp_path / "two.fcd.xml", 50)
    inside = [  # the times 'follow' is within a junction
        float(ts.get("time"))
        for ts in ET.parse(fcd).getroot().iter("timestep")
        for v in ts.iter("vehicle")
        if v.get("id") == "follow" and v.get("lane").startswith(":")
    ]
    assert inside, "the recording's 'follow' crosses no junction: the test needs one"
    csv = _csv_without_lanes(fcd, tmp_path / "two.csv")
    table = pacsv.read_csv(csv, convert_options=pacsv.ConvertOptions(column_types={"id": pa.string()}))
    late = pc.and_(pc.equal(table["id"], "follow"), pc.less(table["t"], inside[0]))
    pacsv.write_csv(table.filter(pc.invert(late)), csv)
    _, _, _, sim = recorded_episode(
        str(csv), road, EpisodeConfig(), PlannerConfig(n_policies=50), "lead", reactive=True
    )
    with sim:
        sim.reset(0)
        waited = False
        while (t := sim._api.simulation.getTime()) < inside[0] + 5.0 and not sim.done:
            waited |= t > inside[0] and "rec/follow" not in sim._api.vehicle.getIDList()
            sim.step(None)
        assert "rec/follow" in sim._driven and sim._api.vehicle.getSpeedMode("rec/follow") != 0
    assert waited  # it was not placed within the junction


@pytest.mark.parametrize("reactive", [False, True])
def test_closed_loop_on_a_recording(fcd, tmp_path, capsys, reactive):
    cfg = tmp_path / "rec.toml"
    cfg.write_text(COLLECT + f'file = "{fcd}"\n')
    out = tmp_path / "drive"
    args = ["drive", "--model", "expert", "--config", str(cfg), "--episodes", "2", "--max-cycles", "20"]
    rc = main([*args, "--frames", "0", "--out", str(out), *(["--reactive"] if reactive else [])])
    assert rc == 0
    drive = json.loads((out / "drive.json").read_text())
    assert drive["config"]["recording"] == {"file": str(fcd), "egos": ["veh0", "veh1"], "reactive": reactive}
    # each episode on its ego's recording; the replayed others do not yield, so the expert may hit one
    assert [e["drive/seed"] for e in drive["episodes"]] == [100, 101]
    assert all(e["drive/end_reason"] in ("max_cycles", "collision") for e in drive["episodes"])


def test_reactive_needs_a_recording(tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "drive"
    rc = main(["drive", "--model", "expert", "--reactive", "--max-cycles", "5", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--reactive drives a recording's vehicles" in err[0], err
    assert not out.exists()


def test_a_recordings_drive_refuses_the_cars_a_reward_learned_from_not_their_seeds(fcd, tmp_path, capsys):
    """A recording's episode is its ego: the seeds its training episodes had (0 and 1 here) say nothing of
    which cars a reward learned from, so a drive of other cars with those seeds runs; a drive of a car an
    episode of its data drove (the validation episode's veh2) is refused in one line, before any work."""
    section = f'file = "{fcd}"\nego = "veh0,veh1,veh2"\n'
    cfg = tmp_path / "learn.toml"
    cfg.write_text(COLLECT.replace("validation_episodes = 0", "validation_episodes = 1") + section)
    data, runs = tmp_path / "data", tmp_path / "runs"
    assert main(["collect", "--config", str(cfg), "--out", str(data)]) == 0
    assert json.loads((data / "manifest.json").read_text())["seeds"]["train"] == [0, 1]  # the drive's seeds
    train = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml", "--data", str(data)]
    assert main([*train, "--set", 'models=["PACNN+S"]', "--out", str(runs)]) == 0
    drive_cfg = tmp_path / "drive.toml"
    drive_cfg.write_text(COLLECT + f'file = "{fcd}"\nego = "veh3,veh4"\n')
    args = ["drive", "--runs", str(runs), "--model", "PACNN+S", "--config", str(drive_cfg), "--seed", "0"]
    capsys.readouterr()
    rc = main([*args, "--episodes", "2", "--max-cycles", "10", "--frames", "0", "--out", str(tmp_path / "d")])
    said = capsys.readouterr()
    assert rc == 0, said.err
    drive_cfg.write_text(COLLECT + f'file = "{fcd}"\nego = "veh3,veh2"\n')
    rc = main([*args, "--episodes", "2", "--max-cycles", "10", "--frames", "0", "--out", str(tmp_path / "e")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert err[0].endswith(
        "car(s) veh2 are egos of the data PACNN+S was trained on (3 cars of this recording): "
        "drive cars it did not learn from (demonstrator.ego)"
    ), err
    assert not (tmp_path / "e").exists()
