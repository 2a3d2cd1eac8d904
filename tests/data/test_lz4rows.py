"""The cache's compressed rows (irlsim.data.lz4rows): what is read back is what was written, indexed as
numpy indexes the array; a failed write leaves no file."""

from pathlib import Path

import numpy as np
import pytest

from irlsim.data.lz4rows import Lz4Rows, Lz4RowsWriter, files
from irlsim.data.npy import RowConcat, take_per_row


def _write(folder: Path, arrays: dict[str, np.ndarray], block: int = 3) -> dict[str, Lz4Rows]:
    specs = {k: (a.shape, a.dtype) for k, a in arrays.items()}
    with Lz4RowsWriter(folder, specs) as w:
        for k, a in arrays.items():
            for s in range(0, len(a), block):  # in blocks, as the reader appends row groups
                w[k].append(a[s : s + block])
    return {k: Lz4Rows.open(folder, k, a.shape[1:], a.dtype) for k, a in arrays.items()}


@pytest.fixture
def arrays(tmp_path):
    rng = np.random.default_rng(0)
    f = rng.normal(size=(11, 7, 5)).astype(np.float32)
    f[2, 3, 1] = np.nan
    labels = rng.random((11, 7, 3)) < 0.3
    return {"f": f, "labels": labels}, _write(tmp_path, {"f": f, "labels": labels})


def test_rows_read_back_byte_for_byte(arrays):
    want, got = arrays
    for k in want:
        a, r = want[k], got[k]
        assert r.shape == a.shape and r.dtype == a.dtype and len(r) == len(a) and r.nbytes == a.nbytes
        assert np.asarray(r).tobytes() == a.tobytes()  # NaN included
        rows = np.array([9, 0, 4, 4, -1])
        assert r[rows].tobytes() == a[rows].tobytes()
        mask = np.arange(len(a)) % 3 == 0
        assert r[mask].tobytes() == a[mask].tobytes()
        assert r[3].tobytes() == a[3].tobytes() and r[-2, 1].tobytes() == a[-2, 1].tobytes()
        assert r[2:9:2, :, 1].tobytes() == a[2:9:2, :, 1].tobytes()
        assert r[..., 0].tobytes() == a[..., 0].tobytes()
        cols = np.array([6, 0, 3])
        assert r[np.array([1, 5, 10]), cols].tobytes() == a[np.array([1, 5, 10]), cols].tobytes()
        view = r[4:8]  # a view: nothing decompressed until it is indexed
        assert isinstance(view, Lz4Rows) and view.shape == a[4:8].shape
        assert np.asarray(view).tobytes() == a[4:8].tobytes() and view[1:3][0].tobytes() == a[5].tobytes()
        assert r[5:5].shape == (0, *a.shape[1:]) and r[np.array([], int)].shape == (0, *a.shape[1:])


def test_a_few_columns_of_each_row_are_numpys(arrays, tmp_path):
    """take_per_row (a training step's policy sample) gives numpy's a[rows[:, None], cols], byte for byte,
    from compressed rows, a concatenation of them and a plain array alike."""
    want, got = arrays
    rows = np.array([10, 0, 4, 4, -1])
    cols = np.random.default_rng(1).integers(0, 7, size=(5, 3))
    for k in want:
        a = want[k]
        expect = a[rows[:, None], cols].tobytes()
        whole = RowConcat([got[k][:6], a[6:]])  # a compressed part and a plain one
        for r in (got[k], whole, a):
            assert take_per_row(r, rows, cols).tobytes() == expect
    with pytest.raises(IndexError, match="take_per_row takes 1-D rows"):
        take_per_row(got["f"], rows, cols[:4])
    with pytest.raises(IndexError, match="out of bounds"):
        take_per_row(got["f"], np.array([11]), cols[:1])


def test_bad_indexes_are_refused(arrays):
    _, got = arrays
    r = got["f"]
    with pytest.raises(IndexError, match="out of bounds"):
        r[11]
    with pytest.raises(IndexError, match="out of bounds"):
        r[np.array([0, 11])]
    with pytest.raises(IndexError, match="boolean row mask"):
        r[np.ones(3, bool)]
    with pytest.raises(IndexError, match="integers"):
        r[np.array([0.5])]
    with pytest.raises(IndexError, match="None"):
        r[:, None]


def test_redundant_rows_take_less_disk(tmp_path):
    a = np.zeros((20, 64, 4), np.float32)  # mostly zero, as the labels and many feature costs are
    a[:, ::8, 0] = np.arange(8, dtype=np.float32)
    _write(tmp_path, {"a": a})
    data, offsets = files(tmp_path, "a")
    assert data.stat().st_size < a.nbytes / 3
    assert np.load(offsets)[-1] == data.stat().st_size


def test_a_failed_write_leaves_no_file(tmp_path):
    a = np.zeros((4, 3), np.float32)
    with (
        pytest.raises(ValueError, match="rows of shape"),
        Lz4RowsWriter(tmp_path, {"a": (a.shape, a.dtype)}) as w,
    ):
        w["a"].append(a[:2])
        w["a"].append(np.zeros((2, 5), np.float32))
    assert list(tmp_path.iterdir()) == []
