"""Datasets of several demonstrators, with real SUMO data: every episode's demonstrator identity, the
selection of an aggregate's demonstrators (``--demonstrator-select``: exactly their episodes, an identity
of its own, a name no folder has refused in one line), training and evaluation on a selection, and the
breakdown per demonstrator of ``irlsim data info`` and of Table I."""

from __future__ import annotations

import json

import numpy as np
import pytest

from irlsim.cli import main
from irlsim.data.aggregate import manifest_identity, open_datasets
from irlsim.data.demonstrator import identity
from irlsim.data.info import dataset_info
from irlsim.data.reader import open_dataset
from irlsim.errors import IrlsimError
from tests.conftest import TINY_COLLECT, one_line, refused

IDM = "sumo:IDM/SL2015{accel=2,decel=3,tau=1.5}"  # configs/collect/sumo_idm.toml


@pytest.fixture(scope="module")
def idm(tmp_path_factory):
    """SUMO's IDM as demonstrator at the expert tiny dataset's planner (seed 1: other episodes)."""
    out = tmp_path_factory.mktemp("sel") / "idm"
    sets = ["--set", "seed=1", "--set", "train_episodes=1", "--set", "max_cycles=30"]
    args = ["collect", "--config", "configs/collect/sumo_idm.toml", "--out", str(out)]
    assert main([*args, *TINY_COLLECT, *sets]) == 0
    return out


@pytest.fixture(scope="module")
def idm_runs(tiny_dataset, idm, tmp_path_factory):
    runs = tmp_path_factory.mktemp("sel_runs")
    args = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml"]
    args += ["--data", str(tiny_dataset), str(idm), "--out", str(runs)]
    args += ["--set", "models=['LIRL']", "--set", "epochs=1"]
    assert main([*args, "--demonstrator-select", "sumo"]) == 0
    return runs


def _text(d: dict) -> str:
    return json.dumps(d, sort_keys=True)


def test_identity_strings():
    assert identity(None) == identity({"kind": "expert"}) == "expert"
    rec = {"kind": "sumo", "car_follow_model": "IDM", "lane_change_model": "LC2013"}
    rec["lane_changes_applied"] = True
    assert identity({**rec, "params": {"tau": 1.5, "accel": 2.0}}) == "sumo:IDM/LC2013{accel=2,tau=1.5}"
    assert identity({**rec, "params": {}}) == "sumo:IDM/LC2013{}"
    many = {f"p{i}": float(i) for i in range(12)}
    long = identity({**rec, "params": many})
    assert long.startswith("sumo:IDM/LC2013#") and len(long) == len("sumo:IDM/LC2013#") + 12
    assert long != identity({**rec, "params": {**many, "p0": 1.0}})
    # a record of an irlsim that left the lane-change attributes out of the driving: another driver
    old = {k: v for k, v in rec.items() if k != "lane_changes_applied"}
    assert identity({**old, "params": {"tau": 1.5}}) == "sumo:IDM/LC2013{tau=1.5}~lc-defaults"
    assert identity({**old, "params": many}) == long + "~lc-defaults"
    assert identity({"kind": "recording", "sha256": "0123456789abcdef"}) == "recording:0123456789ab"


def test_selection_is_exactly_the_demonstrators_episodes(tiny_dataset, idm):
    paths = [tiny_dataset, idm]
    whole = open_datasets(paths)
    assert open_dataset(idm).demonstrator_of_cycle("train").tolist() == [IDM] * 30
    who = whole.demonstrator_of_cycle("train")
    assert set(who.tolist()) == {"expert", IDM} and len(who) == whole.split_tensors("train").n_cycles
    ids = {whole.identity}
    for names in (("sumo",), (IDM,), ("expert",), ("expert", "sumo")):
        sel = open_datasets(paths, demonstrators=names)
        chosen = {IDM} if names in (("sumo",), (IDM,)) else {"expert", IDM} if len(names) == 2 else {"expert"}
        for split in ("train", "validation", "test"):
            t = sel.split_tensors(split)
            assert set(sel.demonstrator_of_cycle(split).tolist()) <= chosen
            mask = np.isin(whole.demonstrator_of_cycle(split), list(chosen))
            assert t.n_cycles == int(mask.sum())
            np.testing.assert_array_equal(
                np.asarray(t.features), np.asarray(whole.split_tensors(split).features)[mask]
            )
        ids.add(sel.identity)
    # a kind and the identity it names are the same selection; every other selection its own identity
    assert (
        open_datasets(paths, demonstrators=("sumo",)).identity
        == open_datasets(paths, demonstrators=(IDM,)).identity
    )
    assert len(ids) == 4
    assert open_datasets(paths, demonstrators=("sumo",)).identity != manifest_identity(
        open_dataset(idm).manifest
    )
    with pytest.raises(IrlsimError) as e:
        open_datasets(paths, demonstrators=("recording",))
    assert "have no demonstrator 'recording'" in one_line(e) and f"expert, {IDM}" in one_line(e)


def test_training_on_a_selection_and_bad_selections(tiny_dataset, idm, idm_runs, capsys):
    import torch

    paths = [tiny_dataset, idm]
    ckpt = torch.load(idm_runs / "stage1" / "LIRL" / "checkpoint.pt", weights_only=True)
    assert ckpt["dataset"] == open_datasets(paths, demonstrators=("sumo",)).identity
    assert ckpt["dataset"] != open_datasets(paths).identity
    summary = json.loads((idm_runs / "stage1" / "summary.json").read_text())
    assert summary["demonstrators"] == ["sumo"]
    args = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml"]
    args += ["--data", str(tiny_dataset), str(idm), "--out", str(idm_runs)]
    args += ["--set", "models=['LIRL']", "--set", "epochs=2"]
    assert "trained on another dataset" in refused(capsys, args)  # resumed on all the data
    msg = refused(capsys, [*args, "--demonstrator-select", "recording"])
    assert "have no demonstrator 'recording'" in msg
    assert "empty name" in refused(capsys, [*args, "--demonstrator-select", "sumo,"])


def test_breakdown_per_demonstrator(tiny_dataset, idm, idm_runs, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "info.json"
    assert main(["data", "info", str(tiny_dataset), str(idm), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    info = json.loads(out.read_text())["demonstrators"]
    assert list(info) == ["expert", IDM]
    assert info["expert"]["episodes"] == {"train": 2, "validation": 1, "test": 1}
    assert info[IDM]["episodes"] == {"train": 1, "validation": 1, "test": 1}
    assert info["expert"]["cycles"] == sum(
        open_dataset(tiny_dataset).split_tensors(s).n_cycles for s in info["expert"]["episodes"]
    )
    assert info[IDM]["cycles"] == 90
    assert f"{IDM} (sumo IDM/SL2015" in text and "episodes train 1, validation 1, test 1; 90 cycles" in text
    # each demonstrator's style is that of its own folder
    for who, folder in ((IDM, idm), ("expert", tiny_dataset)):
        assert _text(info[who]["style"]) == _text(dataset_info(folder)["style"])  # NaN: no following
    assert info[IDM]["style"]["style/km"] > 0

    ev = tmp_path / "eval"
    base = ["evaluate", "--data", str(tiny_dataset), str(idm), "--runs", str(idm_runs), "--no-references"]
    assert main([*base, "--out", str(ev)]) == 0
    assert "## OPD / ED per demonstrator [m]" in (ev / "results.md").read_text()
    lirl = next(r for r in json.loads((ev / "results.json").read_text())["rows"] if r["model"] == "LIRL")
    assert list(lirl["demonstrators"]) == ["expert", IDM]
    total = sum(v["cycles"] for v in lirl["demonstrators"].values())
    assert total == sum(v["cycles"] for v in lirl["situations"].values()) > 0
    opd = sum(v["opd"] * v["cycles"] for v in lirl["demonstrators"].values() if v["cycles"]) / total
    assert opd == pytest.approx(lirl["opd"], rel=1e-6)
    # on the selection alone: one demonstrator, no breakdown
    only = tmp_path / "eval_idm"
    assert main([*base, "--out", str(only), "--demonstrator-select", "sumo"]) == 0
    lirl = next(r for r in json.loads((only / "results.json").read_text())["rows"] if r["model"] == "LIRL")
    assert "demonstrators" not in lirl and lirl["cycles"] <= 30


def test_bench_demonstrator_goes_with_collect(tmp_path, capsys):
    argv = ["bench", "--demonstrator", "configs/collect/sumo_idm.toml", "--out", str(tmp_path / "b")]
    assert "--demonstrator goes with --collect" in refused(capsys, argv)
    assert not (tmp_path / "b").exists()
