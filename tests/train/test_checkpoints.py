"""Runs-folder layout (one folder per stage), checkpoint validation at load, and the refusals of evaluate:
another feature set or schema, another N, no checkpoints, another history H."""

import dataclasses
import json

import pytest
import torch

from irlsim import FEATURE_NAMES
from irlsim.bench.synthetic import make_synthetic_dataset
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.errors import IrlsimError
from irlsim.evaluate import REFERENCE_ROWS, evaluate_models
from irlsim.train import Stage1Config, load_model, train_stage1
from irlsim.train.layout import find_checkpoint, stage_dir
from tests.conftest import one_line, train_synthetic_runs

H = 4  # Stage2Config.smoke()'s history


@pytest.fixture(scope="module")
def dataset():
    return make_synthetic_dataset(n_train=48, n_eval=24, n_policies=32, seed=0)


@pytest.fixture(scope="module")
def runs(dataset, tmp_path_factory):
    """The layout 'irlsim train --out RUNS' writes: RUNS/stage1/<model>/, RUNS/stage2/<model>/."""
    return train_synthetic_runs(dataset, tmp_path_factory.mktemp("runs"))


def test_each_stage_has_its_own_folder(runs):
    assert sorted(p.name for p in (runs / "stage1").iterdir()) == ["LIRL", "PACNN"]
    assert sorted(p.name for p in (runs / "stage2").iterdir()) == ["PTACNN"]
    assert find_checkpoint(runs, "PTACNN") == runs / "stage2" / "PTACNN" / "checkpoint.pt"
    assert find_checkpoint(runs, "LIRL") == runs / "stage1" / "LIRL" / "checkpoint.pt"
    # a stage folder itself (or a flat folder written by the library) resolves too
    assert find_checkpoint(runs / "stage1", "PACNN") == runs / "stage1" / "PACNN" / "checkpoint.pt"
    assert find_checkpoint(runs, "PACNN+S") is None


def test_stage_folders_hide_a_stale_flat_layout(runs, tmp_path):
    """A checkpoint left by the flat layout beside the stage folders is not picked up."""
    import shutil

    shutil.copytree(runs / "stage1", tmp_path / "stage1")
    shutil.copytree(runs / "stage2" / "PTACNN", tmp_path / "PTACNN")  # flat, stale
    assert find_checkpoint(tmp_path, "PTACNN") is None
    assert find_checkpoint(tmp_path, "PACNN") == tmp_path / "stage1" / "PACNN" / "checkpoint.pt"
    # the frozen base of stage 2 is the stage-1 PACNN's selected weights, byte for byte
    base = load_model(runs / "stage2" / "PTACNN" / "checkpoint.pt").base
    pacnn = load_model(runs / "stage1" / "PACNN" / "checkpoint.pt").model
    assert base is not None
    sa, sb = base.state_dict(), pacnn.state_dict()
    assert sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


def test_evaluate_finds_both_stages_and_uses_the_temporal_models_history(dataset, runs, tmp_path):
    rows = evaluate_models(dataset, runs, tmp_path / "eval")
    assert [r["model"] for r in rows] == ["LIRL", "PACNN", "PTACNN", *REFERENCE_ROWS]
    res = json.loads((tmp_path / "eval" / "results.json").read_text())
    assert res["history"] == H
    assert res["provenance"]["torch"] == torch.__version__
    assert rows[0]["provenance"]["threads"] == Stage1Config.smoke().threads
    md = (tmp_path / "eval" / "results.md").read_text()
    assert md.splitlines()[0] == f"# Results on the test split (history H = {H} cycles)"
    assert f"torch {torch.__version__}, 1 thread" in md
    # the stage-1 rows use the same H: a different H gives different history means for PACNN
    stage1_only = evaluate_models(dataset, runs / "stage1", tmp_path / "eval10")
    assert json.loads((tmp_path / "eval10" / "results.json").read_text())["history"] == 10
    assert stage1_only[1]["ed"] != rows[1]["ed"]


def test_evaluate_refuses_another_history_for_ptacnn(dataset, runs, tmp_path):
    with pytest.raises(IrlsimError) as e:
        evaluate_models(dataset, runs, tmp_path / "eval", H=H + 2)
    msg = one_line(e)
    assert f"PTACNN was trained with a history of H={H} cycles and cannot use --history {H + 2}" in msg
    assert not (tmp_path / "eval").exists()  # refused before anything was written
    rows = evaluate_models(dataset, runs, tmp_path / "eval", H=H)  # its own H is fine
    assert rows[2]["model"] == "PTACNN"


def test_evaluate_refuses_another_number_of_policies(runs, dataset, tmp_path):
    other = make_synthetic_dataset(n_train=8, n_eval=16, n_policies=24, seed=1)
    with pytest.raises(IrlsimError) as e:  # another dataset: refused by its identity ...
        evaluate_models(other, runs, tmp_path / "eval")
    assert "was trained on another dataset" in one_line(e)
    other.manifest = dict(dataset.manifest)  # ... and by the shapes, were the identity the same
    with pytest.raises(IrlsimError) as e:
        evaluate_models(other, runs, tmp_path / "eval")
    assert "LIRL was trained on N=32 policies per cycle, the test split has 24" in one_line(e)
    assert not (tmp_path / "eval").exists()


def test_evaluate_without_checkpoints_is_an_error(dataset, tmp_path):
    (tmp_path / "runs" / "stage1").mkdir(parents=True)
    with pytest.raises(IrlsimError) as e:
        evaluate_models(dataset, tmp_path / "runs", tmp_path / "eval")
    assert "no trained model in" in one_line(e)
    assert not (tmp_path / "eval").exists()


@pytest.mark.parametrize(
    "change, expected",
    [
        ({"feature_names": [*FEATURE_NAMES[:-1], "proximity_v0"]}, "features proximity, proximity_v0 differ"),
        ({"feature_names": list(reversed(FEATURE_NAMES))}, "its features are in another order"),
        ({"schema_version": SCHEMA_VERSION - 1}, f"schema version {SCHEMA_VERSION - 1}, this irlsim reads"),
        ({"feature_names": None}, "another feature set"),
    ],
)
def test_load_refuses_another_feature_set_or_schema(runs, tmp_path, change, expected):
    for stage, name in ((1, "PACNN"), (2, "PTACNN")):
        ckpt = torch.load(stage_dir(runs, stage) / name / "checkpoint.pt", weights_only=True)
        ckpt.update(change)
        path = tmp_path / name / "checkpoint.pt"
        path.parent.mkdir(exist_ok=True)
        torch.save(ckpt, path)
        with pytest.raises(IrlsimError) as e:
            load_model(path)
        assert expected in one_line(e) and str(path) in str(e.value)


def test_training_refuses_a_dataset_of_another_schema(tmp_path):
    old = make_synthetic_dataset(n_train=16, n_eval=8, n_policies=16, seed=0)
    old.manifest["schema_version"] = SCHEMA_VERSION - 1
    with pytest.raises(IrlsimError, match=f"dataset schema version {SCHEMA_VERSION - 1} differs"):
        train_stage1(old, dataclasses.replace(Stage1Config.smoke(), models=("LIRL",), epochs=1), tmp_path)
