"""The reader's cache folders: reading, writing, opening and removing one.

A cache folder (``<dataset>/.cache/<split>/``, or ``.cache/scenarios-<key>/<split>/`` for a selection
of scenarios) holds the arrays of :class:`~irlsim.data.tensors.SplitTensors`: each per-cycle one as a
memory-mapped ``<name>.npy``, each per-policy one as rows compressed one by one (``<name>.lz4`` and
``<name>.offsets.npy``, :mod:`irlsim.data.lz4rows`), and a ``meta.json``, written last, that records the
cache and schema versions, what the arrays were built from (:mod:`irlsim.data.reader` compares it with the
split's files), every array file's size and sha256 (``files``) and a sha256 of the record itself
(``meta_sha256``). A folder without a ``meta.json`` is being built (or its build was killed) and is not
read.

A cache is verified, never trusted: :func:`verify_cache` compares every file with what ``meta.json``
recorded when it was written (sizes first, then the content hashes) the first time a process opens the
cache; a file flipped, truncated, swapped with another or missing, or a ``meta.json`` that is not what was
written, is named and the reader rebuilds the cache from the Parquet files (one line on stderr).

:func:`remove_cache` deletes a complete cache folder, and only what irlsim writes in one: the array files
and ``meta.json``, and of the arrays only those not newer than the ``meta.json`` it found (an array a
rebuild started meanwhile by another process has renamed into place is newer: it stays). Anything else
in the folder stays where it is, and so does the folder then.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from irlsim import N_FEATURES
from irlsim.data.lz4rows import Lz4Rows
from irlsim.data.lz4rows import files as lz4_files
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.data.tensors import ARRAY_NAMES, POLICY_ARRAYS, SplitTensors, policy_array_specs
from irlsim.errors import IrlsimError
from irlsim.outputs import human_size
from irlsim.utils import write_json

CACHE_DIR = ".cache"
#: bump when the cache layout changes; an old cache is then rebuilt
#: (5: every file's size and sha256 in meta.json, checked when opened; 4: the per-policy arrays
#: LZ4-compressed by rows; 3: framed LZ4; 2: float32 .npy)
CACHE_VERSION = 5
#: written last in a cache folder: the cache is complete
META_NAME = "meta.json"
#: the content hash of the cache's files (hashlib name)
HASH = "sha256"
#: caches verified by this process: (folder, (inode, size, mtime) of meta.json and of every file); a cache
#: is checked once per process, and again when a file of it was replaced or written since
_VERIFIED: set[tuple[str, tuple[tuple[int, int, int], ...]]] = set()


def read_cache_meta(folder: Path) -> tuple[dict[str, Any], os.stat_result] | None:
    """(meta.json, its stat) of a cache folder of this irlsim's cache and schema versions; None otherwise
    (the caller then rebuilds it). The caller compares what it records; :func:`verify_cache` checks the
    files against it."""
    meta_path = folder / META_NAME
    try:
        meta, st = json.loads(meta_path.read_text()), meta_path.stat()
    except (OSError, ValueError):
        return None
    versions = (CACHE_VERSION, SCHEMA_VERSION)
    if not isinstance(meta, dict) or (meta.get("cache_version"), meta.get("schema_version")) != versions:
        return None
    return meta, st


def cache_files(folder: Path, old: bool = False) -> list[Path]:
    """The array files of a cache folder (``old``: also those of earlier cache versions' layouts)."""
    out = []
    for name in ARRAY_NAMES:
        if name in POLICY_ARRAYS:
            out += [*lz4_files(folder, name), *([folder / f"{name}.npy"] if old else [])]
        else:
            out.append(folder / f"{name}.npy")
    return out


def invalidate_cache(folder: Path) -> None:
    """Before a cache folder is (re)built: it exists and has no meta.json (invalid while rebuilding). The
    builder removes an out-of-date complete cache there first (:func:`remove_cache`), so the old and the
    new arrays never take the disk together."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / META_NAME).unlink(missing_ok=True)


def file_digest(path: Path) -> str:
    """The content hash of file ``path`` (hex)."""
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, HASH).hexdigest()


def meta_digest(meta: dict[str, Any]) -> str:
    """The hash of a meta.json record without its own ``meta_sha256`` (canonical JSON)."""
    body = {k: v for k, v in meta.items() if k != "meta_sha256"}
    return hashlib.new(HASH, json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def write_cache_meta(folder: Path, record: dict[str, Any]) -> None:
    """The last write of a cache build: meta.json with the versions, what the cache was built from, every
    array file's [size, hash] and the record's own hash. The cache then counts as verified here."""
    files = {p.name: [p.stat().st_size, file_digest(p)] for p in cache_files(folder)}
    meta = {"cache_version": CACHE_VERSION, "schema_version": SCHEMA_VERSION, **record, "files": files}
    meta["meta_sha256"] = meta_digest(meta)
    write_json(folder / META_NAME, meta)
    _VERIFIED.add(_stat_key(folder))


def _stat_key(folder: Path) -> tuple[str, tuple[tuple[int, int, int], ...]]:
    """What tells this process that the files of cache ``folder`` are those it verified (a missing file: a
    key never verified)."""
    stats = []
    for path in [folder / META_NAME, *cache_files(folder)]:
        try:
            st = path.stat()
        except OSError:
            return str(folder), ((-1, -1, -1),)
        stats.append((st.st_ino, st.st_size, st.st_mtime_ns))
    return str(folder), tuple(stats)


def verify_cache(folder: Path, meta: dict[str, Any]) -> str | None:
    """None when the files of the cache folder ``folder`` are those its ``meta`` records, sizes and content
    hashes; else what differs, naming the file. Checked once per process (again when a file changed)."""
    key = _stat_key(folder)
    if key in _VERIFIED:
        return None
    files = meta.get("files")
    names = [p.name for p in cache_files(folder)]
    if (
        record_problem(folder) is not None
        or not isinstance(files, dict)
        or sorted(files) != sorted(names)
        or not all(isinstance(v, list) and len(v) == 2 for v in files.values())
    ):
        return f"{folder / META_NAME} is not the record that was written (its hash differs)"
    path = folder
    try:
        for path in cache_files(folder):  # sizes first: a truncated file costs no hashing
            size = path.stat().st_size
            if [size] != files[path.name][:1]:
                return f"{path} has {size} bytes, {files[path.name][0]} when it was written"
        for path in cache_files(folder):
            if file_digest(path) != files[path.name][1]:
                return f"{path} is not the file that was written (its {HASH} differs)"
    except FileNotFoundError:
        return f"{path} is missing"
    except OSError as exc:
        return f"{path} cannot be read ({exc.strerror or type(exc).__name__})"
    _VERIFIED.add(key)
    return None


def open_cache(folder: Path, meta: dict[str, Any]) -> SplitTensors:
    """A verified cache folder's arrays (``meta``: its meta.json): read-only memory maps, the per-policy
    ones compressed rows. A file that cannot be opened as what it should be (changed since it was
    verified) is one line naming it."""
    small: dict[str, Any] = {}
    for name in ARRAY_NAMES:
        if name not in POLICY_ARRAYS:
            path = folder / f"{name}.npy"
            small[name] = _opened(path, partial(np.load, path, mmap_mode="r"))
    c, n, k = (int(meta[key]) for key in ("cycles", "policies", "control_points"))
    big: dict[str, Any] = {}
    f = int(meta.get("features", N_FEATURES))  # F: written only for a feature set other than the paper's
    for name, (shape, dtype) in policy_array_specs(c, n, k, f).items():
        big[name] = _opened(folder / f"{name}.lz4", partial(Lz4Rows.open, folder, name, shape[1:], dtype))
    try:
        return SplitTensors(**small, **big)
    except ValueError as exc:
        raise IrlsimError(
            f"the cache {folder} does not hold the arrays it records ({exc}): {REBUILD}"
        ) from None


#: the fix of a cache that cannot be read
REBUILD = "delete it (the next command rebuilds it from the Parquet files)"


def _opened(path: Path, opener: Any) -> Any:
    """``opener()``, which opens ``path``; an error is one line naming ``path``."""
    try:
        return opener()
    except (OSError, ValueError, EOFError) as exc:
        raise IrlsimError(f"cache file {path} cannot be read ({exc}): {REBUILD}") from None


def record_problem(folder: Path) -> str | None:
    """What is wrong with the ``meta.json`` of ``folder`` when there is one that is not as irlsim wrote it:
    not JSON, not UTF-8, not a table with a ``cache_version``, or one of this cache version (or with a
    ``meta_sha256``) whose hash differs. None when there is none, or it is as written (of any version)."""
    path = folder / META_NAME
    if not path.exists():
        return None
    found = raw_cache_meta(folder)
    if found is None:
        return f"{path} is not a cache record (not JSON, or not the fields irlsim writes)"
    meta = found[0]
    if ("meta_sha256" in meta or meta.get("cache_version") == CACHE_VERSION) and meta.get(
        "meta_sha256"
    ) != meta_digest(meta):
        return f"{path} is not the record that was written (its {HASH} differs)"
    return None


def raw_cache_meta(folder: Path) -> tuple[dict[str, Any], os.stat_result] | None:
    """(meta.json, its stat) of a complete irlsim cache folder of any version (it records a
    ``cache_version``); None for a folder without one, being built, or not a cache."""
    meta_path = folder / META_NAME
    try:
        meta, st = json.loads(meta_path.read_text()), meta_path.stat()
    except (OSError, ValueError):
        return None
    return (meta, st) if isinstance(meta, dict) and "cache_version" in meta else None


def remove_cache(folder: Path, why: str, quiet: bool = False) -> int:
    """Delete the complete cache folder ``folder`` (see the module docstring for what is deleted) and print
    one line naming it, the bytes freed and ``why`` (none when ``quiet``: the caller said why); returns the
    bytes freed (0, and no line, when the folder holds no complete cache). A file that cannot be deleted
    is named in one line on stderr."""
    found = raw_cache_meta(folder)
    if found is None:
        return 0
    meta_st = found[1]
    freed = 0
    try:
        for path in cache_files(folder, old=True):
            try:
                st = path.stat()
            except FileNotFoundError:
                continue
            if st.st_mtime_ns <= meta_st.st_mtime_ns:
                path.unlink()
                freed += st.st_blocks * 512
        st = (folder / META_NAME).stat()
        if (st.st_ino, st.st_mtime_ns) == (meta_st.st_ino, meta_st.st_mtime_ns):  # not a rebuild's new one
            (folder / META_NAME).unlink()
            freed += st.st_blocks * 512
    except FileNotFoundError:  # another process removed it meanwhile
        pass
    except OSError as exc:
        print(f"irlsim: could not remove the cache {folder} ({exc.strerror}): {why}", file=sys.stderr)
        return freed
    left = sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []
    if not left:
        remove_empty(folder)
    kept = f" ({len(left)} other files left in it: {', '.join(left[:3])})" if left else ""
    if not quiet:
        print(f"removed {folder} ({human_size(freed)}){kept}: {why}", flush=True)
    return freed


def remove_empty(folder: Path) -> None:
    """Remove ``folder`` if it is an empty directory (the parent of removed cache folders)."""
    try:
        folder.rmdir()
    except OSError:
        pass
