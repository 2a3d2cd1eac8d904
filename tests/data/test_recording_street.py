"""A recording on a city street, with real netconvert and real SUMO: two lanes for cars beside a bicycle
lane and a sidewalk, and an edge half a metre long between two junctions, which SUMO's FCD at 1 s records
no car on (as OpenStreetMap networks have such edges). A car's route is connected all the same, the edge
filled in, from its recorded lanes as from its positions alone; a bicycle on its lane is no car: no ego,
and replayed on its own lane while SUMO drives the cars in a reactive replay; roads on one network share
the network, read once; a replayed vehicle is never put on a pedestrians' lane; and a dense recording
collects the same bytes in the command's process as in workers."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data.recorded import egos, recorded_episode
from irlsim.data.recording import load_recording
from irlsim.errors import IrlsimError
from irlsim.planner.config import PlannerConfig
from irlsim.road import Road, load_road
from irlsim.road.network import sumo_binary
from irlsim.sim.config import EpisodeConfig
from tests.data.test_recording_routes import _csv_without_lanes

ROUTE = ("ab", "bc", "cd")
LANES = 'numLanes="2" speed="20" sidewalkWidth="2" bikeLaneWidth="1.5"'


def _street(tmp: Path, *options: str) -> Path:
    """The street's network and its scenario file in ``tmp`` (netconvert's ``options`` added); the
    network's path."""
    nodes = {"a": 0.0, "b": 300.0, "c": 300.5, "d": 600.0}
    (tmp / "n.nod.xml").write_text(
        "<nodes>" + "".join(f'<node id="{k}" x="{x}" y="0"/>' for k, x in nodes.items()) + "</nodes>"
    )
    (tmp / "n.edg.xml").write_text(
        "<edges>" + "".join(f'<edge id="{e}" from="{e[0]}" to="{e[1]}" {LANES}/>' for e in ROUTE) + "</edges>"
    )
    net = tmp / "street.net.xml"
    cmd = [sumo_binary("netconvert"), "-n", str(tmp / "n.nod.xml"), "-e", str(tmp / "n.edg.xml")]
    subprocess.run([*cmd, "-o", str(net), "--no-turnarounds", *options], check=True, capture_output=True)
    route = ", ".join(f'"{e}"' for e in ROUTE)
    (tmp / "scenario.toml").write_text(
        f'name = "street"\n[network]\nfile = "{net.name}"\n[route]\nedges = [{route}]\n'
    )
    return net


def _record(tmp: Path, net: Path, vehicles: str, step: str, end: str, *options: str) -> Path:
    """SUMO's FCD of ``vehicles`` (route XML) on the street, every ``step`` seconds (SUMO's ``options``
    added)."""
    (tmp / "r.rou.xml").write_text(f'<routes><vType id="car" sigma="0"/>{vehicles}</routes>')
    fcd = tmp / "fcd.xml"
    cmd = [sumo_binary("sumo"), "-n", str(net), "-r", str(tmp / "r.rou.xml"), "--step-length", step]
    subprocess.run(
        [*cmd, "--end", end, "--fcd-output", str(fcd), "--no-step-log", "true", *options],
        check=True,
        capture_output=True,
    )
    return fcd


def _plain_net(
    tmp: Path, name: str, nodes: dict[str, tuple[float, float]], edges: dict[str, str], *options: str
) -> Path:
    """A netconvert network ``tmp/<name>.net.xml`` of ``nodes`` (id: x, y; a node named in ``options`` as
    ``lights=a,b`` is a traffic light) and ``edges`` (id "uv" from u to v: its attributes)."""
    lights = next((o.removeprefix("lights=").split(",") for o in options if o.startswith("lights=")), [])
    rest = [o for o in options if not o.startswith("lights=")]
    tl = {k: ' type="traffic_light"' if k in lights else "" for k in nodes}
    (tmp / "n.nod.xml").write_text(
        "<nodes>"
        + "".join(f'<node id="{k}" x="{x}" y="{y}"{tl[k]}/>' for k, (x, y) in nodes.items())
        + "</nodes>"
    )
    (tmp / "n.edg.xml").write_text(
        "<edges>"
        + "".join(f'<edge id="{e}" from="{e[0]}" to="{e[1]}" {a}/>' for e, a in edges.items())
        + "</edges>"
    )
    net = tmp / f"{name}.net.xml"
    cmd = [sumo_binary("netconvert"), "-n", str(tmp / "n.nod.xml"), "-e", str(tmp / "n.edg.xml")]
    subprocess.run([*cmd, "-o", str(net), *rest], check=True, capture_output=True)
    return net


def _lanes_of(sim, vid: str, steps: int) -> tuple[set[str], set[str]]:
    """The lanes SUMO has ``vid`` on over ``steps`` steps of ``sim`` from its reset; the vehicles SUMO
    drove (a reactive replay's)."""
    lanes: set[str] = set()
    with sim:
        sim.reset(0)
        for _ in range(steps):
            if vid in sim._api.vehicle.getIDList():
                lanes.add(sim._api.vehicle.getLaneID(vid))
            sim.step(None)
        return lanes, set(sim._driven)


@pytest.fixture(scope="module")
def street(tmp_path_factory) -> tuple[Path, Path]:
    """(the scenario's folder, SUMO's FCD of two cars and a bicycle along the street, every 1 s)."""
    tmp = tmp_path_factory.mktemp("street")
    net = _street(tmp)
    edges = " ".join(ROUTE)
    vehicles = (
        '<vType id="bike" vClass="bicycle" sigma="0"/>'
        f'<vehicle id="car0" type="car" depart="0" departSpeed="max"><route edges="{edges}"/></vehicle>'
        f'<vehicle id="bike" type="bike" depart="1" departSpeed="max"><route edges="{edges}"/></vehicle>'
        f'<vehicle id="car1" type="car" depart="5" departSpeed="max"><route edges="{edges}"/></vehicle>'
    )
    fcd = _record(tmp, net, vehicles, "1", "80")
    return tmp, fcd


def test_a_route_crosses_the_edge_the_recording_skips(street, tmp_path):
    folder, fcd = street
    road = load_road(scenario=folder)
    text = fcd.read_text()
    assert 'lane="ab_' in text and 'lane="cd_' in text and 'lane="bc_' not in text  # SUMO skipped it
    with_lanes = load_recording(fcd, road.net, 0.1)
    without = load_recording(_csv_without_lanes(fcd, tmp_path / "rec.csv"), road.net, 0.1)
    for rec in (with_lanes, without):
        for car in ("car0", "car1"):
            k = rec.ids.index(car)
            assert rec.edges[k] == ROUTE and rec.unrouted[k] == "", (rec.path, car)


def test_a_bicycle_on_its_lane_is_no_ego_and_is_replayed_on_it(street):
    folder, fcd = street
    road = load_road(scenario=folder)
    rec = load_recording(fcd, road.net, 0.1)
    bike = rec.ids.index("bike")
    assert rec.edges[bike] == () and "which a passenger car may not use" in rec.unrouted[bike]
    refused: dict[str, int] = {}
    assert egos(rec, road, (), 10.0, refused) == ["car0", "car1"]
    assert refused == {"on lanes a car may not use": 1}  # what collect prints of the vehicles not taken
    with pytest.raises(IrlsimError) as e:
        egos(rec, road, ("bike",), 10.0)
    msg = str(e.value)
    assert "vehicle bike cannot be an ego: it drove on lane ab_1, which a passenger car may not use" in msg
    assert "\n" not in msg
    # reactive: SUMO drives the car ahead; the bicycle is replayed, on its bicycle lane (not the car lane
    # beside it, where the car SUMO drives would queue behind it)
    _, _, _, sim = recorded_episode(
        str(fcd), road, EpisodeConfig(name="street"), PlannerConfig(n_policies=50), "car1", reactive=True
    )
    lanes, driven = _lanes_of(sim, "rec/bike", 30)
    assert driven == {"rec/car0"}
    assert lanes and {ln.split("_")[0] for ln in lanes} <= {"ab", "bc", "cd"}
    assert {ln.rsplit("_", 1)[1] for ln in lanes} == {"1"}  # lane 0 is the sidewalk, 1 the bicycles'


def test_roads_on_one_network_share_it_until_it_changes(street):
    folder, _ = street
    net = folder / "street.net.xml"
    first, second = Road(net, ROUTE), Road(net, ROUTE[:2])
    assert first.net is second.net
    st = net.stat()
    os.utime(net, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
    assert Road(net, ROUTE).net is not first.net


def test_dense_traffic_collects_the_same_bytes_in_this_process_and_in_workers(tmp_path):
    """80 recorded cars around the ego: products over them large enough for numpy's BLAS to split over
    threads, which rounds otherwise than one thread; the irlsim command keeps BLAS on one thread, so
    --workers 1 (in its process) writes a worker's bytes."""
    net = _street(tmp_path)
    cars = "".join(
        f'<vehicle id="c{i}" type="car" depart="{i // 2}" departLane="{2 + i % 2}" departSpeed="max">'
        f'<route edges="{" ".join(ROUTE)}"/></vehicle>'
        for i in range(80)
    )
    fcd = _record(tmp_path, net, cars, "0.5", "60")
    config = tmp_path / "collect.toml"
    config.write_text(
        "seed = 0\ntrain_episodes = 2\nvalidation_episodes = 0\ntest_episodes = 0\nmax_cycles = 30\n"
        f'[planner]\nn_policies = 500\n[demonstrator]\nkind = "recording"\nfile = "{fcd}"\nego = "c30,c31"\n'
    )
    env = {k: v for k, v in os.environ.items() if k not in {"OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"}}
    for workers in (1, 2):
        cmd = [sys.executable, "-m", "irlsim.cli", "collect", "--config", str(config), "--scenario"]
        cmd += [str(tmp_path), "--workers", str(workers), "--out", str(tmp_path / f"w{workers}")]
        subprocess.run(cmd, check=True, capture_output=True, env=env)
    files = sorted(p.relative_to(tmp_path / "w1") for p in (tmp_path / "w1").rglob("*.parquet"))
    assert len(files) == 4
    for f in files:
        assert (tmp_path / "w1" / f).read_bytes() == (tmp_path / "w2" / f).read_bytes(), f


def test_a_replayed_vehicle_is_never_put_on_a_pedestrians_lane(tmp_path):
    """A bicycle recorded standing where the sidewalks of two junctions meet (0.5 m apart; the street with
    walking areas) is replayed on a lane a vehicle may use: a replayed vehicle SUMO had put on a walking
    area (its class 'ignoring' may use every lane) crashed SUMO when its noisy pose stood at a junction."""
    net = _street(tmp_path, "--walkingareas")
    edges = " ".join(ROUTE)
    vehicles = (
        '<vType id="bike" vClass="bicycle" sigma="0"/>'
        f'<vehicle id="car0" type="car" depart="0" departSpeed="max"><route edges="{edges}"/></vehicle>'
        f'<vehicle id="bike" type="bike" depart="1" departSpeed="max"><route edges="{edges}"/></vehicle>'
    )
    rows = pacsv.read_csv(_csv_without_lanes(_record(tmp_path, net, vehicles, "1", "40"), tmp_path / "r.csv"))
    cols = rows.to_pydict()
    for i, vid in enumerate(cols["id"]):
        if vid == "bike":  # standing between the junctions' walking areas, on the sidewalk's line
            cols["x"][i], cols["y"][i], cols["v"][i] = 300.25, -8.9, 0.0
    rec = tmp_path / "standing.csv"
    pacsv.write_csv(pa.table(cols), rec)
    road = load_road(scenario=tmp_path)
    pedestrians = {lane.getID() for edge in road.net.getEdges(withInternal=True) for lane in edge.getLanes()}
    pedestrians = {
        ln
        for ln in pedestrians
        if road.net.getLane(ln).allows("pedestrian") and not road.net.getLane(ln).allows("bicycle")
    }
    _, _, _, sim = recorded_episode(
        str(rec), road, EpisodeConfig(name="street"), PlannerConfig(n_policies=50), "car0"
    )
    lanes, _ = _lanes_of(sim, "rec/bike", 20)
    assert lanes and not lanes & pedestrians, lanes


def test_a_recorded_ego_may_start_in_any_lane_of_a_wide_road(tmp_path):
    """A car recorded in the fifth lane of a five-lane road is an ego from there (the start lane had been
    held to the oval's three, and such an ego's episode failed on every retry)."""
    net = _plain_net(tmp_path, "wide", {"a": (0, 0), "b": (800, 0)}, {"ab": 'numLanes="5" speed="20"'})
    (tmp_path / "scenario.toml").write_text(
        f'name = "wide"\n[network]\nfile = "{net.name}"\n[route]\nedges = ["ab"]\n'
    )
    vehicles = '<vehicle id="left" type="car" depart="0" departLane="4" departSpeed="max">'
    vehicles += '<route edges="ab"/></vehicle>'
    fcd = _record(tmp_path, net, vehicles, "0.5", "30")
    config = tmp_path / "collect.toml"
    config.write_text(
        "seed = 0\ntrain_episodes = 1\nvalidation_episodes = 0\ntest_episodes = 0\nmax_cycles = 20\n"
        f'[planner]\nn_policies = 100\n[demonstrator]\nkind = "recording"\nfile = "{fcd}"\nego = "left"\n'
    )
    out = tmp_path / "data"
    assert main(["collect", "--config", str(config), "--scenario", str(tmp_path), "--out", str(out)]) == 0
    cycles = pq.read_table(out / "train" / "episode_00000.cycles.parquet", columns=["ego_lane"])
    assert set(cycles.column("ego_lane").to_pylist()) == {4}


def _program_state(net: Path, tls: str, t: float) -> str:
    """The state a static traffic light program of ``net`` shows at SUMO time ``t`` (offset 0), from its
    phases' durations: the closed form SUMO runs by."""
    logic = next(e for e in ET.parse(net).getroot().iter("tlLogic") if e.get("id") == tls)
    phases = [(float(p.get("duration")), p.get("state")) for p in logic.iter("phase")]
    at = (t - float(logic.get("offset", "0"))) % sum(d for d, _ in phases)
    for duration, state in phases:
        if at < duration - 1e-9:
            return state
        at -= duration
    return phases[-1][1]


#: a signal program of the crossing's other than netconvert's, as a SUMO configuration's additional file
#: gives one (the replay must run it, not the network's own)
PROGRAM = (
    '<additional><tlLogic id="b" type="static" programID="recorded" offset="0">'
    '<phase duration="7" state="GGrr"/><phase duration="2" state="yyrr"/>'
    '<phase duration="11" state="rrGG"/><phase duration="2" state="rryy"/></tlLogic></additional>'
)


@pytest.mark.parametrize("program", ["the network's", "the scenario's additional file"])
def test_a_replay_runs_the_lights_by_the_recordings_clock(tmp_path, program):
    """A car recorded from t = 50 s through a signalised crossing: in its replay SUMO's clock is the
    recording's, so the light shows at every step what its program shows at that recorded time (the
    replay had begun at 0 s, the lights 50 s off what the recorded drivers saw); with the program the
    recording ran from an additional file, named by the scenario's [network] additional, the replay runs
    that program, also for a car whose route is its own (d to e, not the scenario's)."""
    nodes = {"a": (0, 0), "b": (200, 0), "c": (400, 0), "d": (200, 200), "e": (200, -200)}
    edges = {e: 'numLanes="1" speed="14"' for e in ("ab", "bc", "db", "be")}
    net = _plain_net(tmp_path, "x", nodes, edges, "lights=b", "--no-turnarounds")
    own = program != "the network's"
    scenario = f'name = "cross"\n[network]\nfile = "{net.name}"\n'
    options: tuple[str, ...] = ()
    if own:
        (tmp_path / "lights.add.xml").write_text(PROGRAM)
        scenario += 'additional = ["lights.add.xml"]\n'
        options = ("--additional-files", str(tmp_path / "lights.add.xml"))
    (tmp_path / "scenario.toml").write_text(scenario + '[route]\nedges = ["ab", "bc"]\n')
    route = "db be" if own else "ab bc"
    vehicles = (
        f'<vehicle id="car" type="car" depart="50" departSpeed="max"><route edges="{route}"/></vehicle>'
    )
    fcd = _record(tmp_path, net, vehicles, "0.5", "120", *options)
    road = load_road(scenario=tmp_path)
    _, ego_road, _, sim = recorded_episode(
        str(fcd), road, EpisodeConfig(name="cross"), PlannerConfig(n_policies=50), "car"
    )
    assert ego_road.edges == tuple(route.split())
    source = tmp_path / "lights.add.xml" if own else net
    seen, expected = [], []
    with sim:
        sim.reset(0)
        for _ in range(400):  # to 90 s: the network's program changes at 87 s and 90 s
            t = float(sim._api.simulation.getTime())
            seen.append(sim._api.trafficlight.getRedYellowGreenState("b"))
            expected.append(_program_state(source, "b", t - 0.05))  # a switch at T shows after the step to T
            sim.step(None)
        assert abs(sim.ego.t - (50.0 + 400 * 0.1)) < 1e-6  # the ego's clock: the recording's
    assert seen == expected and len(set(seen)) > 1


def test_a_car_is_held_by_its_own_lanes_signal(tmp_path):
    """Three lanes into a signalised junction, only the rightmost one's signal green (a program of the
    scenario's additional file): a car recorded through it on that lane crossed on green, not on the red
    of the route's middle lane, which had been read for every lane."""
    nodes = {"a": (0, 0), "b": (300, 0), "c": (600, 0)}
    edges = {e: 'numLanes="3" speed="14"' for e in ("ab", "bc")}
    net = _plain_net(tmp_path, "x", nodes, edges, "lights=b", "--no-turnarounds")
    links = {
        int(c.get("fromLane")): int(c.get("linkIndex"))
        for c in ET.parse(net).getroot().iter("connection")
        if c.get("from") == "ab" and c.get("tl") == "b"
    }
    state = "".join("G" if i == links[0] else "r" for i in range(len(links)))
    (tmp_path / "lights.add.xml").write_text(
        '<additional><tlLogic id="b" type="static" programID="one" offset="0">'
        f'<phase duration="1000" state="{state}"/></tlLogic></additional>'
    )
    (tmp_path / "scenario.toml").write_text(
        f'name = "three"\n[network]\nfile = "{net.name}"\nadditional = ["lights.add.xml"]\n'
        '[route]\nedges = ["ab", "bc"]\n'
    )
    vehicles = '<vehicle id="car" type="car" depart="0" departLane="0" departSpeed="max">'
    vehicles += '<route edges="ab bc"/></vehicle>'
    fcd = _record(
        tmp_path, net, vehicles, "0.5", "60", "--additional-files", str(tmp_path / "lights.add.xml")
    )
    road = load_road(scenario=tmp_path)
    assert [g.link_of(0) for g in road.signals] == [links[0]] != [g.link for g in road.signals]
    driver, _, _, sim = recorded_episode(
        str(fcd), road, EpisodeConfig(name="three"), PlannerConfig(n_policies=50), "car"
    )
    with sim:
        obs = sim.reset(0)
        while not sim.done:
            sim.execute(driver.plan(obs), 2)
            obs = sim.observe()
        counts = sim.episode.counts
    assert counts["signals_passed"] == 1 and counts.get("red_crossings", 0) == 0, counts
