"""A bad value from any config source names where it came from: the config file, a ``--set`` flag (or the
option that set it), the scenario file's ``[defaults]``; one line, before any work, nothing written."""

from __future__ import annotations

from pathlib import Path

import pytest

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig
from irlsim.errors import IrlsimError
from irlsim.road.network import SUMO_NET_DIR
from irlsim.sim.config import EpisodeConfig, scenario_config
from pipelines.commands import main

OVAL_DIR = SUMO_NET_DIR / "oval"

TINY = "configs/collect/tiny.toml"


def _scenario_with_defaults(folder: Path, defaults: str) -> Path:
    """The oval's route on the oval's network, as a user's scenario file with a [defaults] table."""
    folder.mkdir()
    text = (
        (OVAL_DIR / "scenario.toml")
        .read_text()
        .replace('netconvert = "netconvert.cfg"', f'file = "{OVAL_DIR / "oval.net.xml"}"')
    )
    path = folder / "scenario.toml"
    path.write_text(f"{text}\n[defaults]\n{defaults}\n")
    return path


def _refusal(capsys: pytest.CaptureFixture[str], out: Path, *args: str) -> str:
    assert main(["collect", *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and not out.exists()  # one line, nothing written
    return err


def test_a_set_flag_names_itself(tmp_path, capsys):
    err = _refusal(capsys, tmp_path / "o", "--config", TINY, "--set", "planner.n_policies=-3")
    assert err == "irlsim: error: config: --set planner.n_policies: planner.n_policies must be >= 1, got -3"


def test_a_config_file_names_itself(tmp_path, capsys):
    bad = tmp_path / "x.toml"
    bad.write_text(Path(TINY).read_text() + "\n[demo]\nw_yaw = -1.0\n")
    # the same key set well by --set on top does not hide which source is at fault, and vice versa
    err = _refusal(capsys, tmp_path / "o", "--config", str(bad), "--set", "seed=1")
    assert err.startswith(f"irlsim: error: config: config file {bad}: ")
    assert "--set" not in err


def test_an_option_names_itself(tmp_path, capsys):
    bad = tmp_path / "x.toml"
    bad.write_text(Path(TINY).read_text())
    err = _refusal(capsys, tmp_path / "o", "--config", str(bad), "--seed", "3000")
    assert err.startswith("irlsim: error: config: --seed: seed must be in 0..2147 ")


def test_a_scenarios_defaults_name_the_scenario_file(tmp_path, capsys):
    scn = _scenario_with_defaults(tmp_path / "road", "spawn_distance = -5.0")
    err = _refusal(capsys, tmp_path / "o", "--config", TINY, "--scenario", str(scn))
    assert err == (
        f"irlsim: error: config: scenario {scn} [defaults]: spawn_distance must be > 0 m, got -5.0"
    )
    # a value of the config that overrides the bad default: the defaults are not used, it loads
    cfg = load_config(CollectConfig, TINY, {"scenario.name": str(scn), "scenario.spawn_distance": 90.0})
    assert cfg.scenario.spawn_distance == 90.0
    # the same from the other ways in: EpisodeConfig (irlsim sim) and scenario_config (scenario check)
    for load in (
        lambda: load_config(EpisodeConfig, None, {"name": str(scn)}),
        lambda: scenario_config(str(scn)),
    ):
        with pytest.raises(IrlsimError) as e:
            load()
        assert str(e.value) == f"config: scenario {scn} [defaults]: spawn_distance must be > 0 m, got -5.0"


def test_a_good_config_loads_as_before():
    """The attribution runs only on the error path: a valid config and its overrides load unchanged."""
    cfg = load_config(CollectConfig, TINY, {"planner.n_policies": 7, "seed": 3})
    assert (cfg.planner.n_policies, cfg.seed) == (7, 3)


def test_the_environment_names_its_argument():
    from irlsim.envs.planning import PlanningEnv

    with pytest.raises(IrlsimError) as e:
        PlanningEnv(overrides={"planner.n_policies": -3})
    assert str(e.value) == "config: overrides['planner.n_policies']: planner.n_policies must be >= 1, got -3"


def test_the_old_name_of_the_episode_settings_still_imports():
    """``ScenarioConfig`` was renamed ``EpisodeConfig`` (a scenario is the road's file); code that imports
    the old name gets the same class, so its configs load and hash as before."""
    from irlsim.sim.config import EpisodeConfig
    from irlsim.sim.config import ScenarioConfig as Old

    assert Old is EpisodeConfig
    assert isinstance(load_config(CollectConfig, TINY).scenario, Old)
    assert Old(n_vehicles=3) == EpisodeConfig(n_vehicles=3)
