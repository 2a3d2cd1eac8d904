"""Memory-mapped ``.npy`` files written atomically (:class:`AtomicNpys`: the reader's caches) and read
as one along their rows (:class:`RowConcat`: an aggregate's splits over its folders' caches)."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.utils import atomic_path


class AtomicNpys:
    """Memory-mapped .npy files opened under unique temporary names (``atomic_path``), renamed into place
    on success and removed on failure, so two processes building the same cache never share a file."""

    def __init__(self, folder: Path, specs: dict[str, tuple[tuple[int, ...], Any]]) -> None:
        self.folder = folder
        self.specs = specs
        self.stack = ExitStack()
        self.maps: dict[str, np.memmap] = {}

    def __enter__(self) -> dict[str, np.memmap]:
        try:
            for name, (shape, dtype) in self.specs.items():
                tmp = self.stack.enter_context(atomic_path(self.folder / f"{name}.npy"))
                self.maps[name] = np.lib.format.open_memmap(tmp, mode="w+", dtype=dtype, shape=shape)
        except BaseException as exc:
            self.maps.clear()
            self.stack.__exit__(type(exc), exc, exc.__traceback__)  # with an exception: delete, not rename
            raise
        return self.maps

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        for m in self.maps.values():
            m.flush()
        self.maps.clear()  # unmapped before the rename
        self.stack.__exit__(exc_type, exc, tb)


class RowConcat:
    """Arrays of one dtype and one shape after the first axis read as their concatenation along axis 0,
    without a copy: an aggregate's split over its folders' memory-mapped caches.

    Indexing takes the row index first, then what numpy takes for the other axes:

    - rows an int: that row of its part (a view);
    - rows a slice of step 1: the parts' slices (views, no data read), a plain array when they lie in
      one part; the other axes only basic indices (ints, slices);
    - rows an int array or a [C] bool mask: the rows gathered in the order given (one fancy index per
      part, so a memory map reads only those rows); the other axes basic indices, or int arrays shaped
      like rows (pairs such as ``x[rows, cols]``).

    ``np.asarray`` concatenates every part (reads all of it): index rows first.
    """

    def __init__(self, parts: list[np.ndarray]) -> None:
        if not parts:
            raise ValueError("RowConcat needs one part or more")
        tail, dtype = parts[0].shape[1:], parts[0].dtype
        for p in parts:
            if p.shape[1:] != tail or p.dtype != dtype:
                raise ValueError(f"RowConcat parts differ: {p.dtype}{list(p.shape)} vs {dtype}[..., {tail}]")
        self.parts = list(parts)
        #: [P + 1] first row of each part, then the row count
        self.bounds = np.cumsum([0, *(len(p) for p in parts)], dtype=np.int64)
        self.shape: tuple[int, ...] = (int(self.bounds[-1]), *tail)
        self.dtype = dtype

    @property
    def ndim(self) -> int:
        return len(self.shape)

    @property
    def nbytes(self) -> int:
        return sum(int(p.nbytes) for p in self.parts)

    def __len__(self) -> int:
        return self.shape[0]

    def __repr__(self) -> str:
        return f"RowConcat({self.dtype}{list(self.shape)}, {len(self.parts)} parts)"

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> np.ndarray:
        if copy is False and len(self.parts) > 1:
            raise ValueError("RowConcat of several parts: a copy cannot be avoided")
        out = np.concatenate(self.parts) if len(self.parts) > 1 else np.asarray(self.parts[0])
        return out if dtype is None else out.astype(dtype, copy=False)

    def __getitem__(self, key: Any) -> Any:
        key = key if isinstance(key, tuple) else (key,)
        rows, rest = (slice(None), key) if key and key[0] is Ellipsis else (key[0], key[1:])
        if any(k is None for k in key):
            raise IndexError("RowConcat does not add axes (None): index, then reshape the result")
        if isinstance(rows, (int, np.integer)):
            i = int(rows) + len(self) if int(rows) < 0 else int(rows)
            if not 0 <= i < len(self):
                raise IndexError(f"row {int(rows)} is out of bounds for {len(self)} rows")
            p = int(np.searchsorted(self.bounds, i, side="right")) - 1
            return self.parts[p][(i - int(self.bounds[p]), *rest)]
        if isinstance(rows, slice):
            start, stop, step = rows.indices(len(self))
            if step == 1:
                return self._slice(start, max(start, stop), rest)
            rows = np.arange(start, stop, step)
        return self._gather(np.asarray(rows), rest)

    def _slice(self, start: int, stop: int, rest: tuple[Any, ...]) -> Any:
        _check_basic(rest)
        pieces = []
        for p, part in enumerate(self.parts):
            a, b = int(self.bounds[p]), int(self.bounds[p + 1])
            if a < stop and start < b:
                pieces.append(part[(slice(max(start - a, 0), min(stop, b) - a), *rest)])
        if not pieces:  # an empty range: an empty view of the first part
            return self.parts[0][(slice(0, 0), *rest)]
        return pieces[0] if len(pieces) == 1 else RowConcat(pieces)

    def _gather(self, rows: np.ndarray, rest: tuple[Any, ...]) -> np.ndarray:
        rows, flat = flat_rows(rows, len(self))
        paired = [isinstance(r, (np.ndarray, list)) for r in rest]  # arrays pair up with the rows
        if any(paired):
            rest = tuple(np.asarray(r) if a else r for r, a in zip(rest, paired, strict=True))
            if rows.ndim != 1 or any(
                np.shape(r) != rows.shape for r, a in zip(rest, paired, strict=True) if a
            ):
                raise IndexError("RowConcat: arrays indexing other axes must have the rows' 1-D shape")
        else:
            _check_basic(rest)
        which = np.searchsorted(self.bounds, flat, side="right") - 1
        out: np.ndarray | None = None
        for p in np.unique(which):
            m = which == p
            sub = tuple(r[m] if a else r for r, a in zip(rest, paired, strict=True))
            got = np.asarray(self.parts[p][(flat[m] - self.bounds[p], *sub)])
            if out is None:
                out = np.empty((len(flat), *got.shape[1:]), got.dtype)
            out[m] = got
        if out is None:  # no rows: what the first part gives for none
            empty = tuple(np.asarray(r)[:0] if a else r for r, a in zip(rest, paired, strict=True))
            out = np.asarray(self.parts[0][(flat, *empty)])
        return out.reshape(*rows.shape, *out.shape[1:])

    def take_per_row(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """``out[i, j] = self[rows[i], cols[i, j]]`` (see :func:`take_per_row`): one call per part."""
        flat, cols = per_row_index(rows, cols, len(self))
        which = np.searchsorted(self.bounds, flat, side="right") - 1
        out = np.empty((len(flat), cols.shape[1], *self.shape[2:]), self.dtype)
        for p in np.unique(which):
            m = which == p
            out[m] = take_per_row(self.parts[p], flat[m] - self.bounds[p], cols[m])
        return out


def _check_basic(rest: tuple[Any, ...]) -> None:
    """Only ints, slices and Ellipsis for the axes after the rows."""
    for r in rest:
        if not (isinstance(r, (int, np.integer, slice)) or r is Ellipsis):
            kind = type(r).__name__
            raise IndexError(f"RowConcat: an index of type {kind} for an axis after the rows is not taken")


def flat_rows(rows: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(the int rows, flattened in range 0..n-1) of a row index into ``n`` rows: ints (negative from the
    end) or a [n] bool mask; out of bounds or another dtype is an IndexError."""
    if rows.dtype == np.bool_:
        if rows.shape != (n,):
            raise IndexError(f"a boolean row mask must have shape ({n},), not {rows.shape}")
        rows = np.flatnonzero(rows)
    if rows.size and not np.issubdtype(rows.dtype, np.integer):
        raise IndexError(f"rows must be integers or a boolean mask, not {rows.dtype}")
    flat = rows.astype(np.int64).ravel()
    flat = np.where(flat < 0, flat + n, flat)
    if flat.size and (flat.min() < 0 or flat.max() >= n):
        raise IndexError(f"a row index is out of bounds for {n} rows")
    return rows, flat


def take_per_row(a: Any, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``a[rows[:, None], cols]`` of a [C, N, ...] array: ``out[i, j] = a[rows[i], cols[i, j]]``, a few
    columns (policies) of each row, [len(rows), cols.shape[1], ...].

    A :class:`RowConcat` or :class:`irlsim.data.lz4rows.Lz4Rows` takes the columns as it reads each row
    (a compressed row is decompressed once and never copied whole); any other array is indexed by numpy.
    The values are numpy's, byte for byte."""
    if hasattr(a, "take_per_row"):
        return np.asarray(a.take_per_row(rows, cols))
    flat, cols = per_row_index(rows, cols, len(a))
    return np.asarray(a[flat[:, None], cols])


def per_row_index(rows: np.ndarray, cols: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(1-D rows in range, [len(rows), k] int columns) of :func:`take_per_row`'s arguments."""
    rows, flat = flat_rows(np.asarray(rows), n)
    cols = np.asarray(cols)
    if rows.ndim != 1 or cols.ndim != 2 or len(cols) != len(flat) or cols.dtype.kind not in "iu":
        raise IndexError(
            f"take_per_row takes 1-D rows and a [rows, k] int array of columns, got rows {rows.shape} and "
            f"columns {cols.dtype}{list(cols.shape)}"
        )
    return flat, cols
