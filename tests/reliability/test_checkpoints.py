"""Checkpoint identity (model, stage, dataset), finite weights, a folder as checkpoint, byte-identical
checkpoints, and resume checks: each refusal is one line before any output is written."""

import dataclasses
import errno
import shutil
from pathlib import Path

import pytest
import torch

from irlsim.bench.synthetic import make_synthetic_dataset
from irlsim.errors import IrlsimError
from irlsim.evaluate import evaluate_models
from irlsim.outputs import os_error_message
from irlsim.train import Stage1Config, Stage2Config, load_model, train_stage1, train_stage2
from irlsim.train.layout import stage_dir
from tests.conftest import one_line, train_synthetic_runs


@pytest.fixture(scope="module")
def dataset():
    return make_synthetic_dataset(n_train=32, n_eval=16, n_policies=16, seed=0)


@pytest.fixture(scope="module")
def runs(dataset, tmp_path_factory):
    return train_synthetic_runs(dataset, tmp_path_factory.mktemp("runs"))


def _copy(runs: Path, tmp_path: Path) -> Path:
    out = tmp_path / "runs"
    shutil.copytree(runs, out)
    return out


@pytest.mark.parametrize(
    "src, dst, needle",
    [
        ("stage1/LIRL", "stage1/PACNN", "holds LIRL, not PACNN"),  # defect 2: another model's numbers
        ("stage2/PTACNN", "stage1/PACNN", "holds PTACNN, not PACNN"),  # a stage-2 checkpoint in stage 1
    ],
)
def test_evaluate_refuses_a_checkpoint_in_another_models_folder(runs, dataset, tmp_path, src, dst, needle):
    r = _copy(runs, tmp_path)
    shutil.copy(r / src / "checkpoint.pt", r / dst / "checkpoint.pt")
    with pytest.raises(IrlsimError) as e:
        evaluate_models(dataset, r, tmp_path / "eval")
    assert needle in one_line(e) and str(r / dst / "checkpoint.pt") in str(e.value)
    assert not (tmp_path / "eval").exists()


def test_a_stage_folder_holds_its_stage(runs, tmp_path):
    r = _copy(runs, tmp_path)
    (r / "stage1" / "PTACNN").mkdir()
    shutil.copy(r / "stage2" / "PTACNN" / "checkpoint.pt", r / "stage1" / "PTACNN" / "checkpoint.pt")
    with pytest.raises(IrlsimError) as e:
        load_model(r / "stage1" / "PTACNN" / "checkpoint.pt")
    assert "stage-2 checkpoint in a stage-1 folder" in one_line(e)


def test_drive_refuses_a_copied_checkpoint(runs, tmp_path):
    from irlsim.reward import load_reward

    r = _copy(runs, tmp_path)
    shutil.copy(r / "stage1" / "LIRL" / "checkpoint.pt", r / "stage1" / "PACNN" / "checkpoint.pt")
    with pytest.raises(IrlsimError) as e:
        load_reward("PACNN", r)
    assert "holds LIRL, not PACNN" in one_line(e)
    assert load_reward("LIRL", r).name == "LIRL"  # the right one still loads


def test_stage2_refuses_a_base_trained_on_another_dataset(runs, tmp_path):
    other = make_synthetic_dataset(n_train=32, n_eval=16, n_policies=16, seed=5)
    cfg2 = dataclasses.replace(Stage2Config.smoke(), models=("PTACNN",), epochs=1)
    with pytest.raises(IrlsimError) as e:
        train_stage2(other, cfg2, tmp_path / "s2", stage_dir(runs, 1))
    assert "was trained on another dataset" in one_line(e)
    assert not (tmp_path / "s2" / "PTACNN").exists()


@pytest.mark.parametrize("key", ["state_dict", "best"])
def test_non_finite_weights_are_refused_on_load(runs, tmp_path, key):
    ckpt = torch.load(runs / "stage1" / "PACNN" / "checkpoint.pt", weights_only=True)
    sd = ckpt[key]["state_dict"] if key == "best" else ckpt[key]
    name = next(iter(sd))
    sd[name] = torch.full_like(sd[name], float("nan"))
    path = tmp_path / "PACNN" / "checkpoint.pt"
    path.parent.mkdir()
    torch.save(ckpt, path)
    with pytest.raises(IrlsimError) as e:
        load_model(path)
    assert "non-finite weights" in one_line(e) and name in str(e.value)


def test_a_checkpoint_that_is_a_folder_isone_line(runs, dataset, tmp_path):
    r = _copy(runs, tmp_path)
    (r / "stage1" / "PACNN" / "checkpoint.pt").unlink()
    (r / "stage1" / "PACNN" / "checkpoint.pt").mkdir()
    with pytest.raises(IrlsimError) as e:  # not silently left out of Table I
        evaluate_models(dataset, r, tmp_path / "eval")
    assert "is a folder, not a file" in one_line(e)


@pytest.mark.parametrize("chop", [0.5, 0.0])
def test_truncated_or_foreign_checkpoint_isone_line(runs, tmp_path, chop):
    data = (runs / "stage1" / "LIRL" / "checkpoint.pt").read_bytes()
    path = tmp_path / "LIRL" / "checkpoint.pt"
    path.parent.mkdir()
    path.write_bytes(data[: int(len(data) * chop)] if chop else b"PK\x03\x04 not a checkpoint")
    with pytest.raises(IrlsimError) as e:
        load_model(path)
    assert "corrupt or unreadable" in one_line(e)


def test_identical_runs_give_identical_checkpoint_bytes(dataset, tmp_path):
    cfg = dataclasses.replace(Stage1Config.smoke(), models=("LIRL",), epochs=2)
    for run in ("a", "b"):
        train_stage1(dataset, cfg, tmp_path / run)
    a = (tmp_path / "a" / "LIRL" / "checkpoint.pt").read_bytes()
    b = (tmp_path / "b" / "LIRL" / "checkpoint.pt").read_bytes()
    assert a == b
    assert b".checkpoint.pt." not in a  # no temporary name inside


# ------------------------------------------------------------------------------------------- resume


def _train(dataset, out, **changes):
    cfg = dataclasses.replace(Stage1Config.smoke(), models=("LIRL",), **changes)
    return train_stage1(dataset, cfg, out)["LIRL"]


def test_resume_with_a_lower_lr_uses_and_records_it(dataset, tmp_path):
    _train(dataset, tmp_path, epochs=1, lr=0.05)
    summary = _train(dataset, tmp_path, epochs=2, lr=1e-3)
    ckpt = torch.load(tmp_path / "LIRL" / "checkpoint.pt", weights_only=True)
    assert ckpt["optimizer"]["param_groups"][0]["lr"] == 1e-3  # defect 3: the old lr was resumed
    assert ckpt["config"]["lr"] == 1e-3 and ckpt["epoch"] == 2
    assert ckpt["resumes"] == [{"epoch": 1, "changed": {"epochs": [1, 2], "lr": [0.05, 1e-3]}}]
    assert summary["resumes"] == ckpt["resumes"]


@pytest.mark.parametrize(
    "change, needle",
    [
        ({"seed": 3}, "trained with seed 0, asked 3"),
        ({"max_cycles": 10}, "trained with max_cycles 0, asked 10"),
        ({"select_by": "val/ed"}, "trained with select_by 'val/opd', asked 'val/ed'"),
        ({"history": 4}, "trained with history 10, asked 4"),
        ({"safe_demos": False}, "trained with safe_demos True, asked False"),
        ({"stop_demos": False}, "trained with stop_demos True, asked False"),
    ],
)
def test_resume_refuses_what_it_cannot_change(dataset, tmp_path, change, needle):
    _train(dataset, tmp_path, epochs=1)
    before = (tmp_path / "LIRL" / "checkpoint.pt").read_bytes()
    with pytest.raises(IrlsimError) as e:
        _train(dataset, tmp_path, epochs=2, **change)
    assert needle in one_line(e)
    assert (tmp_path / "LIRL" / "checkpoint.pt").read_bytes() == before  # nothing lost or changed


def test_resume_refuses_another_dataset(dataset, tmp_path):
    _train(dataset, tmp_path, epochs=1)
    other = make_synthetic_dataset(n_train=32, n_eval=16, n_policies=16, seed=9)
    with pytest.raises(IrlsimError) as e:
        _train(other, tmp_path, epochs=2)
    assert "was trained on another dataset" in one_line(e)


def test_a_disk_full_checkpoint_write_keeps_the_old_one_and_leaves_no_temporary(
    dataset, tmp_path, monkeypatch
):
    _train(dataset, tmp_path, epochs=1)
    before = (tmp_path / "LIRL" / "checkpoint.pt").read_bytes()

    def full(self, data):  # the writer's OS call fails as on a full disk
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    monkeypatch.setattr(Path, "write_bytes", full)
    with pytest.raises(OSError) as e:
        _train(dataset, tmp_path, epochs=2)
    monkeypatch.undo()
    msg = os_error_message(e.value)
    assert "\n" not in msg and "No space left on device" in msg and "free disk space" in msg
    assert str(tmp_path / "LIRL" / "metrics.csv") in msg and ".tmp" not in msg  # the file being written
    assert (tmp_path / "LIRL" / "checkpoint.pt").read_bytes() == before
    assert not [p for p in (tmp_path / "LIRL").iterdir() if p.name.endswith(".tmp")]
