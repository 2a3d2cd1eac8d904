"""The aggregate (``irlsim.data.aggregate``) on real Parquet of the tiny preset: the expert's tiny dataset
and a second, smaller collection (another seed, no test split) read as one, in place: a view over each
folder's own cache, with the bytes of their concatenation and no copy on disk."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim.data.aggregate import EPISODE_OFFSET, AggregateDataset, open_datasets
from irlsim.data.cache import CACHE_DIR, cache_files
from irlsim.data.lz4rows import Lz4Rows
from irlsim.data.npy import RowConcat
from irlsim.data.reader import Dataset, open_dataset
from irlsim.data.tensors import ARRAY_NAMES, POLICY_ARRAYS, SplitTensors


def _concatenated(folders: tuple[Path, ...], split: str) -> dict[str, np.ndarray]:
    """What the aggregate must hold: the folders' own split arrays concatenated in memory, ids offset."""
    parts = [(i, open_dataset(f)) for i, f in enumerate(folders)]
    tensors = [(i, d.split_tensors(split)) for i, d in parts if d.episodes(split)]
    out = {}
    for name in ARRAY_NAMES:
        cols = [np.asarray(getattr(t, name)) for _, t in tensors]
        if name == "episode":
            cols = [
                (c + i * EPISODE_OFFSET).astype(np.int32) for (i, _), c in zip(tensors, cols, strict=True)
            ]
        out[name] = np.concatenate(cols)
    return out


def _assert_equal(tensors: SplitTensors, expected: dict[str, np.ndarray]) -> None:
    for name, want in expected.items():
        got = getattr(tensors, name)
        assert got.dtype == want.dtype and got.shape == want.shape, name
        assert np.asarray(got).tobytes() == want.tobytes(), f"{name} differs"  # byte-equal, NaN included


def _files(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file below ``folder`` (relative path -> inode, mtime)."""
    return {
        p.relative_to(folder).as_posix(): (p.stat().st_ino, p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _cache_files(splits: tuple[str, ...]) -> set[str]:
    """What a folder's reader caches of ``splits`` hold, and all they hold."""
    return {f"{s}/{p.name}" for s in splits for p in [*cache_files(Path(s)), Path("meta.json")]}


def test_aggregate_is_a_view_of_the_folders_own_caches(pair) -> None:
    agg = open_datasets(list(pair))
    assert isinstance(agg, AggregateDataset)
    for split in ("train", "validation"):
        tensors = agg.split_tensors(split)
        expected = _concatenated(pair, split)
        _assert_equal(tensors, expected)  # the round trip: the per-folder reads, one after the other
        # read in place: each per-policy array views the folders' own cache files (compressed rows)
        for name in POLICY_ARRAYS:
            view = getattr(tensors, name)
            assert isinstance(view, RowConcat), name
            assert [Path(p.filename) for p in view.parts] == [
                f / CACHE_DIR / split / f"{name}.lz4" for f in pair
            ]
        # rows as training gathers them (sorted batches, across both folders) and pairs of indexes
        rows = np.sort(np.random.default_rng(0).choice(tensors.n_cycles, 12, replace=False))
        assert tensors.features[rows].tobytes() == expected["features"][rows].tobytes()
        cols = np.asarray(tensors.demo_index)[rows].clip(0)
        assert tensors.labels[rows, cols, 0].tobytes() == expected["labels"][rows, cols, 0].tobytes()
        # both kinds of folder, in order, histories never across folders
        n0 = open_dataset(pair[0]).split_tensors(split).n_cycles
        assert 0 < n0 < tensors.n_cycles
        assert (tensors.episode[n0:] >= EPISODE_OFFSET).all() and (
            tensors.episode[:n0] < EPISODE_OFFSET
        ).all()
    head = agg.split_tensors("train", max_cycles=10)
    assert head.n_cycles == 10 and isinstance(head.features, Lz4Rows)  # rows of the first folder only
    assert np.asarray(head.distances).tobytes() == _concatenated(pair, "train")["distances"][:10].tobytes()
    # no copy on disk: each folder holds its own caches of the splits read, and nothing else
    for folder in pair:
        assert set(_files(folder / CACHE_DIR)) == _cache_files(("train", "validation")), folder


def test_split_of_the_first_folder_only_is_its_own_cache(pair) -> None:
    test = open_datasets(list(pair)).split_tensors("test")  # the second folder has no test episode
    assert Path(test.features.filename).parent == pair[0] / CACHE_DIR / "test"
    _assert_equal(test, _concatenated(pair, "test"))


def test_folders_caches_are_reused(pair, monkeypatch: pytest.MonkeyPatch) -> None:
    open_datasets(list(pair)).split_tensors("train")
    before = [_files(f / CACHE_DIR) for f in pair]
    monkeypatch.setattr(Dataset, "_build_cache", lambda *a: pytest.fail("a cache was rebuilt"))
    again = open_datasets(list(pair))
    _assert_equal(again.split_tensors("train"), _concatenated(pair, "train"))
    assert [_files(f / CACHE_DIR) for f in pair] == before


def test_changed_folder_rebuilds_its_own_cache_only(pair, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = pair
    old = np.array(open_datasets([a, b]).split_tensors("train").demo_distance)
    before_a, before_b = _files(a / CACHE_DIR), _files(b / CACHE_DIR)
    # new content in the second folder's episode (as a re-collection would write)
    path = next((b / "train").glob("*.cycles.parquet"))
    t = pq.read_table(path)
    i = t.schema.get_field_index("demo_distance")
    changed = t.set_column(i, t.schema.field(i), pa.array(t.column(i).to_numpy() + np.float32(1)))
    pq.write_table(changed.replace_schema_metadata(t.schema.metadata), path)
    capsys.readouterr()
    tensors = open_datasets([a, b]).split_tensors("train")
    # the out-of-date cache is named and removed before its rebuild (not kept beside the new one)
    out = capsys.readouterr().out
    assert f"removed {b / CACHE_DIR / 'train'} (" in out and "out of date" in out, out
    assert _files(a / CACHE_DIR) == before_a
    after_b = _files(b / CACHE_DIR)
    assert {k for k in after_b if before_b[k] != after_b[k]} == {k for k in after_b if k.startswith("train/")}
    expected = _concatenated(pair, "train")
    _assert_equal(tensors, expected)
    n0 = open_dataset(a).split_tensors("train").n_cycles
    assert old[:n0].tobytes() == expected["demo_distance"][:n0].tobytes()
    np.testing.assert_allclose(expected["demo_distance"][n0:], old[n0:] + 1)
    # a deleted cache is simply rebuilt
    shutil.rmtree(b / CACHE_DIR)
    _assert_equal(open_datasets([a, b]).split_tensors("train"), expected)


def test_folder_order_is_kept(pair) -> None:
    b_first = open_datasets(list(pair[::-1]))
    _assert_equal(b_first.split_tensors("train"), _concatenated(pair[::-1], "train"))


class _Copy:
    """The aggregate as one concatenated copy (what training read before aggregates were views): the
    same manifest and identity, its splits' arrays concatenated in memory."""

    def __init__(self, agg: AggregateDataset, folders: tuple[Path, ...]) -> None:
        self.manifest, self.identity = agg.manifest, agg.identity
        self.splits, self.episodes = agg.splits, agg.episodes
        self.tensors = {s: SplitTensors(**_concatenated(folders, s)) for s in ("train", "validation")}

    def split_tensors(self, split: str) -> SplitTensors:
        return self.tensors[split]


def test_training_on_the_view_is_training_on_a_copy(pair, tmp_path) -> None:
    """Same seed, same batches in the same order, same bytes: the weights, the selected epoch and every
    metric of a training on the view are those of a training on the concatenated copy."""
    import dataclasses

    import torch

    from irlsim.train import Stage1Config, train_stage1

    agg = open_datasets(list(pair))
    cfg = dataclasses.replace(
        Stage1Config.smoke(), models=("LIRL", "PACNN+S"), epochs=2, safe_demos=True, stop_demos=True
    )
    train_stage1(agg, cfg, tmp_path / "view")
    train_stage1(_Copy(agg, pair), cfg, tmp_path / "copy")
    for name in cfg.models:
        view, copy = (
            torch.load(tmp_path / r / name / "checkpoint.pt", weights_only=True) for r in ("view", "copy")
        )
        assert view.keys() == copy.keys()
        for k, v in view["state_dict"].items():
            assert v.numpy().tobytes() == copy["state_dict"][k].numpy().tobytes(), (name, k)
        assert view["metrics"] == copy["metrics"] and view["best"]["epoch"] == copy["best"]["epoch"]
        assert view["feature_stats"] == copy["feature_stats"] and view["dataset"] == copy["dataset"]
