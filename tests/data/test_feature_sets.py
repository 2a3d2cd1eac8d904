"""The lane-preference feature set (``planner.feature_set = "lanes"``) end to end: collected in SUMO, read,
trained and driven, the paper's 15 columns untouched; a model of one set refused by a planner of another."""

from __future__ import annotations

import json

import numpy as np
import pytest

from irlsim import FEATURE_NAMES, FEATURE_SETS, LANE_FEATURE_NAMES, feature_names_of, feature_set_of
from irlsim.cli import main
from irlsim.data.reader import open_dataset

from ..conftest import TINY_COLLECT

LANES = ["--set", "planner.feature_set=lanes"]


@pytest.fixture(scope="module")
def lanes_dataset(tmp_path_factory):
    """tiny_dataset's collection (the same seeds and episodes) with the lane pair computed too."""
    out = tmp_path_factory.mktemp("lanes") / "data"
    assert (
        main(["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT, *LANES])
        == 0
    )
    return out


def test_a_feature_set_is_named_by_its_names_in_order_and_found_by_its_size():
    for key, names in FEATURE_SETS.items():
        assert feature_set_of(list(names)) == key and feature_set_of(tuple(names)) == key
        assert feature_names_of(len(names)) == names
    assert feature_set_of(list(reversed(FEATURE_NAMES))) is None  # another order weighs other features
    assert feature_set_of(list(FEATURE_NAMES[:-1])) is None
    assert feature_set_of(None) is None and feature_set_of("mission_lane") is None  # a damaged manifest
    assert feature_names_of(3, default=FEATURE_NAMES) == FEATURE_NAMES
    with pytest.raises(ValueError, match="no feature set has 3 features"):
        feature_names_of(3)


def test_the_lane_pair_adds_two_columns_and_changes_nothing_else(lanes_dataset, tiny_dataset):
    manifest = json.loads((lanes_dataset / "manifest.json").read_text())
    assert manifest["feature_names"] == list(FEATURE_SETS["lanes"]) == [*FEATURE_NAMES, *LANE_FEATURE_NAMES]
    assert manifest["config"]["planner"]["feature_set"] == "lanes"
    paper = json.loads((tiny_dataset / "manifest.json").read_text())
    assert paper["feature_names"] == list(FEATURE_NAMES) and "feature_set" not in paper["config"]["planner"]
    lanes, ref = (
        open_dataset(lanes_dataset).split_tensors("train"),
        open_dataset(tiny_dataset).split_tensors("train"),
    )
    assert lanes.features.shape == (*ref.features.shape[:2], 17)
    # the expert does not price the lanes: it drives the same episodes, so the 15 columns are the same bytes
    np.testing.assert_array_equal(np.asarray(lanes.features[..., :15]), np.asarray(ref.features))
    np.testing.assert_array_equal(np.asarray(lanes.demo_index), np.asarray(ref.demo_index))
    right, left = np.asarray(lanes.features[..., 15]), np.asarray(lanes.features[..., 16])
    assert (right >= 0).all() and (left >= 0).all() and right.std() > 0 and left.std() > 0


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_trained_on_the_lanes_then_driven_only_with_them(lanes_dataset, tmp_path, capsys):
    runs = tmp_path / "runs"
    train = [
        "train",
        "--stage",
        "1",
        "--config",
        "configs/train/tiny_stage1.toml",
        "--data",
        str(lanes_dataset),
    ]
    assert main([*train, "--out", str(runs), "--set", 'models=["LIRL"]', "--set", "epochs=1"]) == 0
    # Table I on the lanes' test split: the oracle is a fit over the set's 17 features, and says so
    table = tmp_path / "table"
    assert main(["evaluate", "--data", str(lanes_dataset), "--runs", str(runs), "--out", str(table)]) == 0
    results = (table / "results.md").read_text()
    assert "| oracle (optimistic bound) | 17 per cycle |" in results and "over the 17 features" in results
    drive = ["drive", "--runs", str(runs), "--model", "LIRL", "--config", "configs/collect/tiny.toml"]
    drive += ["--max-cycles", "10", "--frames", "0", "--set", "planner.n_policies=120"]
    capsys.readouterr()
    assert main([*drive, "--out", str(tmp_path / "paper")]) == 2
    line = _one_line(capsys)
    assert "trained on the 'lanes' feature set (17 features), the planner computes the 'paper' set" in line
    assert 'planner.feature_set = "lanes"' in line
    assert not (tmp_path / "paper" / "drive.json").exists()  # refused before any drive
    assert main([*drive, *LANES, "--out", str(tmp_path / "lanes")]) == 0
    rec = json.loads((tmp_path / "lanes" / "drive.json").read_text())["episodes"][0]
    assert rec["drive/model"] == "LIRL" and rec["drive/cycles"] == 10


def test_an_unknown_feature_set_is_one_line(tmp_path, capsys):
    out = tmp_path / "d"
    args = [
        "collect",
        "--config",
        "configs/collect/tiny.toml",
        "--out",
        str(out),
        "--set",
        "planner.feature_set=lane",
    ]
    assert main(args) == 2
    assert "planner.feature_set must be one of paper, lanes, got 'lane'" in _one_line(capsys)
    assert not out.exists()
