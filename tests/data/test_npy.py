"""RowConcat (irlsim.data.npy): several arrays read as their concatenation along the rows, without a copy.
Every index the training and evaluation code uses gives the bytes numpy gives on the concatenation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from irlsim.data.npy import RowConcat


@pytest.fixture()
def parts(tmp_path: Path) -> list[np.ndarray]:
    """Three memory-mapped parts [5|1|7, 4, 3] float32 with NaNs (as a cache's distances hold)."""
    rng = np.random.default_rng(0)
    out = []
    for i, rows in enumerate((5, 1, 7)):
        a = rng.normal(size=(rows, 4, 3)).astype(np.float32)
        a[a > 1.5] = np.nan
        np.save(tmp_path / f"p{i}.npy", a)
        out.append(np.load(tmp_path / f"p{i}.npy", mmap_mode="r"))
    return out


def _same(got: object, want: np.ndarray) -> None:
    got = np.asarray(got)
    assert got.dtype == want.dtype and got.shape == want.shape, (got.shape, want.shape)
    assert got.tobytes() == want.tobytes()  # byte-equal, NaN included


def test_indexes_give_the_concatenations_bytes(parts) -> None:
    view, whole = RowConcat(parts), np.concatenate(parts)
    assert view.shape == whole.shape and view.dtype == whole.dtype and len(view) == 13
    assert view.nbytes == whole.nbytes and view.ndim == 3
    rows = np.array([12, 0, 5, 5, 4, 6, -1])  # unsorted, repeated, negative, across every part
    cols = np.array([3, 0, 1, 2, 3, 0, 1])
    mask = np.zeros(13, bool)
    mask[[1, 5, 9]] = True
    for key in (
        3,
        -8,
        (5, 2),
        slice(None),
        slice(2, 11),
        slice(4, 6),
        slice(6, 7),
        slice(9, 3),
        slice(1, 12, 3),
        (slice(None), slice(None), 0),
        (Ellipsis, 1),
        (slice(3, 9), 2),
        rows,
        rows.tolist(),
        np.sort(rows),
        mask,
        (rows, cols),
        (rows, cols, 2),
        (rows, slice(None), 0),
        (rows, 1),
        np.array([], dtype=np.int64),
        rows.reshape(7, 1),
    ):
        _same(view[key], whole[key])


def test_slices_are_views_and_nest(parts) -> None:
    view, whole = RowConcat(parts), np.concatenate(parts)
    inside = view[6:9]  # rows of the third part only: a plain view of its memory map
    assert isinstance(inside, np.memmap) and np.shares_memory(inside, parts[2])
    head = view[:10]  # across parts: again a view, no data read
    assert isinstance(head, RowConcat) and len(head.parts) == 3
    labels = view[:, :, 0]  # the collision label of every policy, as get_split takes it
    assert isinstance(labels, RowConcat) and labels.shape == (13, 4)
    _same(labels[np.array([2, 7, 12]), np.array([0, 3, 1])], whole[:, :, 0][[2, 7, 12], [0, 3, 1]])
    _same(head[[9, 0, 4]], whole[:10][[9, 0, 4]])


def test_bad_indexes_are_refused(parts) -> None:
    view = RowConcat(parts)
    for key in (13, -14, np.array([13]), np.ones(12, bool), np.array([0.5])):
        with pytest.raises(IndexError):
            view[key]
    with pytest.raises(IndexError):
        view[None]
    with pytest.raises(IndexError):
        view[np.array([1, 2]), np.array([0, 1, 2])]  # arrays for other axes pair up with the rows
    with pytest.raises(ValueError):
        RowConcat([parts[0], parts[1][:, :2]])
    with pytest.raises(ValueError):
        RowConcat([])
