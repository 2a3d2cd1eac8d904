"""Caches nobody reads any more, removed by the command that made them obsolete, one line each.

In a dataset folder's ``.cache``:

- ``aggregate-<key>/``: the copies older irlsim versions made of an aggregate's splits (in its first
  folder). An aggregate is now read from its folders' own caches (:mod:`irlsim.data.aggregate`), so
  they are removed by the first training or evaluation of the folder;
- ``<split>/`` and ``scenarios-<key>/<split>/`` (a selection of scenarios) that are out of date: their
  split is no longer in the manifest, or they were built from other files than the split has now (an
  episode collected again) or by another cache version. ``irlsim collect`` removes them when it has
  changed the folder, training and evaluation once their inputs are checked, and the reader before it
  rebuilds one (:meth:`irlsim.data.reader.Dataset.split_tensors`).

Only complete irlsim caches are removed (a ``meta.json`` with a cache version), and of them only the
files irlsim writes there (:func:`irlsim.data.cache.remove_cache`); a folder being built (no
``meta.json`` yet), a valid cache, a selection whose scenarios cannot be told, and anything that is not
an irlsim cache stay. A dataset whose files are missing is left as it is (the reader names what is
missing).
"""

from __future__ import annotations

import re
from pathlib import Path

from irlsim.data.cache import (
    CACHE_DIR,
    CACHE_VERSION,
    raw_cache_meta,
    record_problem,
    remove_cache,
    remove_empty,
)
from irlsim.data.reader import Dataset
from irlsim.data.roads import selection_key, selections
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.errors import IrlsimError

#: an aggregate's cache folder as older irlsim versions named it (16 hex digits of its folders' hash)
AGGREGATE_RE = re.compile(r"aggregate-[0-9a-f]{16}")
#: a selection's cache folder (irlsim.data.roads.selection_key)
SELECTION_RE = re.compile(r"scenarios-[0-9a-f]{12}")
#: why an aggregate's copy goes
AGGREGATE_WHY = (
    "a copy of an aggregate's split that an older irlsim made; aggregates are now read from each "
    "folder's own cache"
)


def prune_caches(dataset: Dataset) -> int:
    """Remove the obsolete caches of ``dataset``'s folder (the module docstring says which), one line
    each; returns the bytes freed."""
    root = dataset.path / CACHE_DIR
    if not root.is_dir():
        return 0
    whole = Dataset(dataset.path, dataset.manifest) if dataset.selection is not None else dataset
    by_key = {selection_key(s): s for s in selections(whole.scenarios)}
    freed = 0
    for entry in sorted(p for p in root.iterdir() if p.is_dir()):
        if AGGREGATE_RE.fullmatch(entry.name):
            freed += sum(remove_cache(f, AGGREGATE_WHY) for f in _folders(entry))
            remove_empty(entry)
        elif SELECTION_RE.fullmatch(entry.name):
            chosen = by_key.get(entry.name)
            if chosen is None:
                continue  # the selection cannot be told: left as it is
            view = Dataset(dataset.path, dataset.manifest, chosen)
            for folder in _folders(entry):
                freed += _remove_if_stale(view, folder, f"of the scenarios {', '.join(chosen)}")
            remove_empty(entry)
        else:
            freed += _remove_if_stale(whole, entry, "")
    return freed


def _folders(parent: Path) -> list[Path]:
    return sorted(p for p in parent.iterdir() if p.is_dir())


def _remove_if_stale(dataset: Dataset, folder: Path, which: str) -> int:
    """Remove ``folder``, the cache of split ``folder.name`` of ``dataset``, when it is out of date."""
    why = stale_reason(dataset, folder.name, folder)
    if why is None:
        return 0
    return remove_cache(folder, f"the cache of split {folder.name}{' ' + which if which else ''}, {why}")


def stale_reason(dataset: Dataset, split: str, folder: Path) -> str | None:
    """Why the complete cache ``folder`` of ``split`` is out of date, or None (valid, being built, not an
    irlsim cache, or the dataset's files cannot be read to tell)."""
    found = raw_cache_meta(folder)
    if found is None or record_problem(folder) is not None:  # the reader names a broken record
        return None
    meta = found[0]
    versions = (meta.get("cache_version"), meta.get("schema_version"))
    if versions != (CACHE_VERSION, SCHEMA_VERSION):
        return f"out of date: written by another irlsim (cache version {versions[0]}, schema {versions[1]})"
    if split not in dataset.splits:
        return "out of date: a split the dataset no longer has"
    try:
        valid = dataset.cache_valid(split)
    except IrlsimError:  # files of the manifest are missing: the reader says which when it reads them
        return None
    return None if valid else "out of date: built from other files than the split has now (or incomplete)"
