"""A recording without lanes: each vehicle's route comes from its positions (map matching onto the
network's edges), with real SUMO: vehicles that turn through the generated city grid, recorded by SUMO
itself (--fcd-output), give the same routes from a CSV of positions alone as from SUMO's recorded lanes,
and can be egos on them; positions that match no connected route are one line naming the vehicle."""

from __future__ import annotations

import math
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pytest

from irlsim.data.recorded import egos
from irlsim.data.recording import load_recording
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import sumo_binary

#: routes through the grid that turn off and onto the scenario's route (C0C1 C1C2 C2C3 C3C4)
ROUTES = {
    "right-left": "C0C1 C1D1 D1D2 D2D3",
    "onto": "B0B1 B1C1 C1C2 C2C3",
    "straight": "C0C1 C1C2 C2C3 C3C4",
    "across": "D4D3 D3C3 C3B3 B3A3",
}


@pytest.fixture(scope="module")
def grid_fcd(tmp_path_factory) -> Path:
    """Four vehicles on the grid for 70 s, each on its own route, recorded by SUMO every 0.2 s."""
    tmp = tmp_path_factory.mktemp("grid")
    road = load_road(scenario="grid")
    cars = "".join(
        f'<vehicle id="{vid}" type="car" depart="{i}" departSpeed="max"><route edges="{edges}"/></vehicle>'
        for i, (vid, edges) in enumerate(ROUTES.items())
    )
    routes = tmp / "cars.rou.xml"
    routes.write_text(f'<routes><vType id="car" sigma="0"/>{cars}</routes>')
    out = tmp / "fcd.xml"
    cmd = [sumo_binary("sumo"), "-n", str(road.net_file), "-r", str(routes), "--end", "70"]
    cmd += ["--step-length", "0.2", "--fcd-output", str(out), "--no-step-log", "true", "--seed", "1"]
    subprocess.run(cmd, check=True, capture_output=True)
    return out


def _csv_without_lanes(fcd: Path, path: Path) -> Path:
    """SUMO's FCD as the columnar format, the lane column left out."""
    cols: dict[str, list] = {k: [] for k in ("id", "t", "x", "y", "v", "heading")}
    for ts in ET.parse(fcd).getroot().iter("timestep"):
        for v in ts.iter("vehicle"):
            cols["id"].append(v.get("id"))
            cols["t"].append(float(ts.get("time")))
            cols["x"].append(float(v.get("x")))
            cols["y"].append(float(v.get("y")))
            cols["v"].append(float(v.get("speed")))
            cols["heading"].append(math.remainder(math.radians(90.0 - float(v.get("angle"))), 2 * math.pi))
    pacsv.write_csv(pa.table(cols), path)
    return path


def test_routes_from_positions_are_the_recorded_lanes_routes(grid_fcd, tmp_path):
    road = load_road(scenario="grid")
    with_lanes = load_recording(grid_fcd, road.net, 0.1)
    without = load_recording(_csv_without_lanes(grid_fcd, tmp_path / "rec.csv"), road.net, 0.1)
    assert without.ids == with_lanes.ids == tuple(sorted(ROUTES))
    assert without.edges == with_lanes.edges
    for vid, edges in zip(without.ids, without.edges, strict=True):
        assert edges == tuple(ROUTES[vid].split()[: len(edges)]) and len(edges) >= 3, vid  # turns too
    assert without.unrouted == ("",) * 4
    # and they drive on them: every vehicle is an ego on its own route, as with the lanes
    assert egos(without, road, (), 20.0) == egos(with_lanes, road, (), 20.0) == list(without.ids)


def test_positions_that_match_no_connected_route_are_one_line(grid_fcd, tmp_path):
    road = load_road(scenario="grid")
    path = _csv_without_lanes(grid_fcd, tmp_path / "rec.csv")
    table = pacsv.read_csv(path, convert_options=pacsv.ConvertOptions(column_types={"id": pa.string()}))
    cols = table.to_pydict()
    # for its last 12 s 'straight' jumps back from C2C3 to where 'onto' drives, C1C2: no route drives
    # there in the time (a loop round a block)
    rows = np.flatnonzero(np.array(cols["id"]) == "straight")
    onto = np.flatnonzero(np.array(cols["id"]) == "onto")
    for r, s in zip(rows[-60:], onto[-60:], strict=True):
        for k in ("x", "y", "heading"):
            cols[k][r] = cols[k][s]
    pacsv.write_csv(pa.table(cols), path)
    rec = load_recording(path, road.net, 0.1)
    k = rec.ids.index("straight")
    assert rec.edges[k] == () and "only over" in rec.unrouted[k]
    with pytest.raises(IrlsimError) as e:
        egos(rec, road, ("straight",), 20.0)
    msg = str(e.value)
    assert "vehicle straight cannot be an ego: it drove no connected route" in msg
    assert "\n" not in msg and str(path) in msg


def test_reactive_replay_drives_each_vehicle_on_its_matched_route(grid_fcd, tmp_path):
    """Reactive, SUMO takes the other recorded vehicles over on the routes matched from their positions
    (the CSV has no lane column): each one SUMO drives has its own route through the grid, turns included,
    not the scenario's."""
    from irlsim.data.recorded import recorded_episode
    from irlsim.planner.config import PlannerConfig
    from irlsim.sim.config import EpisodeConfig

    road = load_road(scenario="grid")
    csv = _csv_without_lanes(grid_fcd, tmp_path / "rec.csv")
    _, _, _, sim = recorded_episode(
        str(csv), road, EpisodeConfig(name="grid"), PlannerConfig(n_policies=50), "straight", reactive=True
    )
    seen: dict[str, tuple[str, ...]] = {}
    with sim:
        sim.reset(0)
        for _ in range(40):
            api = sim._api.vehicle
            for vid in api.getIDList():
                if vid.startswith("rec/") and vid not in seen:
                    seen[vid] = tuple(api.getRoute(vid))
            sim.step(None)
            if sim.done:
                break
    others = {vid.removeprefix("rec/"): r for vid, r in seen.items()}
    assert set(others) >= {"right-left", "across"}
    for vid, route in others.items():
        full = tuple(ROUTES[vid].split())  # what it drove, of which the recording holds a stretch
        starts = [k for k in range(len(full)) if full[k : k + len(route)] == route]
        assert starts and len(route) >= 2, (vid, route)
