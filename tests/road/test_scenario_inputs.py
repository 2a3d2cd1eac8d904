"""Every input of a scenario checked against what it names, when the road is built: checkpoints against
the road (the point on it, the lane there), route edges against the network, a compressed network that
is whole gzip. Each refusal is one line naming the file, and the CLI exits 2."""

from __future__ import annotations

import gzip
import math
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from irlsim.cli import main
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.geometry import CHECKPOINT_MARGIN
from irlsim.road.scenario import load_scenario

OVAL = load_scenario("oval", build=False)


def scenario(folder: Path, network: str, edges: tuple[str, ...], checkpoints=()) -> Path:
    """A scenario folder: ``network`` is the [network] line, the route ``edges``, checkpoints (x, y, lane)."""
    folder.mkdir(parents=True, exist_ok=True)
    cps = "".join(f"\n[[checkpoints]]\nx = {x!r}\ny = {y!r}\nlane = {lane}\n" for x, y, lane in checkpoints)
    route = ", ".join(f'"{e}"' for e in edges)
    (folder / "scenario.toml").write_text(
        textwrap.dedent(f"""\
        [network]
        {network}

        [route]
        edges = [{route}]
        """)
        + cps
    )
    return folder


def oval_with(tmp_path: Path, road, checkpoints, edges: tuple[str, ...] = OVAL.edges) -> Path:
    """The oval's route on its network (named by its absolute path) with other checkpoints."""
    return scenario(tmp_path / "oval_cp", f'file = "{road.net_file}"', edges, checkpoints)


RAMP = ("gneE2", "offramp", "gneE3", "gneE7", "gneE8", "gneE11")


def ramp_with(tmp_path: Path, checkpoints) -> Path:
    return scenario(tmp_path / "ramp_cp", 'sumo_tools = "game/ramp/ramp.net.xml"', RAMP, checkpoints)


def refusal(folder: Path, capsys) -> str:
    """The one line that loading ``folder`` is refused with, and the same line from the CLI (exit 2)."""
    with pytest.raises(IrlsimError) as e:
        load_road(scenario=folder)
    msg = str(e.value)
    assert "\n" not in msg and str(folder / "scenario.toml") in msg
    capsys.readouterr()
    assert main(["scenario", "show", str(folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"irlsim: error: {msg}"
    return msg


@pytest.mark.parametrize(
    "checkpoints, says",
    [
        ([(250.0, 0.0, -2)], "checkpoint 0 (x=250, y=0) has lane -2: give a lane >= 0"),
        ([(math.nan, 0.0, 2)], "must be a finite number, got nan"),
        ([(250.0, 20.0, 2)], "checkpoint 0 (x=250, y=20) lies 15.2 m beyond the road's edge (more than 1 m"),
        ([(250.0, 0.0, 2), (850.0, 150.0, 3)], "checkpoint 1 (x=850, y=150) requires lane 3, but the route "
         "has lanes 0..2 there: give one of them or -1 (any lane)"),
    ],
)  # fmt: skip
def test_a_checkpoint_off_the_oval_or_in_no_lane_is_one_line(tmp_path, road, capsys, checkpoints, says):
    assert says in refusal(oval_with(tmp_path, road, checkpoints), capsys)


def test_checkpoints_on_the_road_load_where_the_file_puts_them(tmp_path, road):
    """Within the margin beyond the edge (4.8 m + 1 m) and any lane: accepted, at the file's points."""
    cps = [(250.0, -5.7, 0), (850.0, 150.0, -1), (450.0, 300.0, 1)]
    other = load_road(scenario=oval_with(tmp_path, road, cps))
    assert [(c.x, c.y, c.lane) for c in other.checkpoints] == cps
    assert other.ref_xy.tobytes() == road.ref_xy.tobytes()


def test_ramp_checkpoints_meet_the_lanes_that_exist_and_the_route_s_ends(tmp_path, capsys):
    ramp = load_road(scenario="ramp")
    x, y = ramp.to_xy(np.array([ramp.route_end_s - 5.0, ramp.route_end_s + 50.0]), np.zeros(2))
    assert ramp.lane_bounds(np.array([ramp.route_end_s - 5.0]))[0][0] == 1  # lane 0 has ended there
    msg = refusal(ramp_with(tmp_path, [(float(x[0]), float(y[0]), 0)]), capsys)
    assert "requires lane 0, but the route has lanes 1..2 there" in msg
    msg = refusal(ramp_with(tmp_path, [(float(x[1]), float(y[1]), -1)]), capsys)
    assert "lies 50.0 m beyond the route's end (more than 1 m): move it onto the route" in msg
    ok = load_road(scenario=ramp_with(tmp_path, [(float(x[0]), float(y[0]), 1)]))
    assert [c.lane for c in ok.checkpoints] == [1]


def test_a_route_edge_the_network_lacks_is_one_line_naming_both_files(tmp_path, road, capsys):
    folder = oval_with(tmp_path, road, [], edges=("A_S1", "nope"))
    msg = refusal(folder, capsys)
    assert f"route edge 'nope' is not in the network {road.net_file}: fix [route]" in msg
    grid = load_road(scenario="grid").net_file
    with pytest.raises(IrlsimError) as e:  # the oval's route (its scenario file) on another network
        load_road(net_file=grid)
    assert str(e.value) == (
        f"scenario {OVAL.path}: route edge 'A_S1' is not in the network {grid}: fix [route] or give the "
        "network the route was written for"
    )


@pytest.mark.parametrize("damage", ["truncated", "not gzip"])
def test_a_compressed_network_that_is_not_whole_gzip_is_one_line(tmp_path, road, capsys, damage):
    folder = tmp_path / "gz"
    folder.mkdir()
    data = road.net_file.read_bytes()
    packed = gzip.compress(data)
    (folder / "oval.net.xml.gz").write_bytes(packed[: len(packed) // 2] if damage == "truncated" else data)
    scenario(folder, 'file = "oval.net.xml.gz"', OVAL.edges)
    msg = refusal(folder, capsys)
    assert f"network {folder / 'oval.net.xml.gz'} is malformed: not a whole gzip file" in msg
    assert sorted(p.name for p in folder.iterdir()) == ["oval.net.xml.gz", "scenario.toml"]  # nothing cached
    (folder / "oval.net.xml.gz").write_bytes(packed)  # whole: the oval
    assert load_road(scenario=folder).ref_xy.tobytes() == road.ref_xy.tobytes()


def _expected(road, x: float, y: float, lane: int) -> bool | None:
    """Closed form on the road's own arrays: the nearest of all reference segments (an open route's
    closing chord left out), its signed offset, the lanes of that segment and the route's ends. None
    within 5 cm of a bound or 1 m of a change of lanes, where the library's smooth projection may
    differ from the nearest segment's by a few millimetres."""
    a = road.ref_xy
    m = len(a) if road.closed else len(a) - 1
    b = np.roll(a, -1, axis=0)[:m]
    u = b - a[:m]
    ln = np.linalg.norm(u, axis=1)
    u = u / ln[:, None]
    q = np.array([x, y]) - a[:m]
    t = np.clip((q * u).sum(1), 0.0, ln)
    dist = np.linalg.norm(q - u * t[:, None], axis=1)
    j = int(np.argmin(dist))
    s = road.ref_s[j] + t[j]
    d = math.copysign(dist[j], u[j, 0] * q[j, 1] - u[j, 1] * q[j, 0])
    near = np.arange(j - 2, j + 3) % len(a)
    lo, hi = road._lane_lo[near], road._lane_hi[near]
    if (lo != lo[2]).any() or (hi != hi[2]).any():
        return None
    w, n = road.lane_width, road.n_lanes
    right = (lo[2] - (n - 1) / 2) * w - w / 2 - CHECKPOINT_MARGIN
    left = (hi[2] - (n - 1) / 2) * w + w / 2 + CHECKPOINT_MARGIN
    bounds = [
        right - d,
        d - left,
        road.route_begin_s - CHECKPOINT_MARGIN - s,
        s - road.route_end_s - CHECKPOINT_MARGIN,
    ]
    if min(abs(v) for v in bounds) < 0.05:
        return None
    return lane >= -1 and max(bounds) < 0 and (lane == -1 or lo[2] <= lane <= hi[2])


@settings(max_examples=120, deadline=None)
@given(
    name=st.sampled_from(["oval", "ramp"]),
    where=st.floats(0.0, 1.0),
    off=st.floats(-9.0, 9.0),
    lane=st.integers(-3, 5),
)
def test_a_checkpoint_is_accepted_exactly_when_it_is_on_the_road_in_a_lane_there(name, where, off, lane):
    """Random points around a shipped road (up to 20 m beyond an open route's ends, up to 9 m beside
    the reference) and lanes -3..n+2: the road accepts them exactly when the closed form does."""
    road = load_road(scenario=name)
    s0, s1 = (0.0, road.lap_length) if road.closed else (road.route_begin_s - 20.0, road.route_end_s + 20.0)
    x, y = road.to_xy(np.array([s0 + where * (s1 - s0)]), np.array([off]))
    expected = _expected(road, float(x[0]), float(y[0]), lane)
    if expected is None:
        return
    try:
        road.check_checkpoints(((float(x[0]), float(y[0]), lane),))
        accepted = True
    except IrlsimError as e:
        assert "\n" not in str(e) and f"scenario {road.scenario_file}: checkpoint 0 (x=" in str(e)
        accepted = False
    assert accepted == expected
