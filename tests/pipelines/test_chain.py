"""The whole chain at a tiny size, as a user runs it: ``irlsim demo --preset tiny`` (net, collect, train
stage 1, train stage 2, evaluate, drive) on real SUMO data, then the stages' CLI on its outputs."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import pytest

from irlsim.cli import main
from irlsim.evaluate import REFERENCE_ROWS

STAGE1 = ("LIRL", "1DCNN", "Bi1DCNN", "PACNN", "PACNN+S")
STAGE2 = ("PTACNN", "PTACNN+S")


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """(data, runs, stdout) of one tiny demo run."""
    root = tmp_path_factory.mktemp("demo")
    data, runs = root / "data", root / "runs"
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(["demo", "--preset", "tiny", "--data", str(data), "--runs", str(runs)])
    assert rc == 0, out.getvalue()[-3000:]
    return data, runs, out.getvalue()


def _braces(pattern: str) -> list[str]:
    m = re.search(r"\{([^{}]*)\}", pattern)
    if not m:
        return [pattern]
    return [p for o in m.group(1).split(",") for p in _braces(pattern[: m.start()] + o + pattern[m.end() :])]


def test_demo_prints_outputs_that_all_exist(demo):
    data, runs, stdout = demo
    listing = stdout.split("Outputs:\n", 1)[1].splitlines()
    lines = [line for line in listing if line.startswith("  ")]
    assert len(lines) >= 6
    paths = [Path(p) for line in lines for pat in line[18:].split(", ") for p in _braces(pat.strip())]
    for p in paths:
        assert p.is_file() and p.stat().st_size > 0, p
    printed = {str(p) for p in paths}
    for m in STAGE1:  # each stage in its own folder
        assert str(runs / "stage1" / m / "checkpoint.pt") in printed, m
    for m in STAGE2:
        assert str(runs / "stage2" / m / "checkpoint.pt") in printed, m
    assert str(runs / "drive_safety" / "drive.json") in printed
    assert str(data / "manifest.json") in printed
    # every step's command was echoed, in order
    commands = re.findall(r"^\$ irlsim (\w+)", stdout, flags=re.M)
    assert commands == ["net", "collect", "train", "train", "evaluate", "drive", "drive"]
    assert "1DCNN" in stdout and "trainable parameters" in stdout


def test_chain_outputs_are_consistent(demo):
    _, runs, _ = demo
    for m in STAGE1:
        assert (runs / "stage1" / m / "metrics.csv").read_text().count("\n") >= 2, m
        assert not (runs / "stage2" / m).exists(), m
    for m in STAGE2:
        assert (runs / "stage2" / m / "metrics.csv").read_text().count("\n") >= 2, m
    s1 = json.loads((runs / "stage1" / "summary.json").read_text())
    s2 = json.loads((runs / "stage2" / "summary.json").read_text())
    assert set(s1["models"]) == set(STAGE1) and set(s2["models"]) == set(STAGE2)
    assert s2["base"] == str(runs / "stage1") and s1["config"]["epochs"] == 3
    assert s1["models"]["LIRL"]["parameters"] == 15
    res = json.loads((runs / "eval" / "results.json").read_text())
    assert res["history"] == 10  # configs/train/tiny_stage2.toml's H
    rows = {r["model"]: r for r in res["rows"]}
    assert set(rows) == {*STAGE1, *STAGE2, *REFERENCE_ROWS}
    for r in rows.values():  # OPD is bounded below by DEMO (the demonstration is the argmin)
        assert r["opd"] >= r["demo"] - 1e-6
        if r["model"] not in REFERENCE_ROWS:
            assert r["opd_untrained"] >= r["demo"] - 1e-6
    drive = json.loads((runs / "drive" / "drive.json").read_text())
    assert "PTACNN+S" in json.dumps(drive)


def test_lirl_learns_from_real_demonstrations(demo):
    """Three epochs on the expert's demonstrations move LIRL's optimal policy closer to them than the
    same model at its initial weights (and than a random policy)."""
    _, runs, _ = demo
    rows = {r["model"]: r for r in json.loads((runs / "eval" / "results.json").read_text())["rows"]}
    assert rows["LIRL"]["opd"] < rows["LIRL"]["opd_untrained"]
    assert rows["LIRL"]["opd"] < rows["random policy"]["opd"]


def test_training_resumes_from_checkpoint(demo):
    """A second run with the same config finds finished checkpoints and does not retrain."""
    data, runs, _ = demo
    before = (runs / "stage1" / "LIRL" / "checkpoint.pt").read_bytes()
    argv = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml"]
    assert main([*argv, "--data", str(data), "--out", str(runs), "--set", "models=['LIRL']"]) == 0
    assert (runs / "stage1" / "LIRL" / "checkpoint.pt").read_bytes() == before


def _fails_with_one_line(capsys, argv: list[str], *expected: str) -> None:
    rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    for e in expected:
        assert e in err[0], err[0]


def test_stage_errors_are_one_line(demo, tmp_path, capsys):
    data, runs, _ = demo
    train = ["train", "--data", str(data)]
    _fails_with_one_line(
        capsys, [*train, "--stage", "1", "--out", str(tmp_path), "--set", "models=['PACNN++']"], "PACNN++"
    )
    # stage 2 without its stage-1 folder, or with one that lacks the base model
    _fails_with_one_line(
        capsys, [*train, "--stage", "2", "--out", str(tmp_path / "fresh")], "stage1", "does not exist"
    )
    (tmp_path / "only_lirl" / "LIRL").mkdir(parents=True)
    _fails_with_one_line(
        capsys,
        [*train, "--stage", "2", "--out", str(tmp_path / "x"), "--base", str(tmp_path / "only_lirl")],
        "needs a trained PACNN",
    )
    _fails_with_one_line(
        capsys, [*train, "--stage", "1", "--out", str(tmp_path), "--base", str(runs)], "--base", "--stage 2"
    )
    # evaluate: no checkpoints, a history the temporal models were not trained with, a corrupt checkpoint
    (tmp_path / "empty").mkdir()
    _fails_with_one_line(
        capsys, ["evaluate", "--data", str(data), "--runs", str(tmp_path / "empty")], "no trained model"
    )
    _fails_with_one_line(
        capsys,
        [
            "evaluate",
            "--data",
            str(data),
            "--runs",
            str(runs),
            "--history",
            "4",
            "--out",
            str(tmp_path / "ev"),
        ],
        "PTACNN was trained with a history of H=10",
        "--history 4",
    )
    assert not (tmp_path / "ev").exists()
    bad = tmp_path / "runs" / "stage1" / "LIRL"
    bad.mkdir(parents=True)
    (bad / "checkpoint.pt").write_bytes(b"not a checkpoint")
    _fails_with_one_line(
        capsys, ["evaluate", "--data", str(data), "--runs", str(tmp_path / "runs")], "corrupt"
    )


def test_drive_refuses_seeds_of_the_training_data(demo, tmp_path, capsys):
    """Every checkpoint stores the episode seeds of its dataset (all splits, from the manifest), and
    `irlsim drive` refuses evaluation seeds among them, for stage 1 and stage 2 models alike."""
    import torch

    data, runs, _ = demo
    manifest = json.loads((data / "manifest.json").read_text())
    seeds = sorted({s for split in manifest["seeds"].values() for s in split})
    for stage, name in ((1, "LIRL"), (2, "PTACNN+S")):
        ckpt = torch.load(runs / f"stage{stage}" / name / "checkpoint.pt", weights_only=True)
        assert ckpt["dataset_seeds"] == seeds
        drive = ["drive", "--runs", str(runs), "--model", name, "--config", "configs/collect/tiny.toml"]
        _fails_with_one_line(
            capsys,
            [*drive, "--seed", str(seeds[0]), "--episodes", "1", "--out", str(tmp_path / "d")],
            f"episode seed(s) {seeds[0]} ",
            f"{name} was trained on",
        )
        assert not (tmp_path / "d" / "drive.json").exists()
