"""Robustness of the dataset reader and writer: incomplete datasets, corrupt files, concurrent cache
builds, and the ways third-party tools open a dataset folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from irlsim.data import reader as reader_mod
from irlsim.data.reader import open_dataset


def test_two_readers_building_the_cache_at_once(dataset: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A second reader builds the whole cache while the first is half way: both must succeed and leave
    the same arrays (with fixed temporary names the second would overwrite the first's files)."""
    real = reader_mod.iter_policy_groups
    nested: list[np.ndarray] = []

    def interleaved(*args, **kwargs):
        if not nested:
            nested.append(np.zeros(0))  # only once, and not inside the nested build
            nested[0] = np.array(open_dataset(dataset).split_tensors("train").features)
        yield from real(*args, **kwargs)

    monkeypatch.setattr(reader_mod, "iter_policy_groups", interleaved)
    first = np.array(open_dataset(dataset).split_tensors("train").features)
    monkeypatch.undo()
    assert first.shape == nested[0].shape and first.shape[0] == 120
    np.testing.assert_array_equal(first, nested[0])
    cache = dataset / reader_mod.CACHE_DIR / "train"
    assert not list(cache.glob(".*")), "temporary files left behind"
    # the cache both wrote is valid: a third reader reuses it without rebuilding
    monkeypatch.setattr(reader_mod.Dataset, "_build_cache", lambda *a: pytest.fail("cache rebuilt"))
    np.testing.assert_array_equal(np.array(open_dataset(dataset).split_tensors("train").features), first)


def test_failed_cache_build_leaves_no_temporary_file(dataset: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args, **kwargs):
        raise OSError("disk full")
        yield  # pragma: no cover - makes this a generator

    monkeypatch.setattr(reader_mod, "iter_policy_groups", broken)
    with pytest.raises(OSError, match="disk full"):
        open_dataset(dataset).split_tensors("train")
    cache = dataset / reader_mod.CACHE_DIR / "train"
    assert sorted(p.name for p in cache.iterdir()) == []
