"""The whole learning chain at a tiny size on real collected data: train stage 1, stage 2, evaluate."""

from __future__ import annotations

import json

import numpy as np
import pytest

from irlsim.cli import main


@pytest.fixture(scope="module")
def tiny_runs(tiny_dataset, tmp_path_factory):
    runs = tmp_path_factory.mktemp("runs")
    data = str(tiny_dataset)
    assert (
        main(
            [
                "train",
                "--stage",
                "1",
                "--config",
                "configs/train/tiny_stage1.toml",
                "--data",
                data,
                "--out",
                str(runs),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "train",
                "--stage",
                "2",
                "--config",
                "configs/train/tiny_stage2.toml",
                "--data",
                data,
                "--out",
                str(runs),
            ]
        )
        == 0
    )
    assert main(["evaluate", "--data", data, "--runs", str(runs)]) == 0
    return runs


def test_chain_writes_every_output(tiny_runs):
    for m in ("LIRL", "1DCNN", "Bi1DCNN", "PACNN", "PACNN+S", "PTACNN", "PTACNN+S"):
        assert (tiny_runs / m / "checkpoint.pt").is_file(), m
        assert (tiny_runs / m / "metrics.csv").read_text().count("\n") >= 2, m
    ev = tiny_runs / "eval"
    for f in ("results.md", "results.json", "convergence.png", "opd_distribution.png"):
        assert (ev / f).stat().st_size > 0, f
    rows = {r["model"]: r for r in json.loads((ev / "results.json").read_text())["rows"]}
    assert {"PTACNN+S", "LIRL", "random policy"} <= set(rows)
    for r in rows.values():  # OPD is bounded below by DEMO (the demonstration is the argmin)
        assert r["opd"] >= r["demo"] - 1e-6
        if r["model"] != "random policy":
            assert r["opd_untrained"] >= r["demo"] - 1e-6


def test_lirl_learns_from_real_demonstrations(tiny_runs):
    import torch

    ck = torch.load(tiny_runs / "LIRL" / "checkpoint.pt", weights_only=False)
    rows = {r["model"]: r for r in json.loads((tiny_runs / "eval" / "results.json").read_text())["rows"]}
    assert rows["LIRL"]["opd"] < rows["random policy"]["opd"]
    assert np.isfinite(rows["PACNN"]["opd"])
    assert ck["epoch"] >= 1


def test_training_resumes_from_checkpoint(tiny_dataset, tiny_runs, capsys):
    """A second run with the same config finds finished checkpoints and does not retrain."""
    before = (tiny_runs / "LIRL" / "checkpoint.pt").read_bytes()
    assert (
        main(
            [
                "train",
                "--stage",
                "1",
                "--config",
                "configs/train/tiny_stage1.toml",
                "--data",
                str(tiny_dataset),
                "--out",
                str(tiny_runs),
                "--set",
                "models=['LIRL']",
            ]
        )
        == 0
    )
    assert (tiny_runs / "LIRL" / "checkpoint.pt").read_bytes() == before


def test_unknown_model_and_corrupt_checkpoint(tiny_dataset, tiny_runs, tmp_path, capsys):
    rc = main(
        [
            "train",
            "--stage",
            "1",
            "--data",
            str(tiny_dataset),
            "--out",
            str(tmp_path),
            "--set",
            "models=['PACNN++']",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "PACNN++" in err[0]
    bad = tmp_path / "runs" / "LIRL"
    bad.mkdir(parents=True)
    (bad / "checkpoint.pt").write_bytes(b"not a checkpoint")
    rc = main(["evaluate", "--data", str(tiny_dataset), "--runs", str(tmp_path / "runs")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "checkpoint" in err[0], err
