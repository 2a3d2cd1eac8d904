"""A recorded ego at its own size (``demonstrator.ego_size = 'recorded'``) and egos of other classes
(``demonstrator.ego_classes``): a 12 m recorded ego is 12 m in its planner, in the episode's collision
check and in SUMO, where the scenario's size keeps it a 4.5 m car; a car of the scenario's size gives the
same bytes either way; what cannot be is one line before any work. Real SUMO runs on the oval."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data.demonstrator import DemonstratorConfig
from irlsim.data.recorded import recorded_episode
from irlsim.data.recording_as import ReadAs
from irlsim.errors import IrlsimError
from irlsim.planner.config import PlannerConfig
from irlsim.road import load_road
from irlsim.sim.config import EpisodeConfig
from tests.data.test_recording import _columns, _csv
from tests.data.test_recording_sizes import _sized


@pytest.mark.parametrize(("ego_size", "size"), [("scenario", (4.5, 1.8)), ("recorded", (12.0, 2.5))])
def test_a_recorded_ego_is_planned_checked_and_driven_at_its_size(fcd, tmp_path, ego_size, size):
    """veh2 is recorded 12 m by 2.5 m: with its recorded size its planner, its episode (whose collision
    check takes the ego's size from it) and SUMO's ego (what SUMO's drivers see) are that size."""
    path = _csv(tmp_path / "sized.csv", _sized(fcd, tmp_path))
    driver, _, scn, sim = recorded_episode(
        str(path), load_road(), EpisodeConfig(), PlannerConfig(n_policies=50), "veh2", reactive=True,
        read=ReadAs(ego_size=ego_size),
    )  # fmt: skip
    assert (scn.ego_length, scn.ego_width) == size
    assert (driver.planner.cfg.ego_length, driver.planner.cfg.ego_width) == size
    with sim:
        sim.reset(0)
        assert (sim._api.vehicle.getLength("ego"), sim._api.vehicle.getWidth("ego")) == size


def _collect(tmp_path: Path, recording: Path, name: str, extra: str = "") -> tuple[int, Path]:
    config = tmp_path / f"{name}.toml"
    config.write_text(
        "seed = 0\ntrain_episodes = 1\nvalidation_episodes = 0\ntest_episodes = 0\nmax_cycles = 40\n"
        f'[planner]\nn_policies = 100\n[demonstrator]\nkind = "recording"\nfile = "{recording}"\n'
        f'ego = "veh0"\n{extra}'
    )
    out = tmp_path / name
    return main(["collect", "--config", str(config), "--out", str(out)]), out


def _parquet(folder: Path) -> dict[str, str]:
    """Each Parquet file's rows (its bytes without the metadata that names the config, which differs)."""
    out = {}
    for p in sorted(folder.rglob("*.parquet")):
        sink = pa.BufferOutputStream()
        pq.write_table(pq.read_table(p).replace_schema_metadata(None), sink)
        out[str(p.relative_to(folder))] = hashlib.sha256(sink.getvalue().to_pybytes()).hexdigest()
    return out


def test_a_car_of_the_scenarios_size_collects_the_same_bytes_at_its_recorded_size(fcd, tmp_path, capsys):
    """veh0 is recorded 4.5 m by 1.8 m, the scenario's ego size: its episode's rows are the same either
    way (the files' metadata name the config, which differs), and the manifest says which size was asked
    for."""
    path = _csv(tmp_path / "sized.csv", _sized(fcd, tmp_path))
    assert _collect(tmp_path, path, "scenario")[0] == 0
    rc, out = _collect(tmp_path, path, "recorded", 'ego_size = "recorded"\n')
    assert rc == 0 and _parquet(out) == _parquet(tmp_path / "scenario") and _parquet(out)
    record = json.loads((out / "manifest.json").read_text())["demonstrator"]
    assert record["ego_size"] == "recorded" and "egos at their recorded size" in capsys.readouterr().out
    assert "ego_size" not in json.loads((tmp_path / "scenario" / "manifest.json").read_text())["demonstrator"]


def test_what_an_egos_class_or_size_cannot_be_is_one_line(fcd, tmp_path, capsys):
    """Each before any work: an unknown size, another class without the types that give classes, another
    class at a car's size, either on a demonstrator that is no recording, and a recorded size of a
    recording that has none (the collection writes nothing)."""
    rec = {"kind": "recording", "file": "x.csv"}
    for fields, message in (
        ({"ego_size": "big"}, "demonstrator.ego_size must be one of scenario, recorded, got 'big'"),
        ({"ego_classes": ("truck",), "ego_size": "recorded"}, "are the recorded types' classes: give"),
        ({"ego_classes": ("truck",), "vehicle_types": ("t.xml",)}, "an ego of class truck would be planned"),
        ({"ego_classes": ()}, "demonstrator.ego_classes must be SUMO vehicle classes"),
    ):
        with pytest.raises(IrlsimError, match=message):
            DemonstratorConfig(**rec, **fields).validate()  # type: ignore[arg-type]
    with pytest.raises(IrlsimError, match="ego_classes / ego_size belong to kind = 'recording'"):
        DemonstratorConfig(ego_size="recorded").validate()
    plain = _csv(tmp_path / "plain.csv", _columns(fcd))
    rc, out = _collect(tmp_path, plain, "unsized", 'ego_size = "recorded"\n')
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "ego_size = 'recorded' needs each vehicle's length and width" in err, err
    assert "\n" not in err and not list(out.rglob("*.parquet"))


def test_a_reward_drives_a_recorded_ego_at_its_size(fcd, tmp_path):
    """``irlsim drive`` on a recording with ``ego_size = 'recorded'``: the reward's planner and the
    episode are at the driven car's size (veh2, 12 m by 2.5 m)."""
    from irlsim.config import load_config
    from irlsim.data.collection import CollectConfig
    from irlsim.drive.closed_loop import _decider

    path = _csv(tmp_path / "sized.csv", _sized(fcd, tmp_path))
    config = tmp_path / "drive.toml"
    config.write_text(
        f'[planner]\nn_policies = 50\n[demonstrator]\nkind = "recording"\nfile = "{path}"\nego = "veh2"\n'
        'ego_size = "recorded"\n'
    )
    cfg = load_config(CollectConfig, config)
    _, decider, _, scn, sim = _decider("expert", cfg, load_road(), 1, 0, False, None, 0, False, ())
    assert (decider.planner.cfg.ego_length, decider.planner.cfg.ego_width) == (12.0, 2.5)
    assert (scn.ego_length, scn.ego_width) == (12.0, 2.5)
