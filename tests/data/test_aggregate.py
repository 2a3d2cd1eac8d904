"""The on-disk aggregate (``irlsim.data.aggregate``) on real Parquet of the tiny preset: the expert's tiny
dataset and a second, smaller collection (another seed, no test split) read as one."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from irlsim.cli import main
from irlsim.data import aggregate as aggregate_mod
from irlsim.data.aggregate import EPISODE_OFFSET, AggregateDataset, open_datasets
from irlsim.data.reader import ARRAY_NAMES, CACHE_DIR, SplitTensors, open_dataset
from irlsim.errors import IrlsimError
from tests.conftest import TINY_COLLECT, one_line


@pytest.fixture(scope="module")
def second_tiny(tmp_path_factory) -> Path:
    """A second real tiny collection: seed 1, one train and one validation episode, no test split."""
    out = tmp_path_factory.mktemp("data") / "tiny_seed1"
    sets = ["--set", "seed=1", "--set", "train_episodes=1", "--set", "test_episodes=0"]
    args = ["collect", "--config", "configs/collect/tiny.toml", "--out", str(out), *TINY_COLLECT, *sets]
    assert main(args) == 0
    return out


@pytest.fixture()
def pair(tiny_dataset: Path, second_tiny: Path, tmp_path: Path) -> tuple[Path, Path]:
    """Fresh copies of both folders (no caches), so a test may change them."""
    ignore = shutil.ignore_patterns(CACHE_DIR, ".lock")
    a, b = tmp_path / "expert", tmp_path / "round"
    shutil.copytree(tiny_dataset, a, ignore=ignore)
    shutil.copytree(second_tiny, b, ignore=ignore)
    return a, b


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
        assert isinstance(got, np.memmap), f"{name} is not memory-mapped"
        assert got.dtype == want.dtype and got.shape == want.shape, name
        assert np.asarray(got).tobytes() == want.tobytes(), f"{name} differs"  # byte-equal, NaN included


def _files(folder: Path) -> dict[str, tuple[int, int]]:
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in sorted(folder.iterdir())}


def test_aggregate_is_the_concatenation_on_disk(pair, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(aggregate_mod, "CHUNK_CYCLES", 7)  # chunks that split episodes and parts
    agg = open_datasets(list(pair))
    assert isinstance(agg, AggregateDataset)
    for split in ("train", "validation"):
        tensors = agg.split_tensors(split)
        expected = _concatenated(pair, split)
        _assert_equal(tensors, expected)
        folder = agg.cache_dir(split)
        assert folder.parent.parent == pair[0] / CACHE_DIR and folder.parent.name.startswith("aggregate-")
        assert Path(tensors.features.filename).parent == folder
        assert not [p for p in folder.iterdir() if p.name.startswith(".")], "temporary files left behind"
        # both kinds of folder, in order, histories never across folders
        n0 = open_dataset(pair[0]).split_tensors(split).n_cycles
        assert 0 < n0 < tensors.n_cycles
        assert (tensors.episode[n0:] >= EPISODE_OFFSET).all() and (
            tensors.episode[:n0] < EPISODE_OFFSET
        ).all()
    head = agg.split_tensors("train", max_cycles=10)
    assert head.n_cycles == 10 and isinstance(head.features, np.memmap)
    assert np.asarray(head.distances).tobytes() == _concatenated(pair, "train")["distances"][:10].tobytes()


def test_split_of_the_first_folder_only_is_its_own_cache(pair) -> None:
    test = open_datasets(list(pair)).split_tensors("test")  # the second folder has no test episode
    assert Path(test.features.filename).parent == pair[0] / CACHE_DIR / "test"
    _assert_equal(test, _concatenated(pair, "test"))


def test_aggregate_cache_is_reused(pair, monkeypatch: pytest.MonkeyPatch) -> None:
    agg = open_datasets(list(pair))
    agg.split_tensors("train")
    before = _files(agg.cache_dir("train"))
    monkeypatch.setattr(AggregateDataset, "_build_cache", lambda *a: pytest.fail("aggregate rebuilt"))
    again = open_datasets(list(pair))
    _assert_equal(again.split_tensors("train"), _concatenated(pair, "train"))
    assert _files(again.cache_dir("train")) == before


def test_changed_part_rebuilds_the_aggregate(pair) -> None:
    a, b = pair
    agg = open_datasets([a, b])
    old = np.array(agg.split_tensors("train").demo_distance)
    before = _files(agg.cache_dir("train"))
    # new content in the second folder's episode (as a re-collection would write): its reader cache and
    # then the aggregate are rebuilt
    path = next((b / "train").glob("*.cycles.parquet"))
    t = pq.read_table(path)
    i = t.schema.get_field_index("demo_distance")
    changed = t.set_column(i, t.schema.field(i), pa.array(t.column(i).to_numpy() + np.float32(1)))
    pq.write_table(changed.replace_schema_metadata(t.schema.metadata), path)
    tensors = open_datasets([a, b]).split_tensors("train")
    assert _files(agg.cache_dir("train")) != before
    expected = _concatenated(pair, "train")
    _assert_equal(tensors, expected)
    n0 = open_dataset(a).split_tensors("train").n_cycles
    assert old[:n0].tobytes() == expected["demo_distance"][:n0].tobytes()
    np.testing.assert_allclose(expected["demo_distance"][n0:], old[n0:] + 1)
    # a deleted aggregate cache is simply rebuilt
    shutil.rmtree(agg.cache_dir("train"))
    _assert_equal(open_datasets([a, b]).split_tensors("train"), expected)
    # another manifest (another identity) is another aggregate: another folder
    manifest = json.loads((b / "manifest.json").read_text())
    manifest["created_by"] += " (edited)"
    (b / "manifest.json").write_text(json.dumps(manifest))
    other = open_datasets([a, b])
    assert other.cache_dir("train") != agg.cache_dir("train")
    _assert_equal(other.split_tensors("train"), expected)


def test_folder_order_is_kept(pair) -> None:
    b_first = open_datasets(list(pair[::-1]))
    _assert_equal(b_first.split_tensors("train"), _concatenated(pair[::-1], "train"))
    assert b_first.cache_dir("train").parent.parent == pair[1] / CACHE_DIR


def test_no_disk_for_the_aggregate_is_one_line(pair, monkeypatch: pytest.MonkeyPatch) -> None:
    from irlsim import outputs

    agg = open_datasets(list(pair))
    for d in agg.datasets:
        d.split_tensors("train")  # the folders' own caches first: only the aggregate lacks room
    monkeypatch.setattr(outputs, "free_bytes", lambda folder: 1000)
    with pytest.raises(IrlsimError) as e:
        agg.split_tensors("train")
    msg = one_line(e)
    assert "aggregate of 2 datasets" in msg and "free" in msg and "aggregate fewer datasets" in msg
    folder = agg.cache_dir("train")
    assert not folder.exists() or not list(folder.iterdir())
