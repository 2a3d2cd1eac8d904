"""Caches nobody reads any more are removed by the command that made them obsolete, one line each
(``irlsim.data.prune``), and nothing that is not a cache irlsim wrote is ever removed. Real Parquet and
real collections of the tiny preset; the files on disk are asserted."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from irlsim.cli import main
from irlsim.data.cache import CACHE_DIR, cache_files
from irlsim.data.layout import remove_episode
from irlsim.data.npy import AtomicNpys
from irlsim.data.reader import open_dataset
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.data.tensors import ARRAY_NAMES
from irlsim.utils import write_json
from tests.conftest import TINY_COLLECT

CACHE_FILES = {*(p.name for p in cache_files(Path("."))), "meta.json"}


def _files(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file below ``folder`` (relative path -> inode, mtime)."""
    return {
        p.relative_to(folder).as_posix(): (p.stat().st_ino, p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _own_caches(splits: tuple[str, ...]) -> set[str]:
    return {f"{s}/{n}" for s in splits for n in CACHE_FILES}


def _old_aggregate_copy(folders: tuple[Path, ...], key: str, split: str) -> Path:
    """What an older irlsim wrote for ``irlsim train --data FOLDERS`` in the first folder: the splits
    concatenated into ``.cache/aggregate-<key>/<split>/`` (its writer: AtomicNpys, meta.json last)."""
    parts = [open_dataset(f).split_tensors(split) for f in folders]
    cat = {n: np.concatenate([np.asarray(getattr(t, n)) for t in parts]) for n in ARRAY_NAMES}
    out = folders[0] / CACHE_DIR / f"aggregate-{key}" / split
    out.mkdir(parents=True)
    with AtomicNpys(out, {n: (a.shape, a.dtype) for n, a in cat.items()}) as maps:
        for n, m in maps.items():
            m[:] = cat[n]
    meta = {
        "cache_version": 2,
        "schema_version": SCHEMA_VERSION,
        "split": split,
        "cycles": len(cat["episode"]),
    }
    write_json(out / "meta.json", {**meta, "parts": []})
    return out


def test_old_aggregate_copies_go_and_nothing_else(pair, tmp_path, capsys) -> None:
    a, b = pair
    k1, k2, k3 = "0123456789abcdef", "fedcba9876543210", "00000000000000ff"
    old = [_old_aggregate_copy(pair, k1, s) for s in ("train", "validation")]
    old.append(_old_aggregate_copy((b, a), k3, "train"))  # b was the first folder of another aggregate
    # what irlsim did not write, or is still writing, stays: a user's file in a copy, a build without its
    # meta.json yet, a folder whose meta.json is not a cache's, a file in .cache itself
    (old[0] / "notes.txt").write_text("mine")
    building = a / CACHE_DIR / f"aggregate-{k2}" / "train"
    building.mkdir(parents=True)
    (building / ".features.npy.x1y2.tmp").write_bytes(b"\0" * 64)
    (a / CACHE_DIR / "mine").mkdir()
    (a / CACHE_DIR / "mine" / "meta.json").write_text(json.dumps({"mine": True}))
    (a / CACHE_DIR / "README.txt").write_text("mine")
    keep = {
        f"aggregate-{k1}/train/notes.txt",
        f"aggregate-{k2}/train/.features.npy.x1y2.tmp",
        "mine/meta.json",
        "README.txt",
    }
    runs = tmp_path / "runs"
    args = ["train", "--stage", "1", "--config", "configs/train/tiny_stage1.toml", "--out", str(runs)]
    args += ["--data", str(a), "--data", str(b), "--set", 'models=["LIRL"]', "--set", "epochs=1"]
    # bad input is one line before any work: nothing removed yet
    before = [_files(f / CACHE_DIR) for f in pair]
    assert main([*args, "--scenario-select", "nowhere"]) == 2
    assert [_files(f / CACHE_DIR) for f in pair] == before
    capsys.readouterr()
    assert main(args) == 0
    out = capsys.readouterr().out
    for folder in old:
        line = next((x for x in out.splitlines() if x.startswith(f"removed {folder} (")), None)
        assert line is not None and "a copy of an aggregate's split that an older irlsim made" in line, out
    assert "1 other files left in it: notes.txt" in out
    assert set(_files(a / CACHE_DIR)) == _own_caches(("train", "validation")) | keep
    assert set(_files(b / CACHE_DIR)) == _own_caches(("train", "validation"))
    assert not (b / CACHE_DIR / f"aggregate-{k3}").exists()
    # both folders trained on (--data given twice is both, not the last)
    summary = json.loads((runs / "stage1" / "summary.json").read_text())
    assert summary["data"] == [str(a), str(b)]


def test_a_recollected_episode_obsoletes_its_caches(tiny_dataset, tmp_path, capsys) -> None:
    ds = tmp_path / "ds"
    shutil.copytree(tiny_dataset, ds, ignore=shutil.ignore_patterns(CACHE_DIR, ".lock"))
    whole = open_dataset(ds)
    before = {s: whole.split_tensors(s) for s in ("train", "validation", "test")}
    train = {n: np.array(getattr(before["train"], n)) for n in ARRAY_NAMES}
    (scenario,) = whole.scenarios
    open_dataset(ds, (scenario,)).split_tensors("train")  # a selection's cache of its own
    selection = next((ds / CACHE_DIR).glob("scenarios-*"))
    # an older irlsim's cache of the test split: another cache version
    meta = json.loads((ds / CACHE_DIR / "test" / "meta.json").read_text())
    old = {k: v for k, v in meta.items() if k not in ("files", "meta_sha256")}  # what it did not write
    (ds / CACHE_DIR / "test" / "meta.json").write_text(json.dumps({**old, "cache_version": 1}))
    kept = {k: v for k, v in _files(ds / CACHE_DIR).items() if k.startswith("validation/")}
    # an episode lost and collected again: the caches built from its old file are obsolete
    remove_episode(ds, "train", whole.episodes("train")[0])
    capsys.readouterr()
    assert main(["collect", "--config", "configs/collect/tiny.toml", "--out", str(ds), *TINY_COLLECT]) == 0
    out = capsys.readouterr().out
    expect = {
        ds / CACHE_DIR / "train": "built from other files than the split has now",
        selection / "train": "built from other files than the split has now",
        ds / CACHE_DIR / "test": "written by another irlsim (cache version 1",
    }
    for folder, why in expect.items():
        line = next((x for x in out.splitlines() if x.startswith(f"removed {folder} (")), None)
        assert line is not None and why in line, out
    assert _files(ds / CACHE_DIR) == kept  # the validation split's cache is valid: it stays, untouched
    # the reader builds the train split again from the new files: the same bytes (same seed)
    again = open_dataset(ds).split_tensors("train")
    for n, want in train.items():
        assert np.asarray(getattr(again, n)).tobytes() == want.tobytes(), n


def test_stale_cache_is_removed_before_its_rebuild(tiny_dataset, tmp_path, capsys) -> None:
    ds = tmp_path / "ds"
    shutil.copytree(tiny_dataset, ds, ignore=shutil.ignore_patterns(CACHE_DIR, ".lock"))
    open_dataset(ds).split_tensors("validation")
    cache = ds / CACHE_DIR / "validation"
    (cache / "user.txt").write_text("mine")  # not irlsim's: kept through the rebuild
    path = next((ds / "validation").glob("*.cycles.parquet"))
    path.touch()  # another mtime: the cache no longer records the split's files
    capsys.readouterr()
    open_dataset(ds).split_tensors("validation")
    out = capsys.readouterr().out
    assert out.startswith(f"removed {cache} (") and "out of date" in out and "user.txt" in out, out
    assert set(_files(cache)) == CACHE_FILES | {"user.txt"}


@pytest.mark.parametrize("what", ["aggregate", "split"])
def test_nothing_is_removed_from_a_valid_folder(pair, what, capsys) -> None:
    a, b = pair
    from irlsim.data.aggregate import open_datasets

    open_datasets([a, b]).split_tensors("train")
    before = _files(a / CACHE_DIR)
    capsys.readouterr()
    opened = open_datasets([a, b]) if what == "aggregate" else open_datasets([a])
    opened.split_tensors("train")
    assert capsys.readouterr().out == "" and _files(a / CACHE_DIR) == before
