"""One road, one identity: a shipped scenario spelled by its name, its folder or its scenario file
(relative or absolute) is its name in a dataset's config, manifest and episode records; a user's scenario
file is its name and content digest, never its path; a config that lists one road twice (spelled two
ways) is refused in one line before any work."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from irlsim.config import load_config
from irlsim.data.collection import CollectConfig, config_hash, data_config, episode_record
from irlsim.errors import IrlsimError
from irlsim.road.network import SUMO_NET_DIR
from irlsim.road.scenario import load_scenario, scenario_identity
from irlsim.workflows.collect import scenario_records
from pipelines.commands import main

OVAL_DIR = SUMO_NET_DIR / "oval"

TINY = "configs/collect/tiny.toml"


def _user_road(folder: Path) -> Path:
    """A user's scenario: the oval's route on a copy of its network, beside the file."""
    folder.mkdir(parents=True)
    shutil.copy(OVAL_DIR / "oval.net.xml", folder / "my.net.xml")
    text = (
        (OVAL_DIR / "scenario.toml")
        .read_text()
        .replace('netconvert = "netconvert.cfg"', 'file = "my.net.xml"')
    )
    (folder / "scenario.toml").write_text(text.replace('name = "oval"', 'name = "myroad"'))
    return folder / "scenario.toml"


def _multi(tmp_path: Path, *names: str) -> Path:
    body = "seed = 0\nmax_cycles = 3\n[planner]\nn_policies = 40\n"
    for name in names:
        body += f'[[scenarios]]\nname = "{name}"\ntrain_episodes = 1\ntest_episodes = 1\n'
    path = tmp_path / "multi.toml"
    path.write_text(body)
    return path


def test_a_shipped_road_spelled_three_ways_is_one_identity(monkeypatch):
    monkeypatch.chdir(SUMO_NET_DIR.parent)
    spellings = [
        "ramp",
        "sumo_net/ramp",
        "sumo_net/ramp/scenario.toml",
        str(SUMO_NET_DIR / "ramp/scenario.toml"),
    ]
    assert {scenario_identity(s) for s in spellings} == {"ramp"}
    configs = [load_config(CollectConfig, TINY, {"scenario.name": s}) for s in spellings]
    assert len({json.dumps(data_config(c), sort_keys=True) for c in configs}) == 1
    assert len({config_hash(c) for c in configs}) == 1
    assert {json.dumps(scenario_records(c)) for c in configs} == {
        json.dumps({"scenarios": {"ramp": load_scenario("ramp").digest()}})
    }
    assert data_config(configs[-1])["scenario"]["name"] == "ramp"


def test_a_users_road_is_its_name_and_digest_never_its_path(tmp_path):
    here, there = _user_road(tmp_path / "a" / "road"), _user_road(tmp_path / "b" / "copy")
    digest = load_scenario(here).digest()
    assert load_scenario(there).digest() == digest  # the same files by content
    ident = f"myroad@{digest.removeprefix('sha256:')[:16]}"
    assert scenario_identity(here) == scenario_identity(there) == scenario_identity(here.parent) == ident
    for path in (here, there):
        cfg = load_config(CollectConfig, TINY, {"scenario.name": str(path)})
        recorded = json.dumps([data_config(cfg), scenario_records(cfg), episode_record(7, cfg, str(path))])
        assert str(tmp_path) not in recorded and ident in recorded
    # another network, or another scenario file, is another road
    net = there.parent / "my.net.xml"
    net.write_bytes(net.read_bytes() + b"\n")
    assert scenario_identity(there) != ident
    there.write_text(there.read_text() + "\n")
    assert scenario_identity(there) != ident


def test_one_road_listed_twice_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(SUMO_NET_DIR.parent)
    cfg = _multi(tmp_path, "oval", str(SUMO_NET_DIR / "oval" / "scenario.toml"))
    out = tmp_path / "out"
    assert main(["collect", "--config", str(cfg), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and not out.exists()
    assert err == (
        f"irlsim: error: config: [[scenarios]] lists one road twice, as 'oval' and "
        f"'{SUMO_NET_DIR / 'oval' / 'scenario.toml'}' (both oval): give each scenario one entry"
    )
    with pytest.raises(IrlsimError):
        load_config(CollectConfig, cfg).check_roads()


def test_a_collection_on_a_users_road_records_no_path(tmp_path, capsys):
    """Collected from two copies of one user's road, by absolute paths in [[scenarios]]: the two
    manifests are the same bytes, with the road's identity and no path."""
    manifests = []
    for where in ("a", "b"):
        road = _user_road(tmp_path / where / "road")
        cfg = _multi(tmp_path / where, "ramp", str(road))
        out = tmp_path / where / "data"
        assert main(["collect", "--config", str(cfg), "--out", str(out)]) == 0
        manifests.append((out / "manifest.json").read_bytes())
    assert manifests[0] == manifests[1]
    m = json.loads(manifests[0])
    ident = scenario_identity(tmp_path / "a" / "road")
    assert list(m["scenarios"]) == ["ramp", ident]
    assert m["episode_scenarios"]["train"] == {"0": "ramp", "1": ident}
    assert str(tmp_path).encode() not in manifests[0]
