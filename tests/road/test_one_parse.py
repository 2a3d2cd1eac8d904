"""A scenario file is read once per command and road: the command resolves it into one ``Scenario``
and hands that object down (config defaults, the road, the simulation, collection's episodes)."""

from __future__ import annotations

import pickle
from collections import Counter
from pathlib import Path

import pytest

from irlsim.cli import main
from irlsim.road import load_road
from irlsim.road import scenario as scenario_module
from irlsim.road.scenario import Scenarios, load_scenario


@pytest.fixture
def parses(monkeypatch) -> Counter[Path]:
    """Every read_scenario_file call, by the file it read."""
    counts: Counter[Path] = Counter()
    real = scenario_module.read_scenario_file

    def counting(path: Path):
        counts[Path(path).resolve()] += 1
        return real(path)

    monkeypatch.setattr(scenario_module, "read_scenario_file", counting)
    return counts


def test_sim_reads_its_scenario_once(parses, capsys):
    rc = main(["sim", "--episodes", "1", "--vehicles", "0", "--max-time", "1", "--scenario", "oval"])
    assert rc == 0, capsys.readouterr().err
    assert list(parses.values()) == [1], parses


def test_collect_episode_reads_its_scenario_once(parses, tmp_path, capsys):
    config = tmp_path / "collect.toml"
    config.write_text(
        "workers = 1\ntrain_episodes = 1\nvalidation_episodes = 0\ntest_episodes = 0\nmax_cycles = 2\n"
        "[scenario]\nn_vehicles = 0\n[planner]\nn_policies = 20\n"
    )
    rc = main(["collect", "--config", str(config), "--out", str(tmp_path / "data")])
    assert rc == 0, capsys.readouterr().err
    assert list(parses.values()) == [1], parses


def test_a_scenario_pickles_and_loads_its_road_without_reading_the_file(parses):
    scn = pickle.loads(pickle.dumps(load_scenario("oval")))
    roads = Scenarios()
    roads("sumo_net/oval")
    in_worker = pickle.loads(pickle.dumps(roads))  # what a worker process receives with its job
    parses.clear()
    road = load_road(scenario=scn)
    assert road.name == "oval" and road.net_file == scn.net_file
    assert in_worker("oval").path.resolve() == scn.path.resolve() and in_worker.identity("oval") == "oval"
    assert not parses


def _collect_one(tmp_path: Path, config: str, *overrides: str) -> list[str]:
    """A one-episode collect of ``config`` at a tiny size (2 cycles of 20 policies)."""
    sizes = (
        "train_episodes=1",
        "validation_episodes=0",
        "test_episodes=0",
        "max_cycles=2",
        "planner.n_policies=20",
    )
    sets = [f"--set={o}" for o in (*sizes, *overrides)]
    return ["collect", "--config", config, "--out", str(tmp_path / "data"), *sets]


def test_sumo_demonstrator_collect_reads_its_scenario_once(parses, tmp_path, capsys):
    rc = main(_collect_one(tmp_path, "configs/collect/sumo_idm.toml", "scenario.n_vehicles=0"))
    assert rc == 0, capsys.readouterr().err
    assert list(parses.values()) == [1], parses


def test_recording_collect_reads_its_scenario_once(parses, tmp_path, capsys):
    """The recording is read and checked on the road the command loaded, then replayed in the episode."""
    rc = main(_collect_one(tmp_path, "examples/mydriver/collect.toml", "demonstrator.ego=car0"))
    assert rc == 0, capsys.readouterr().err
    assert list(parses.values()) == [1], parses


def test_drive_on_a_recording_reads_its_scenario_once(parses, tmp_path, capsys):
    argv = ["drive", "--config", "examples/mydriver/drive.toml", "--model", "expert", "--episodes", "1"]
    rc = main([*argv, "--max-cycles", "2", "--frames", "0", "--out", str(tmp_path / "drive")])
    assert rc == 0, capsys.readouterr().err
    assert list(parses.values()) == [1], parses


@pytest.mark.parametrize(
    "argv",
    [
        ["scenario", "show", "motorway"],
        ["net"],
        ["plot-cycle", "--time", "0", "--vehicles", "0", "--out", "{tmp}/cycle.png"],
        ["bench", "--planner", "--cycles", "1", "--scenario", "motorway", "--out", "{tmp}/bench"],
    ],
    ids=lambda argv: " ".join(argv[:2]),
)
def test_road_commands_read_their_scenario_once(parses, tmp_path, capsys, argv):
    rc = main([a.format(tmp=tmp_path) for a in argv])
    assert rc == 0, capsys.readouterr().err
    assert list(parses.values()) == [1], parses
