"""The reader's cache folders: reading, writing, opening and removing one.

A cache folder (``<dataset>/.cache/<split>/``, or ``.cache/scenarios-<key>/<split>/`` for a selection
of scenarios) holds the arrays of :class:`~irlsim.data.tensors.SplitTensors`: each per-cycle one as a
memory-mapped ``<name>.npy``, each per-policy one as rows compressed one by one (``<name>.lz4`` and
``<name>.offsets.npy``, :mod:`irlsim.data.lz4rows`), and a ``meta.json``, written last, that records the
cache and schema versions and what the arrays were built from (:mod:`irlsim.data.reader` compares it with the
split's files). A folder without a ``meta.json`` is being built (or its build was killed) and is not
read.

:func:`remove_cache` deletes a complete cache folder, and only what irlsim writes in one: the array files
and ``meta.json``, and of the arrays only those not newer than the ``meta.json`` it found (an array a
rebuild started meanwhile by another process has renamed into place is newer: it stays). Anything else
in the folder stays where it is, and so does the folder then.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.data.lz4rows import Lz4Rows
from irlsim.data.lz4rows import files as lz4_files
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.data.tensors import ARRAY_NAMES, POLICY_ARRAYS, SplitTensors, policy_array_specs
from irlsim.outputs import human_size
from irlsim.utils import write_json

CACHE_DIR = ".cache"
#: bump when the cache layout changes; an old cache is then rebuilt
CACHE_VERSION = 4  # 4: the per-policy arrays LZ4-compressed by rows (3: framed LZ4, 2: float32 .npy)
#: written last in a cache folder: the cache is complete
META_NAME = "meta.json"


def read_cache_meta(folder: Path) -> tuple[dict[str, Any], os.stat_result] | None:
    """(meta.json, its stat) of a cache folder of this irlsim's cache and schema versions whose array files
    are all there; None otherwise (the caller then rebuilds it). The caller compares what it records."""
    meta_path = folder / META_NAME
    try:
        meta, st = json.loads(meta_path.read_text()), meta_path.stat()
    except (OSError, ValueError):
        return None
    versions = (CACHE_VERSION, SCHEMA_VERSION)
    if not isinstance(meta, dict) or (meta.get("cache_version"), meta.get("schema_version")) != versions:
        return None
    return (meta, st) if all(p.is_file() for p in cache_files(folder)) else None


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


def write_cache_meta(folder: Path, record: dict[str, Any]) -> None:
    """The last write of a cache build: meta.json with the versions and what the cache was built from."""
    write_json(
        folder / META_NAME, {"cache_version": CACHE_VERSION, "schema_version": SCHEMA_VERSION, **record}
    )


def open_cache(folder: Path) -> SplitTensors:
    """A valid cache folder's arrays: read-only memory maps, the per-policy ones compressed rows."""
    small = {n: np.load(folder / f"{n}.npy", mmap_mode="r") for n in ARRAY_NAMES if n not in POLICY_ARRAYS}
    c, n, k = (int(read_cache_meta(folder)[0][key]) for key in ("cycles", "policies", "control_points"))  # type: ignore[index]
    big: dict[str, Any] = {
        name: Lz4Rows.open(folder, name, shape[1:], dtype)
        for name, (shape, dtype) in policy_array_specs(c, n, k).items()
    }
    return SplitTensors(**small, **big)


def raw_cache_meta(folder: Path) -> tuple[dict[str, Any], os.stat_result] | None:
    """(meta.json, its stat) of a complete irlsim cache folder of any version (it records a
    ``cache_version``); None for a folder without one, being built, or not a cache."""
    meta_path = folder / META_NAME
    try:
        meta, st = json.loads(meta_path.read_text()), meta_path.stat()
    except (OSError, ValueError):
        return None
    return (meta, st) if isinstance(meta, dict) and "cache_version" in meta else None


def remove_cache(folder: Path, why: str) -> int:
    """Delete the complete cache folder ``folder`` (see the module docstring for what is deleted) and print
    one line naming it, the bytes freed and ``why``; returns the bytes freed (0, and no line, when the
    folder holds no complete cache). A file that cannot be deleted is named in one line on stderr."""
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
    print(f"removed {folder} ({human_size(freed)}){kept}: {why}", flush=True)
    return freed


def remove_empty(folder: Path) -> None:
    """Remove ``folder`` if it is an empty directory (the parent of removed cache folders)."""
    try:
        folder.rmdir()
    except OSError:
        pass
