"""Outputs owned by one command: drive and evaluate hold their --out's lock like collect and train (a
second command into it is one line, not a lost result), and the picture folders of checkpoint paths
never collide. Real training on the tiny data, real SUMO drives."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from irlsim.cli import main
from irlsim.utils import exclusive_lock

DRIVE_TOML = "max_cycles = 60\n[scenario]\nn_vehicles = 2\nmax_time = 200.0\n[planner]\nn_policies = 120\n"


@pytest.fixture(scope="module")
def runs(tiny_dataset, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("own") / "runs"
    args = [
        "train",
        "--stage",
        "1",
        "--config",
        "configs/train/tiny_stage1.toml",
        "--data",
        str(tiny_dataset),
    ]
    assert main([*args, "--out", str(out), "--set", "models=['LIRL']", "--set", "epochs=1"]) == 0
    return out


def _drive(model: str, cfg: Path, out: Path, frames: int = 0) -> int:
    args = ["drive", "--model", model, "--config", str(cfg), "--seed", "5000", "--max-cycles", "4"]
    return main([*args, "--frames", str(frames), "--out", str(out)])


def test_checkpoints_whose_paths_flatten_alike_draw_into_their_own_folders(runs, tmp_path):
    cfg = tmp_path / "drive.toml"
    cfg.write_text(DRIVE_TOML)
    ckpt = runs / "stage1" / "LIRL" / "checkpoint.pt"
    a, b = tmp_path / "x_y" / "checkpoint.pt", tmp_path / "x" / "y" / "checkpoint.pt"
    for p in (a, b):
        p.parent.mkdir(parents=True)
        shutil.copy(ckpt, p)
    out = tmp_path / "drive"
    assert _drive(f"{a},{b}", cfg, out, frames=2) == 0
    folders = [d for d in out.iterdir() if d.is_dir()]
    assert len(folders) == 2, folders
    for d in folders:
        assert sorted(p.name for p in d.glob("cycle_*.png")), d


@pytest.mark.parametrize("command", ["drive", "evaluate"])
def test_a_second_command_into_one_out_is_one_line(runs, tiny_dataset, tmp_path, capsys, command):
    cfg = tmp_path / "drive.toml"
    cfg.write_text(DRIVE_TOML)
    out = tmp_path / "out"
    with exclusive_lock(out / ".lock"):  # as a running drive or evaluate holds it
        capsys.readouterr()
        if command == "drive":
            rc = _drive(str(runs / "stage1" / "LIRL" / "checkpoint.pt"), cfg, out)
        else:
            rc = main(["evaluate", "--data", str(tiny_dataset), "--runs", str(runs), "--out", str(out)])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and f"another 'irlsim {command}' is writing" in err[0], err
    assert sorted(p.name for p in out.iterdir()) == [".lock"]  # nothing of the refused run
