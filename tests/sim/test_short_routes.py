"""Short and mission-free routes (real SUMO): a closed circuit without exits or lane requirements (built
by netconvert) is a scenario whose mission is any lane; a 290 m urban route of the wheel's ``square``
network scales the ego's start clearances down; a route too short for any start is refused once, in one
line, before any episode (sim, collect, drive)."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.preflight import check_starts
from irlsim.sim.simulation import Simulation
from tests.road.test_scenario import make_scenario

#: a config whose start clearances no route of a few hundred metres can meet, even scaled down
NO_START = "ego_start_clearance = 5000.0\n"


def circuit(tmp_path: Path) -> Path:
    """A one-way two-lane circuit of 16 straight edges round a circle of 130 m radius (817 m)."""
    n, r = 16, 130.0
    xy = [(r * math.cos(2 * math.pi * i / n), r * math.sin(2 * math.pi * i / n)) for i in range(n)]
    nodes = "".join(f'<node id="n{i}" x="{x:.3f}" y="{y:.3f}"/>' for i, (x, y) in enumerate(xy))
    edges = "".join(
        f'<edge id="e{i}" from="n{i}" to="n{(i + 1) % n}" numLanes="2" speed="20"/>' for i in range(n)
    )
    route = "edges = [" + ", ".join(f'"e{i}"' for i in range(n)) + "]"
    return make_scenario(tmp_path / "circuit", nodes, edges, route)


def urban_300(tmp_path: Path) -> Path:
    folder = tmp_path / "urban"
    folder.mkdir()
    (folder / "scenario.toml").write_text(
        '[network]\nsumo_tools = "game/square/square.net.xml"\n\n[route]\nedges = ["left0A0", "A0B0"]\n'
    )
    return folder


def test_a_circuit_without_a_mission_is_a_scenario(tmp_path, capsys):
    folder = circuit(tmp_path)
    road = load_road(scenario=folder)
    assert road.closed and road.exits == () and road.n_lanes == 2
    assert [(c.lane, c.lanes) for c in road.checkpoints] == [(-1, ())]  # the mission: any lane
    from irlsim.cli import main

    out = tmp_path / "sim.json"
    argv = ["sim", "--scenario", str(folder), "--driver", "expert", "--episodes", "1", "--laps", "1"]
    assert main([*argv, "--vehicles", "4", "--max-time", "120", "--json", str(out)]) == 0
    ep = json.loads(out.read_text())["episodes"][0]
    assert ep["end_reason"] == "laps" and ep["sim/collisions"] == 0
    assert ep["sim/checkpoints_passed"] == ep["sim/checkpoints_in_lane"] >= 1


def test_a_short_urban_route_scales_the_start_down(tmp_path):
    road = load_road(scenario=urban_300(tmp_path))
    assert road.route_end_s - road.route_begin_s == pytest.approx(293.0, abs=3.0)
    with Simulation(road, EpisodeConfig(name="urban", n_vehicles=3, max_time=20.0)) as sim:
        assert sim.start_scale < 1.0  # 300 m of room ahead and 150 m from the exit do not fit
        starts = []
        for seed in range(5):
            obs = sim.reset(seed)
            starts.append(obs.ego.s)
            assert road.route_begin_s <= obs.ego.s < road.route_end_s
        assert len(set(np.round(starts, 3))) == 5  # each seed its own start
    # the shipped roads keep their starts: no scaling there
    assert Simulation(load_road(scenario="ramp"), EpisodeConfig(name="ramp")).start_scale == 1.0


def test_a_route_too_short_for_any_start_is_refused_once(tmp_path, capsys):
    folder = urban_300(tmp_path)
    road = load_road(scenario=folder)
    cfg = EpisodeConfig(name=str(folder))
    with pytest.raises(IrlsimError, match="leaves no start for the ego") as e:
        Simulation(road, replace(cfg, ego_start_clearance=5000.0))
    assert "\n" not in str(e.value)
    with pytest.raises(IrlsimError, match="choose a longer route or lower them"):
        check_starts(replace(cfg, ego_start_clearance=5000.0), (str(folder),))
    from irlsim.cli import main

    toml = tmp_path / "nostart.toml"
    toml.write_text(NO_START)
    # irlsim sim: one line, exit 2, before any episode
    assert main(["sim", "--scenario", str(folder), "--config", str(toml), "--episodes", "3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "leaves no start for the ego" in err and "Traceback" not in err
    # irlsim collect and drive: the same line before any episode is started
    collect = tmp_path / "collect.toml"
    collect.write_text(
        "train_episodes = 2\nvalidation_episodes = 0\ntest_episodes = 0\n\n[scenario]\n" + NO_START
    )
    out = tmp_path / "data"
    assert main(["collect", "--config", str(collect), "--scenario", str(folder), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "leaves no start for the ego" in err and "Traceback" not in err and not out.exists()
    drive = ["drive", "--model", "expert", "--config", str(collect), "--scenario", str(folder)]
    assert main([*drive, "--out", str(tmp_path / "drive")]) == 2
    err = capsys.readouterr().err
    assert "leaves no start for the ego" in err and "Traceback" not in err


def test_a_random_start_leaves_room_to_stop_before_a_traffic_light(tmp_path):
    """Over many seeds of a 331 m route of the wheel's grid6 through a light (its start clearances scaled
    down) and of the corridor (three lights), no start lies within the stopping distance at the start's
    top speed before a light: a start 2 m before one crossed it on red in the first cycle."""
    from irlsim.sim.start import SIGNAL_START_DECEL, SIGNAL_START_MARGIN, draw_start, start_scale
    from irlsim.sim.traffic import LoopEdges

    grid6 = tmp_path / "grid6" / "scenario.toml"
    grid6.parent.mkdir()
    grid6.write_text(
        'name = "grid6-route"\n[network]\nsumo_tools = "game/grid6/grid6.net.xml"\n[route]\n'
        'edges = ["left0to0/0", "0/0to1/0", "1/0tobottom1", "gneE29"]\n'
    )
    for scenario in (str(grid6), "corridor"):
        road = load_road(scenario=scenario)
        cfg = EpisodeConfig(name=scenario)
        edges = LoopEdges.from_road(road)
        scale = start_scale(road, cfg, edges)
        stop = cfg.ego_start_speed_max**2 / (2 * SIGNAL_START_DECEL) + SIGNAL_START_MARGIN
        lights = np.array([g.s for g in road.signals])
        assert len(lights) >= 1
        starts = np.array([draw_start(road, cfg, edges, seed, scale=scale)[0] for seed in range(200)])
        ahead = (lights[None, :] - starts[:, None]) % road.lap_length
        assert (ahead >= stop).all(), (scenario, ahead.min())
        assert len(np.unique(starts)) == 200  # still a draw per seed
