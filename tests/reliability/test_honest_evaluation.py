"""Honest evaluation records: ``irlsim evaluate --held-out`` refuses a model's own training data in one
line, results.json / results.md say whether the evaluation was held out and on what the models were
trained, and an empty split is named as empty (it was reported as a policy-count mismatch). Real
collections of the tiny preset, real training."""

from __future__ import annotations

import json

import pytest

from irlsim.cli import main

STAGE1 = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml"]
ONE_MODEL = ["--set", 'models=["LIRL"]', "--set", "epochs=1"]


@pytest.fixture(scope="module")
def runs(second_tiny, tmp_path_factory):
    """LIRL trained on the second tiny collection (train and validation episodes, no test split)."""
    out = tmp_path_factory.mktemp("honest") / "runs"
    assert main([*STAGE1, "--data", str(second_tiny), "--out", str(out), *ONE_MODEL]) == 0
    return out


def _one_line(capsys, argv: list[str]) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_held_out_refuses_the_training_data_and_the_record_says_what_was_evaluated(
    runs, second_tiny, tiny_dataset, tmp_path, capsys
):
    line = _one_line(
        capsys,
        ["evaluate", "--data", str(second_tiny), "--runs", str(runs), "--held-out", "--split", "train"],
    )
    assert line == (
        f"irlsim: error: --held-out: {runs}/stage1/LIRL/checkpoint.pt was trained on data that includes "
        f"{second_tiny}, so it is not held out: evaluate without --held-out (Table I on its train split) or "
        "pass data the models were not trained on"
    )
    out = tmp_path / "eval"
    args = [
        "evaluate",
        "--data",
        str(tiny_dataset),
        "--runs",
        str(runs),
        "--no-references",
        "--out",
        str(out),
    ]
    assert main([*args, "--held-out"]) == 0
    record = json.loads((out / "results.json").read_text())
    assert record["evaluated_on"]["held_out"] is True and record["evaluated_on"]["data"] == [
        str(tiny_dataset)
    ]
    assert record["trained_on"]["stage1/LIRL"]["data"] == str(second_tiny)
    assert record["trained_on"]["stage1/LIRL"]["dataset"] != record["evaluated_on"]["dataset"]
    md = (out / "results.md").read_text()
    assert md.endswith(
        f"Held out: yes. Evaluated on {tiny_dataset}; the models were trained on {second_tiny}.\n"
    )
    assert record["trained_on"]["stage1/LIRL"]["data_verified"] is True
    # summary.json carries no check of its own: a path changed in it no longer matches the checkpoint
    summary = runs / "stage1" / "summary.json"
    good = summary.read_text()
    summary.write_text(good.replace(json.dumps(str(second_tiny)), json.dumps(str(tiny_dataset))))
    try:
        assert main([*args, "--held-out"]) == 0
    finally:
        summary.write_text(good)
    record = json.loads((out / "results.json").read_text())
    assert record["note"].endswith(
        "trained on other data (1 of them on data their summary.json does not name)."
    )
    assert record["trained_on"]["stage1/LIRL"] == {
        "dataset": record["trained_on"]["stage1/LIRL"]["dataset"],
        "data": str(tiny_dataset),
        "data_verified": False,
    }


def test_an_empty_test_split_is_named_as_empty(runs, second_tiny, tmp_path, capsys):
    out = tmp_path / "eval"
    line = _one_line(capsys, ["evaluate", "--data", str(second_tiny), "--runs", str(runs), "--out", str(out)])
    assert line == (
        f"irlsim: error: the test split of {second_tiny} is empty (no cycles): collect it with "
        "test_episodes > 0, or evaluate another split (--split)"
    )
    assert not (out / "results.json").exists()


def test_held_out_refuses_a_folder_of_the_aggregate_the_models_were_trained_on(
    second_tiny, tiny_dataset, tmp_path, capsys
):
    """A checkpoint records an aggregate's identity alone; its stage's summary.json names the folders, and
    one of them is not held out."""
    runs = tmp_path / "runs"
    data = ["--data", str(tiny_dataset), "--data", str(second_tiny)]
    assert main([*STAGE1, *data, "--out", str(runs), *ONE_MODEL]) == 0
    line = _one_line(capsys, ["evaluate", "--data", str(tiny_dataset), "--runs", str(runs), "--held-out"])
    assert line.startswith(
        f"irlsim: error: --held-out: {runs}/stage1/LIRL/checkpoint.pt was trained on data that includes "
        f"{tiny_dataset}, so it is not held out"
    )
    assert not (runs / "eval").exists()
