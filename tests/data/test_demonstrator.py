"""SUMO's driver models as demonstrators, with real SUMO: different models and parameters give different
odometry and demonstrations, the same seed the same bytes, the manifest records the demonstrator, a
dataset of one demonstrator is never resumed as another's, and SUMO's refusal of a model or attribute is
one line before any work."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import libsumo
import numpy as np
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data.demonstrator import identity
from irlsim.sim.inputs import SumoErrorLog

BASE = """
seed = 0
workers = 1
train_episodes = 1
validation_episodes = 0
test_episodes = 0
max_cycles = 30

[scenario]
n_vehicles = 4
laps = 1
max_time = 120.0

[planner]
n_policies = 120
"""
IDM = '[demonstrator]\nkind = "sumo"\ncar_follow_model = "IDM"\nparams = {tau = 1.5, accel = 2.0}\n'
KRAUSS = '[demonstrator]\nkind = "sumo"\ncar_follow_model = "Krauss"\nparams = {tau = 1.0, accel = 2.6}\n'


def _collect(tmp: Path, name: str, section: str) -> tuple[int, Path]:
    cfg = tmp / f"{name}.toml"
    cfg.write_text(BASE + section)
    out = tmp / name
    return main(["collect", "--config", str(cfg), "--out", str(out)]), out


def _parquet(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*.parquet"))}


@pytest.fixture(scope="module")
def sumo_sets(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("demonstrators")
    outs = {}
    for name, section in (("idm", IDM), ("krauss", KRAUSS)):
        rc, outs[name] = _collect(tmp, name, section)
        assert rc == 0
    return tmp, outs


def _cycles(out: Path):
    return pq.read_table(out / "train" / "episode_00000.cycles.parquet").to_pandas()


def test_models_give_different_odometry_and_demonstrations(sumo_sets):
    _, outs = sumo_sets
    idm, kr = _cycles(outs["idm"]), _cycles(outs["krauss"])
    assert len(idm) == len(kr) == 30
    assert idm["ego_v"].iloc[0] == kr["ego_v"].iloc[0]  # the same start (seed)...
    assert np.abs(idm["ego_v"].to_numpy() - kr["ego_v"].to_numpy()).max() > 1.0  # ...driven otherwise
    both = (idm["demo_index"] >= 0) & (kr["demo_index"] >= 0)
    assert both.sum() > 0 and (idm["demo_index"][both] != kr["demo_index"][both]).any()
    for out, cycles in ((outs["idm"], idm), (outs["krauss"], kr)):
        pol = pq.read_table(out / "train" / "episode_00000.policies.parquet").to_pandas()
        dist = pol["distance"].to_numpy().reshape(len(cycles), -1)
        has = cycles["demo_index"].to_numpy() >= 0
        # the demonstration is the odometry's projection; the executed policy the nearest one
        np.testing.assert_array_equal(cycles["demo_index"][has], np.argmin(dist[has], axis=1))
        finite = np.isfinite(dist).all(axis=1)
        np.testing.assert_array_equal(cycles["executed_index"][finite], np.argmin(dist[finite], axis=1))
        assert (cycles["demo_source"] == "odometry").all()


def test_manifest_records_the_demonstrator_and_the_style(sumo_sets, capsys):
    _, outs = sumo_sets
    man = json.loads((outs["idm"] / "manifest.json").read_text())
    assert man["demonstrator"] == {
        "kind": "sumo",
        "car_follow_model": "IDM",
        "lane_change_model": "LC2013",
        "params": {"tau": 1.5, "accel": 2.0},
        "lane_changes_applied": True,
    }
    assert man["config"]["demonstrator"]["car_follow_model"] == "IDM"
    stats = json.loads((outs["idm"] / "train" / "episode_00000.stats.json").read_text())
    assert stats["style/km"] > 0 and sum(stats["style/lane_share"]) == pytest.approx(1.0)
    capsys.readouterr()
    assert main(["data", "info", str(outs["idm"])]) == 0
    text = capsys.readouterr().out
    assert "demonstrator: sumo IDM/LC2013 {accel=2.0,tau=1.5}" in text and "lane changes/km" in text


def test_same_seed_same_bytes_and_a_vtype_file_is_its_attributes(sumo_sets):
    tmp, outs = sumo_sets
    vt = tmp / "idm.add.xml"
    vt.write_text('<additional><vType id="mine" carFollowModel="IDM" tau="1.5" accel="2.0"/></additional>')
    rc, again = _collect(tmp, "idm_file", f'[demonstrator]\nkind = "sumo"\nvtype_file = "{vt}"\n')
    assert rc == 0
    assert _parquet(again) == _parquet(outs["idm"])
    man = json.loads((again / "manifest.json").read_text())
    assert man["demonstrator"]["vtype_file"] == {
        "path": str(vt),
        "sha256": hashlib.sha256(vt.read_bytes()).hexdigest(),
    }
    # the file's model, unless the config names one: here the config's default Krauss would not apply
    assert man["demonstrator"]["car_follow_model"] == "IDM"


@pytest.mark.parametrize("section", [KRAUSS, ""], ids=["other-model", "expert"])
def test_resume_as_another_demonstrator_is_refused(sumo_sets, capsys, section):
    tmp, outs = sumo_sets
    before = (outs["idm"] / "manifest.json").read_bytes()
    capsys.readouterr()
    cfg = tmp / "other.toml"
    cfg.write_text(BASE + section)
    assert main(["collect", "--config", str(cfg), "--out", str(outs["idm"])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    now = "sumo Krauss/LC2013 {accel=2.6,tau=1.0}" if section else "expert"
    assert err == [
        f"irlsim: error: {outs['idm']} was collected with demonstrator sumo IDM/LC2013 "
        f"{{accel=2.0,tau=1.5}}, this config has {now}: choose another --out or delete {outs['idm']}"
    ]
    assert (outs["idm"] / "manifest.json").read_bytes() == before


def test_a_dataset_collected_before_lane_change_attributes_took_effect_is_named_so(sumo_sets, capsys):
    # an irlsim that inserted the ego with its own type ran LC2013 at its defaults whatever the record
    # said: its record lacks lane_changes_applied, and the same config does not resume it as its own
    tmp, outs = sumo_sets
    old = tmp / "old-idm"
    shutil.copytree(outs["idm"], old)
    man = json.loads((old / "manifest.json").read_text())
    del man["demonstrator"]["lane_changes_applied"]
    (old / "manifest.json").write_text(json.dumps(man))
    capsys.readouterr()
    assert main(["collect", "--config", str(tmp / "idm.toml"), "--out", str(old)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tau=1.5} (collected with its lane-change attributes not in effect" in err[0]


@pytest.mark.parametrize(
    "section, needle",
    [
        ('car_follow_model = "IDX"', "Unknown car following model 'IDX'"),
        ('lane_change_model = "LC2099"', "Unknown lane change model 'LC2099'"),
        ("params = {foo = 3}", "attribute 'foo' is not declared for element 'vType'"),
        ('params = {tau = "abc"}', "tau"),
        ('kind = "human"', "demonstrator.kind must be one of expert, sumo"),
        ("lane_change_duration = -1.0", "lane_change_duration must be a number >= 0 s"),
        ('kind = "expert"\nlane_change_duration = 3.0', "lane_change_duration belongs to kind = 'sumo'"),
    ],
)
def test_unknown_model_or_attribute_is_one_line_before_any_work(tmp_path, capsys, section, needle):
    capsys.readouterr()
    kind = "" if section.startswith("kind") else 'kind = "sumo"\n'
    rc, out = _collect(tmp_path, "bad", f"[demonstrator]\n{kind}{section}\n")
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and needle in err[0], err
    assert not out.exists()


def test_an_aggregate_of_several_demonstrators_names_each(sumo_sets):
    from irlsim.data.aggregate import open_datasets

    _, outs = sumo_sets
    agg = open_datasets([outs["idm"], outs["krauss"]])
    assert agg.manifest["demonstrators"] == [
        "sumo IDM/LC2013 {accel=2.0,tau=1.5}",
        "sumo Krauss/LC2013 {accel=2.6,tau=1.0}",
    ]
    assert len(agg.split_tensors("train").demo_index) == 60


def test_the_guides_sumo_config_loads():
    from irlsim.config import load_config
    from irlsim.data.collection import CollectConfig

    cfg = load_config(CollectConfig, Path(__file__).resolve().parents[2] / "configs/collect/sumo_idm.toml")
    cfg.validate()
    assert (cfg.demonstrator.kind, cfg.demonstrator.car_follow_model) == ("sumo", "IDM")
    assert cfg.demonstrator.lane_change_model == "SL2015" and cfg.demonstrator.params["tau"] == 1.5


EAGER = (
    '[demonstrator]\nkind = "sumo"\ncar_follow_model = "IDM"\n'
    "params = {lcSpeedGain = 5.0, lcKeepRight = 0.3, lcAssertive = 2.0}\n"
)


def test_a_lane_change_duration_spreads_the_lateral_move(tmp_path):
    """SUMO's lane changes are a jump of a lane width within one step; with a duration the odometry
    moves across as a driver steers, and the manifest names the duration."""
    base = BASE.replace("max_cycles = 30", "max_cycles = 70").replace("n_vehicles = 4", "n_vehicles = 12")
    moves = {}
    for lc in (0.0, 3.0):
        cfg = tmp_path / f"lc{lc:g}.toml"
        cfg.write_text(base + EAGER + f"lane_change_duration = {lc}\n")
        assert main(["collect", "--config", str(cfg), "--out", str(tmp_path / f"lc{lc:g}")]) == 0
        cycles = _cycles(tmp_path / f"lc{lc:g}")
        assert (np.diff(cycles["ego_lane"].to_numpy()) != 0).any()  # the driver changed lanes
        moves[lc] = np.abs(np.diff(cycles["ego_d"].to_numpy())).max()
    assert moves[0.0] > 2.5 and moves[3.0] < 1.0  # [m] per 0.2 s planning cycle
    man = json.loads((tmp_path / "lc3" / "manifest.json").read_text())
    assert man["demonstrator"]["lane_change_duration"] == 3.0
    lc0 = json.loads((tmp_path / "lc0" / "manifest.json").read_text())["demonstrator"]
    assert identity(man["demonstrator"]) != identity(lc0)  # another demonstrator than lc0's
    assert (
        "lane_change_duration"
        not in json.loads((tmp_path / "lc0" / "manifest.json").read_text())["demonstrator"]
    )


def test_a_model_sumo_stops_mid_episode_is_named_in_sumos_words(tmp_path, capsys):
    # SUMO loads Rail with SL2015 (it passes the check before any work) and quits where the lane-change
    # model asks the rail model what it refuses: with this seed and five cars, within the first 30 cycles
    # (measured with SUMO 1.28); libsumo itself says only 'Process Error'
    rail = '[demonstrator]\nkind = "sumo"\ncar_follow_model = "Rail"\nlane_change_model = "SL2015"\n'
    cfg = tmp_path / "rail.toml"
    cfg.write_text(BASE.replace("n_vehicles = 4", "n_vehicles = 5") + rail)
    out = tmp_path / "rail"
    logs = set(Path(tempfile.gettempdir()).glob(f"irlsim-sumo-{os.getpid()}-*"))  # earlier tests' sims
    capsys.readouterr()
    rc = main(["collect", "--config", str(cfg), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and "function call not allowed for rail model" in err[-1], err[-1]
    assert "Process Error" not in err[-1] and not list(out.rglob("*.parquet"))
    assert set(Path(tempfile.gettempdir()).glob(f"irlsim-sumo-{os.getpid()}-*")) <= logs  # its log removed


def test_sumo_error_log_passes_every_other_error_unchanged(tmp_path):
    log = SumoErrorLog()
    log.path = tmp_path / "sumo.log"
    own = libsumo.TraCIException("Vehicle 'ego' is not known")
    assert log.explain(own) is own  # a message of its own: kept
    stopped = libsumo.FatalTraCIError("Process Error")
    assert log.explain(stopped) is stopped  # no log written: nothing better to say
    log.path.write_text("Warning: a teleport\nError: the first\nError: the last\n")
    assert str(log.explain(stopped)).startswith("SUMO stopped the episode: the last ")
    ours, bare = RuntimeError("Process Error"), AssertionError()  # irlsim's own, never taken for SUMO's
    assert log.explain(ours) is ours and log.explain(bare) is bare
    log.remove()
    log.remove()  # twice is fine
    assert not log.path.exists()
