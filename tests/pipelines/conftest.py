"""Shared by the DAgger tests: a tiny PACNN+S trained on the expert's tiny dataset, and its collect config."""

from __future__ import annotations

from pathlib import Path

import pytest

from irlsim.cli import main
from tests.conftest import TINY_COLLECT

MODEL = "PACNN+S"


def _collect_toml(path: Path) -> Path:
    """The tiny dataset's collect config as a file (TINY_COLLECT's overrides on configs/collect/tiny.toml)."""
    sets = dict(TINY_COLLECT[i + 1].split("=", 1) for i in range(0, len(TINY_COLLECT), 2))
    top = "\n".join(f"{k} = {v}" for k, v in sets.items() if "." not in k)
    text = (
        f"{top}\n[scenario]\nn_vehicles = {sets['scenario.n_vehicles']}\nlaps = 1\nmax_time = 120.0\n"
        f"[planner]\nn_policies = {sets['planner.n_policies']}\n"
    )
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def learner(tiny_dataset, tmp_path_factory):
    """(collect config path, runs folder) of a tiny PACNN+S trained on the expert's tiny dataset."""
    root = tmp_path_factory.mktemp("dagger")
    runs = root / "runs"
    rc = main(
        ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml", "--data", str(tiny_dataset)]
        + ["--out", str(runs), "--set", f"models=['{MODEL}']"]
    )
    assert rc == 0
    return _collect_toml(root / "collect.toml"), runs
