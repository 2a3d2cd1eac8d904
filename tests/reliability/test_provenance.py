"""Provenance by content: a dataset or an aggregate of dataset folders is identified by what it holds
(member identities in order, never paths), and every checkpoint records the episode seeds of everything
it was trained on, so ``irlsim drive`` refuses them for any model, DAgger's included. Real tiny
collections, real training, the real CLI."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import torch

from irlsim.cli import main
from irlsim.data.aggregate import open_datasets
from irlsim.data.reader import CACHE_DIR
from irlsim.train.checkpoint import dataset_identity
from tests.conftest import TINY_COLLECT

ROOT = Path(__file__).resolve().parents[2]


def _copies(tiny_dataset: Path, second_tiny: Path, where: Path) -> tuple[Path, Path]:
    ignore = shutil.ignore_patterns(CACHE_DIR, ".lock")
    a, b = where / "expert", where / "round"
    shutil.copytree(tiny_dataset, a, ignore=ignore)
    shutil.copytree(second_tiny, b, ignore=ignore)
    return a, b


def _train(data: list[Path | str], out: Path, epochs: int = 1) -> int:
    return main(
        [
            "train",
            "--stage",
            "1",
            "--config",
            str(ROOT / "configs/train/tiny_stage1.toml"),
            "--data",
            *map(str, data),
            "--set",
            'models=["LIRL"]',
            "--set",
            f"epochs={epochs}",
            "--out",
            str(out),
        ]
    )


def _seeds(path: Path) -> list[int]:
    import json

    seeds = json.loads((path / "manifest.json").read_text())["seeds"]
    return sorted(int(x) for split in seeds.values() for x in split)


def test_a_model_trained_on_several_folders_records_their_seeds_and_drive_refuses_them(
    tiny_dataset, second_tiny, tmp_path, capsys
):
    a, b = _copies(tiny_dataset, second_tiny, tmp_path)
    assert _train([a, b], tmp_path / "runs") == 0
    ckpt = tmp_path / "runs" / "stage1" / "LIRL" / "checkpoint.pt"
    recorded = torch.load(ckpt, weights_only=True)["dataset_seeds"]
    assert recorded is not None and sorted(recorded) == sorted(_seeds(a) + _seeds(b))
    # the cars of a recording's data are recorded only where there is a recording: these bytes as before
    assert "dataset_egos" not in torch.load(ckpt, weights_only=True)
    cfg = tmp_path / "tiny.toml"
    cfg.write_text("[planner]\nn_policies = 120\n")
    for seed in (_seeds(a)[0], _seeds(b)[-1]):  # the expert data's seed 0, the round's own seeds
        capsys.readouterr()
        args = ["drive", "--model", str(ckpt), "--seed", str(seed), "--config", str(cfg), "--out"]
        assert main([*args, str(tmp_path / "drive")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "are seeds of the data" in err[0], err
    assert not (tmp_path / "drive" / "drive.json").exists()
    # a checkpoint written before the seeds were recorded cannot be checked: said, not silent
    from irlsim.train.checkpoint import save_checkpoint

    old = {k: v for k, v in torch.load(ckpt, weights_only=True).items() if k != "format"}
    save_checkpoint(ckpt, {**old, "dataset_seeds": None})
    args = ["drive", "--model", str(ckpt), "--seed", "0", "--config", str(cfg), "--max-cycles", "2"]
    assert main([*args, "--frames", "0", "--out", str(tmp_path / "drive")]) == 0
    assert "records no training seeds" in capsys.readouterr().err


def test_an_aggregate_is_identified_by_its_content_not_its_paths(tiny_dataset, second_tiny, tmp_path, capsys):
    a, b = _copies(tiny_dataset, second_tiny, tmp_path / "first")
    runs = tmp_path / "runs"
    assert _train([a, b], runs) == 0
    # the folders copied byte for byte, moved elsewhere and named by relative paths: the same dataset
    moved = tmp_path / "elsewhere"
    c, d = _copies(a, b, moved)
    assert dataset_identity(open_datasets([c, d])) == dataset_identity(open_datasets([a, b]))
    cwd = Path.cwd()
    os.chdir(moved)
    try:
        assert _train(["expert", "round"], runs, epochs=2) == 0  # resumed, not "another dataset"
        capsys.readouterr()
        # the order is part of what was trained on (rows, episode ids): another order is another dataset
        assert _train(["round", "expert"], runs, epochs=3) == 2
        assert "trained on another dataset" in capsys.readouterr().err
    finally:
        os.chdir(cwd)
    ckpt = torch.load(runs / "stage1" / "LIRL" / "checkpoint.pt", weights_only=True)
    assert ckpt["epoch"] == 2 and ckpt["dataset"] == dataset_identity(open_datasets([c, d]))
    out = tmp_path / "eval"
    assert main(["evaluate", "--data", str(c), str(d), "--runs", str(runs), "--out", str(out)]) == 0


def test_a_copied_dagger_round_folder_resumes_with_its_copied_driver(tiny_dataset, tmp_path, capsys):
    """A DAgger round's data and its driver copied elsewhere (another machine, a backup): the collection
    resumes (nothing re-collected, the manifest and so the identity unchanged); a driver recorded by path
    refused it as 'another config'."""
    first = tmp_path / "first"
    runs = first / "runs"
    args = [
        "train",
        "--stage",
        "1",
        "--config",
        "configs/train/tiny_stage1.toml",
        "--data",
        str(tiny_dataset),
    ]
    assert main([*args, "--out", str(runs), "--set", "models=['PACNN+S']", "--set", "epochs=1"]) == 0
    sets = ["--set", "train_episodes=1", "--set", "validation_episodes=0", "--set", "test_episodes=0"]
    sets += TINY_COLLECT

    def collect(root: Path) -> int:
        driver = root / "runs" / "stage1" / "PACNN+S" / "checkpoint.pt"
        base = ["collect", "--config", "configs/collect/tiny.toml", "--driver", str(driver)]
        return main([*base, "--out", str(root / "round"), *sets])

    assert collect(first) == 0
    copy = tmp_path / "copy"
    shutil.copytree(first, copy, ignore=shutil.ignore_patterns(CACHE_DIR, ".lock"))
    manifest = (copy / "round" / "manifest.json").read_bytes()
    stamps = sorted(p.stat().st_mtime_ns for p in (copy / "round").rglob("*.parquet"))
    capsys.readouterr()
    assert collect(copy) == 0, capsys.readouterr().err
    assert (copy / "round" / "manifest.json").read_bytes() == manifest
    assert sorted(p.stat().st_mtime_ns for p in (copy / "round").rglob("*.parquet")) == stamps


def _collect(out: Path, seed: int) -> int:
    args = ["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT]
    return main([*args, "--set", "test_episodes=0", "--seed", str(seed)])


def _parquet_sha(folder: Path) -> dict[str, str]:
    import hashlib

    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in folder.rglob("*.parquet")
    }


def test_a_resume_with_another_seed_and_no_manifest_recollects_instead_of_relabelling(tmp_path, capsys):
    import json

    import pyarrow.parquet as pq

    out, fresh = tmp_path / "data", tmp_path / "fresh"
    assert _collect(out, 0) == 0
    meta = pq.ParquetFile(out / "train" / "episode_00000.policies.parquet").schema_arrow.metadata
    assert meta[b"irlsim.seed"] == b"0" and meta[b"irlsim.config"].startswith(b"sha256:")
    (out / "manifest.json").unlink()  # lost
    capsys.readouterr()
    assert _collect(out, 1) == 0
    assert "was collected with seed 0, this run's is 1000000" in capsys.readouterr().err
    assert _collect(fresh, 1) == 0
    # the files are seed 1's, as the manifest says: the bytes of a fresh seed-1 collection
    assert _parquet_sha(out) == _parquet_sha(fresh)
    assert json.loads((out / "manifest.json").read_text())["seeds"]["train"][0] == 1_000_000


def test_files_of_an_older_irlsim_are_kept_with_their_manifest_and_recollected_without(tmp_path):
    import pyarrow.parquet as pq

    out = tmp_path / "data"
    assert _collect(out, 0) == 0
    recorded = _parquet_sha(out)
    for p in out.rglob("*.parquet"):  # as an irlsim before the seed record wrote them
        table = pq.read_table(p)
        meta = {
            k: v
            for k, v in (table.schema.metadata or {}).items()
            if k not in (b"irlsim.seed", b"irlsim.config")
        }
        pq.write_table(table.replace_schema_metadata(meta), p)
    older = _parquet_sha(out)
    assert _collect(out, 0) == 0 and _parquet_sha(out) == older  # the manifest vouches: kept
    (out / "manifest.json").unlink()
    assert _collect(out, 0) == 0 and _parquet_sha(out) == recorded  # nothing vouches: collected again


def test_the_cars_a_model_learned_from_are_those_its_episodes_drove_by_recording():
    """A recording's manifest lists every car it gives as an ego, in the order episodes take them; the
    checkpoint's record is the ones the config's episodes took, by recording, over every folder."""
    from types import SimpleNamespace

    from irlsim.train.checkpoint import dataset_egos

    def folder(sha: str, egos: list[str], train: int, validation: int, test: int) -> SimpleNamespace:
        config = {"train_episodes": train, "validation_episodes": validation, "test_episodes": test}
        record = {"kind": "recording", "file": "r.csv", "sha256": sha, "egos": egos}
        return SimpleNamespace(manifest={"demonstrator": record, "config": config})

    expert = SimpleNamespace(manifest={"demonstrator": {"kind": "expert"}, "config": {"train_episodes": 4}})
    one = folder("aa", ["c9", "c1", "c5", "c7", "c2"], 2, 1, 0)
    assert dataset_egos(one) == {"aa": ["c1", "c5", "c9"]}  # c7 and c2 were no episode's
    more = folder("aa", ["c3", "c9"], 1, 0, 1)
    other = folder("bb", ["x"], 1, 0, 0)
    both = SimpleNamespace(datasets=[one, expert, more, other], manifest={})
    assert dataset_egos(both) == {"aa": ["c1", "c3", "c5", "c9"], "bb": ["x"]}
    assert dataset_egos(expert) is None and dataset_egos(SimpleNamespace(manifest={})) is None
