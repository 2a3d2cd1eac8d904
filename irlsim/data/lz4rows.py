"""Rows compressed one by one (LZ4): the reader cache's per-policy arrays.

A per-policy array [C, N, ...] of a cache is stored as ``<name>.lz4`` (each row, i.e. one planning cycle,
compressed on its own with LZ4, one after the other) and ``<name>.offsets.npy`` ([C + 1] int64: where
each row starts, then the file's size). :class:`Lz4Rows` reads it like a read-only array of rows:
random rows cost one decompression each (LZ4 decompresses at GB/s), and the file, 3-5x smaller than the
float32 rows, is what the page cache holds. Lossless: the rows read back are the bytes written.
:class:`Lz4RowsWriter` appends rows in order and renames both files into place on success.
"""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from irlsim.data.npy import flat_rows, per_row_index
from irlsim.errors import IrlsimError
from irlsim.utils import atomic_path, naming

CODEC = "lz4_raw"  # LZ4 blocks without the frame: twice the decompression speed of framed LZ4
_CODEC = pa.Codec(CODEC)
#: rows decompressed at once when a whole range is read (bounds the memory of a column read)
CHUNK = 256


def files(folder: Path, name: str) -> tuple[Path, Path]:
    """(the compressed rows, their offsets) of array ``name`` in a cache folder."""
    return folder / f"{name}.lz4", folder / f"{name}.offsets.npy"


class Lz4Rows:
    """A read-only [C, ...] array of LZ4-compressed rows.

    Indexing takes the row index first, then what numpy takes for the other axes:

    - rows a slice of step 1 and nothing else: a view (no data read), like a memory map's slice;
    - rows an int, a slice, an int array or a [C] bool mask: those rows decompressed into a new array,
      then the other axes applied to them (ints, slices, or int arrays shaped like the rows: pairs such
      as ``x[rows, cols]``), a chunk of rows at a time.

    ``np.asarray`` decompresses every row.
    """

    def __init__(
        self, data: np.ndarray, offsets: np.ndarray, tail: tuple[int, ...], dtype: Any, filename: str = ""
    ) -> None:
        self.data, self.offsets = data, offsets
        #: the compressed rows' file (as a memory map's ``filename``)
        self.filename = filename
        self.dtype = np.dtype(dtype)
        self.shape: tuple[int, ...] = (len(offsets) - 1, *tail)
        self.row_bytes = int(np.prod(tail, dtype=np.int64)) * self.dtype.itemsize

    @classmethod
    def open(cls, folder: Path, name: str, tail: tuple[int, ...], dtype: Any) -> Lz4Rows:
        path, offsets = files(folder, name)
        data = np.memmap(path, dtype=np.uint8, mode="r") if path.stat().st_size else np.zeros(0, np.uint8)
        return cls(data, np.load(offsets, mmap_mode="r"), tail, dtype, str(path))

    @property
    def ndim(self) -> int:
        return len(self.shape)

    @property
    def nbytes(self) -> int:
        """The bytes of the rows as an array (not of the file)."""
        return len(self) * self.row_bytes

    def __len__(self) -> int:
        return self.shape[0]

    def __repr__(self) -> str:
        return f"Lz4Rows({self.dtype}{list(self.shape)})"

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> np.ndarray:
        if copy is False:
            raise ValueError("Lz4Rows: reading compressed rows makes a copy")
        out = self._read(np.arange(len(self)), ())
        return out if dtype is None else out.astype(dtype, copy=False)

    def __getitem__(self, key: Any) -> Any:
        key = key if isinstance(key, tuple) else (key,)
        rows, rest = (slice(None), key) if key and key[0] is Ellipsis else (key[0], key[1:])
        if any(k is None for k in key):
            raise IndexError("Lz4Rows does not add axes (None): index, then reshape the result")
        if isinstance(rows, slice):
            start, stop, step = rows.indices(len(self))
            if step == 1 and not rest:
                stop = max(start, stop)
                return Lz4Rows(
                    self.data, self.offsets[start : stop + 1], self.shape[1:], self.dtype, self.filename
                )
            rows = np.arange(start, stop, step)
        if isinstance(rows, (int, np.integer)):
            i = int(rows) + len(self) if int(rows) < 0 else int(rows)
            if not 0 <= i < len(self):
                raise IndexError(f"row {int(rows)} is out of bounds for {len(self)} rows")
            return self._read(np.array([i]), ())[0][rest] if rest else self._read(np.array([i]), ())[0]
        rows, flat = flat_rows(np.asarray(rows), len(self))
        out = self._read(flat, rest)
        return out.reshape(*rows.shape, *out.shape[1:])

    def take_per_row(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """``out[i, j] = self[rows[i], cols[i, j]]`` (:func:`irlsim.data.npy.take_per_row`): each row
        decompressed and its columns taken at once, without copying the whole row out."""
        flat, cols = per_row_index(rows, cols, len(self))
        out = np.empty((len(flat), cols.shape[1], *self.shape[2:]), self.dtype)
        starts, ends = self.offsets[flat], self.offsets[flat + 1]
        for j in range(len(flat)):
            out[j] = self._row(int(starts[j]), int(ends[j])).view(self.dtype).reshape(self.shape[1:])[cols[j]]
        return out

    def _row(self, a: int, b: int) -> np.ndarray:
        """The row stored in bytes a..b, decompressed; a row that cannot be decoded is one line naming the
        file (the cache changed after it was verified)."""
        try:
            if not 0 <= a <= b <= len(self.data):
                raise ValueError(f"bytes {a}..{b} of {len(self.data)}")
            raw = _CODEC.decompress(self.data[a:b], decompressed_size=self.row_bytes, asbytes=False)
            if raw.size != self.row_bytes:
                raise ValueError(f"{raw.size} bytes decoded, {self.row_bytes} expected")
        except (pa.ArrowException, ValueError, OSError) as exc:
            raise IrlsimError(
                f"cache file {self.filename} cannot be decoded ({exc}): delete it (the next command "
                "rebuilds the cache from the Parquet files)"
            ) from None
        return np.frombuffer(raw, np.uint8)  # one copy: from Arrow's buffer into the rows

    def _read(self, rows: np.ndarray, rest: tuple[Any, ...]) -> np.ndarray:
        """Rows ``rows`` (in range) decompressed, the other axes ``rest`` applied per chunk of rows."""
        paired = [isinstance(r, (np.ndarray, list)) for r in rest]
        rest = tuple(np.asarray(r) if a else r for r, a in zip(rest, paired, strict=True))
        if any(a and np.shape(r) != rows.shape for r, a in zip(rest, paired, strict=True)):
            raise IndexError("Lz4Rows: arrays indexing other axes must have the rows' 1-D shape")
        pieces = []
        for s in range(0, max(len(rows), 1), CHUNK):
            chunk = rows[s : s + CHUNK]
            block = np.empty((len(chunk), *self.shape[1:]), self.dtype)
            flat = block.reshape(len(chunk), self.row_bytes // self.dtype.itemsize).view(np.uint8)
            for j, i in enumerate(chunk):
                a, b = int(self.offsets[i]), int(self.offsets[i + 1])
                flat[j] = self._row(a, b)
            sub = tuple(r[s : s + CHUNK] if a else r for r, a in zip(rest, paired, strict=True))
            pieces.append(block[(np.arange(len(chunk)), *sub)] if any(paired) else block[(slice(None), *sub)])
        return pieces[0] if len(pieces) == 1 else np.concatenate(pieces)


class Lz4RowsWriter:
    """Write arrays of rows compressed one by one, in order: ``with Lz4RowsWriter(folder, specs) as w:
    w['features'].append(block)``. Each array goes to temporary files renamed into place on success and
    removed on failure (``atomic_path``); the caller checks that every array got its rows."""

    def __init__(self, folder: Path, specs: dict[str, tuple[tuple[int, ...], Any]]) -> None:
        self.folder, self.specs = folder, specs
        self.stack = ExitStack()
        self.appenders: dict[str, _Appender] = {}

    def __enter__(self) -> dict[str, _Appender]:
        try:
            for name, (shape, dtype) in self.specs.items():
                path, offsets = files(self.folder, name)
                tmp_data = self.stack.enter_context(atomic_path(path))
                tmp_offsets = self.stack.enter_context(atomic_path(offsets))
                fh = self.stack.enter_context(open(tmp_data, "wb"))
                self.appenders[name] = _Appender(fh, tmp_offsets, shape, np.dtype(dtype), path)
        except BaseException as exc:
            self.stack.__exit__(type(exc), exc, exc.__traceback__)
            raise
        return self.appenders

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        try:
            if exc_type is None:
                for a in self.appenders.values():
                    a.finish()
        except BaseException as e:
            exc_type, exc, tb = type(e), e, e.__traceback__
        if exc_type is not None:  # closed first: a close's own error (a full disk) would hide the first
            for a in self.appenders.values():
                a.abandon()
        self.stack.__exit__(exc_type, exc, tb)  # with an exception: delete, not rename; re-raised
        if exc is not None:
            raise exc


class _Appender:
    def __init__(self, fh: Any, offsets: Path, shape: tuple[int, ...], dtype: np.dtype, path: Path) -> None:
        self.fh, self.offsets_path, self.shape, self.dtype = fh, offsets, shape, dtype
        #: the file the rows go to once renamed (what an OSError of a write names)
        self.path = path
        self.offsets = [0]

    def append(self, block: np.ndarray) -> None:
        """Rows [g, ...] of the array's row shape and dtype, after those appended before."""
        block = np.ascontiguousarray(block, dtype=self.dtype)
        if block.shape[1:] != tuple(self.shape[1:]):
            raise ValueError(f"rows of shape {block.shape[1:]}, the array's are {tuple(self.shape[1:])}")
        with naming(self.path):
            for row in block:
                packed = _CODEC.compress(row.reshape(-1).view(np.uint8), asbytes=True)
                self.fh.write(packed)
                self.offsets.append(self.offsets[-1] + len(packed))

    def abandon(self) -> None:
        """Close the rows' file after an error, dropping what it could not write (it is deleted)."""
        try:
            self.fh.close()
        except OSError:
            pass

    def finish(self) -> None:
        with naming(self.path):
            self.fh.flush()
        with naming(files(self.path.parent, self.path.stem)[1]), open(self.offsets_path, "wb") as fh:
            np.save(fh, np.asarray(self.offsets, np.int64))
