"""DAgger's inputs that need no round of their own: a dataset's demonstration source read back, the same
folder aggregated twice, a per-round recipe reaching each round's commands (tests/pipelines/test_dagger.py
has the rounds themselves)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim.config import load_config
from irlsim.data.reader import open_dataset
from irlsim.errors import IrlsimError


def test_reader_without_or_with_a_bad_demo_source(tiny_dataset, tmp_path):
    """A version-2 cycles file written before the column reads as 'odometry'; an unknown value is refused."""
    ds = tmp_path / "old"
    shutil.copytree(tiny_dataset, ds, ignore=shutil.ignore_patterns(".cache", ".lock"))
    files = sorted(ds.glob("*/*.cycles.parquet"))
    for f in files:
        t = pq.read_table(f)
        pq.write_table(t.drop_columns(["demo_source"]).replace_schema_metadata(t.schema.metadata), f)
    d = open_dataset(ds)
    assert set(d.read_cycles("train")["demo_source"]) == {"odometry"}
    assert (d.split_tensors("train").demo_source == 0).all()
    t = pq.read_table(files[0])
    bad = t.append_column("demo_source", pa.array(["teacher"] * t.num_rows, pa.string()))
    pq.write_table(bad.replace_schema_metadata(t.schema.metadata), files[0])
    split = files[0].parent.name
    with pytest.raises(IrlsimError, match="demo_source 'teacher'"):
        open_dataset(ds).split_tensors(split)


def test_aggregate_refuses_the_same_folder_twice(tiny_dataset):
    from irlsim.data.aggregate import open_datasets

    with pytest.raises(IrlsimError, match="given twice"):
        open_datasets([tiny_dataset, tiny_dataset])


def test_dagger_config_per_round_recipe(tmp_path):
    """Per-round episodes and epochs, a training seed and stage-2 companions reach each round's commands."""
    from irlsim.workflows.dagger import DaggerConfig, DaggerRun, round_commands

    cfg = load_config(DaggerConfig, "configs/dagger/paper.toml", {"seed": 1})
    args = DaggerRun(cfg, Path("D"), Path("R"), Path("O"))
    for r, (episodes, epochs) in enumerate([(6, 20), (20, 10)], start=1):
        collect, stage1, stage2 = round_commands(args, r)
        assert f"train_episodes={episodes}" in collect
        assert collect[collect.index("--runs") + 1] == ("R" if r == 1 else str(Path("O/round_1/runs")))
        assert f"epochs={epochs}" in stage1 and "seed=1" in stage1
        assert stage1[stage1.index("--data") + 1 : stage1.index("--out")] == [
            "D",
            *(str(Path(f"O/round_{k}/data")) for k in range(1, r + 1)),
        ]
        assert stage2[:3] == ["train", "--stage", "2"] and "models=['PTACNN+S']" in stage2
        assert "seed=1" in stage2 and not any(a.startswith("epochs=") for a in stage2)
    # stage2_epochs sets every round's stage-2 epochs, and the stage-1 epochs stay the rounds' own
    short = DaggerRun(
        load_config(DaggerConfig, "configs/dagger/paper.toml", {"stage2_epochs": 5}),
        Path("D"),
        Path("R"),
        Path("O"),
    )
    for r, epochs in enumerate([20, 10], start=1):
        _, stage1, stage2 = round_commands(short, r)
        assert f"epochs={epochs}" in stage1 and "epochs=5" in stage2
    # one number is every round's; no epochs list leaves the stage config's epochs alone
    plain = DaggerConfig(rounds=3, episodes=5)
    plain.validate()
    for r in (1, 2, 3):
        collect, stage1 = round_commands(DaggerRun(plain, Path("D"), Path("R"), Path("O")), r)
        assert "train_episodes=5" in collect
        assert not any(a.startswith(("epochs=", "seed=")) for a in stage1)
    # --rounds 1 runs the first entry of a longer list; a shorter list or a wrong companion is refused
    load_config(DaggerConfig, "configs/dagger/paper.toml", {"rounds": 1}).validate()
    for overrides, needle in [
        ({"rounds": 3}, "episodes has 2 entries for 3 round"),
        ({"episodes": 4, "rounds": 3}, "epochs has 2 entries for 3 round"),
        ({"episodes": [6, 0]}, "episodes must be in 1..10000, got 0"),
        ({"stage2_models": ["PTACNN"]}, "stage2_models entry 'PTACNN'"),
        ({"seed": -1}, "seed must be in"),
        ({"stage2_epochs": -1}, "stage2_epochs must be in 0..100000"),
    ]:
        with pytest.raises(IrlsimError, match=needle):
            load_config(DaggerConfig, "configs/dagger/paper.toml", overrides)
