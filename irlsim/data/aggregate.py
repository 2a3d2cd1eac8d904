"""DAgger's aggregation: several dataset folders read as one (``irlsim train --data A B ...``).

Each folder stays a complete dataset of its own (its manifest, seeds, ``demo_source``, its reader cache),
and :class:`AggregateDataset` reads, per split, their arrays in the order given. Episode ids are made
unique by adding ``EPISODE_OFFSET`` x (the folder's position) to each folder's ids (a split holds fewer
than 100,000 episodes), so a temporal model's histories never run across two folders.

Nothing is copied: a split of the aggregate is a view over the folders' own memory-mapped caches (each
built once, in its folder, by the reader): the per-policy arrays (features, control points, actions,
distances, labels: all but a few bytes per cycle) are :class:`~irlsim.data.npy.RowConcat` views that
read only the rows asked for, the per-cycle arrays (demonstration index, episode ids offset, ...) are
concatenated in memory (25 bytes a cycle). The rows, their order and their bytes are those of the
concatenation, so a training reads the same batches as from a copy. A DAgger round therefore adds to the
disk only its own folder and its cache, whatever the number of rounds before it. A split only the first
folder has (the expert data's test split) is that folder's own split.

Older irlsim versions wrote the concatenation as a cache of its own
(``<first folder>/.cache/aggregate-<key>/``); training and evaluation remove such copies, and any other
cache of their folders that is out of date, once their inputs are checked
(:func:`remove_obsolete_caches`), one line each.

The aggregate's identity (what a checkpoint records as the dataset it was trained on) is a hash of the
folders' manifest hashes in order (:func:`aggregate_identity`), never of their paths: a copied or moved
folder, or one named by a relative path, is the same dataset. Its manifest's ``seeds`` hold every folder's
episode seeds per split, so a checkpoint trained on it records them (``irlsim drive`` refuses them). An
identity written before (a hash of the aggregate's manifest with the paths as typed) is still accepted
(``legacy_identities``). The folders must share the schema, the features and the planner
(the policies and features mean the same) and may differ in everything else (seeds, counts, DAgger round,
demonstrator). Folders of other demonstrators than the expert are never taken for the first folder's: the
manifest then names every folder's demonstrator (``demonstrators``, in folder order).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from irlsim.data.by_demonstrator import (
    check_demonstrators,
    dataset_demonstrator,
    demonstrator_selection_identity,
    known_demonstrators,
)
from irlsim.data.demonstrator import EXPERT, describe
from irlsim.data.npy import RowConcat
from irlsim.data.prune import prune_caches
from irlsim.data.reader import Dataset, open_dataset
from irlsim.data.roads import check_selection, selection_identity, selections
from irlsim.data.tensors import ARRAY_NAMES, POLICY_ARRAYS, SplitTensors
from irlsim.errors import IrlsimError

#: episode ids of the i-th folder become i * EPISODE_OFFSET + id
EPISODE_OFFSET = 100_000


def manifest_identity(manifest: dict[str, Any]) -> str:
    """sha256 of a manifest's canonical JSON (the identity a checkpoint records of its dataset)."""
    text = json.dumps(manifest, sort_keys=True, separators=(",", ":"), default=str)
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


def aggregate_identity(identities: list[str]) -> str:
    """The identity of an aggregate of folders whose manifest identities are ``identities``, in order
    (the order is part of what was trained on: it decides the rows and the episode ids)."""
    text = json.dumps({"aggregate": list(identities)}, separators=(",", ":"))
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


class AggregateDataset:
    """Several complete datasets as one (see the module docstring); the :class:`Dataset` methods that
    training and evaluation use: ``split_tensors``, ``read_cycles``, ``episodes``, ``splits``,
    ``manifest``."""

    def __init__(self, datasets: list[Dataset]):
        if len(datasets) < 2:
            raise ValueError("an aggregate needs two or more datasets")
        first = datasets[0]
        planner = (first.manifest.get("config") or {}).get("planner")
        for d in datasets[1:]:
            if (d.manifest.get("config") or {}).get("planner") != planner:
                raise IrlsimError(
                    f"dataset {d.path} was collected with another planner config than {first.path}: "
                    "aggregate only datasets of one planner (same policies and features)"
                )
        self.datasets = datasets
        # a folder read for some of its scenarios is identified with its selection
        self.identities = [getattr(d, "identity", None) or manifest_identity(d.manifest) for d in datasets]
        self.path = first.path
        self.paths = [d.path for d in datasets]
        splits = sorted({s for d in datasets for s in d.splits})
        self.manifest: dict[str, Any] = {
            "schema_version": first.manifest["schema_version"],
            "feature_names": first.manifest["feature_names"],
            "config": first.manifest.get("config"),
            "aggregate": [
                {"path": str(d.path), "identity": ident}
                for d, ident in zip(datasets, self.identities, strict=True)
            ],
            "splits": {s: self._ids(s) for s in splits},
            "complete": True,
        }
        who = [describe(d.manifest.get("demonstrator")) for d in datasets]
        if any(w != EXPERT for w in who):  # each folder's demonstrator named (the expert's alone: as before)
            self.manifest["demonstrators"] = who
        #: what identified an aggregate before: its manifest as written above, the paths as typed
        self.legacy_identities = (manifest_identity(self.manifest),)
        self.identity = aggregate_identity(self.identities)
        self.manifest["seeds"] = {s: self._seeds(s) for s in splits}

    @property
    def splits(self) -> list[str]:
        return list(self.manifest["splits"])

    @property
    def scenarios(self) -> list[str]:
        """The folders' scenarios, each once, in folder order."""
        return list(dict.fromkeys(n for d in self.datasets for n in d.scenarios))

    def scenario_of_cycle(self, split: str) -> np.ndarray:
        """[C] the scenario of every cycle of ``split``, rows as ``split_tensors`` orders them."""
        parts = [d.scenario_of_cycle(split) for _, d in self._parts(split)]
        return np.concatenate(parts) if parts else np.asarray([], dtype=str)

    def demonstrator_of_cycle(self, split: str) -> np.ndarray:
        """[C] the demonstrator's identity of every cycle of ``split``, rows as ``split_tensors``."""
        parts = [d.demonstrator_of_cycle(split) for _, d in self._parts(split)]
        return np.concatenate(parts) if parts else np.asarray([], dtype=str)

    def _seeds(self, split: str) -> list[int]:
        """Every folder's episode seeds of ``split``, in folder order."""
        seeds = ((d.manifest.get("seeds") or {}).get(split) or () for d in self.datasets)
        return [int(x) for part in seeds for x in part]

    def _ids(self, split: str) -> list[int]:
        return [
            i * EPISODE_OFFSET + e
            for i, d in enumerate(self.datasets)
            if split in d.splits
            for e in d.episodes(split)
        ]

    def episodes(self, split: str) -> list[int]:
        if split not in self.manifest["splits"]:
            raise IrlsimError(f"datasets {', '.join(map(str, self.paths))} have no split {split!r}")
        return list(self.manifest["splits"][split])

    def _parts(self, split: str) -> list[tuple[int, Dataset]]:
        parts = [(i, d) for i, d in enumerate(self.datasets) if split in d.splits and d.episodes(split)]
        if not parts:
            self.episodes(split)  # the one-line error for an unknown split
        return parts

    def split_tensors(self, split: str, max_cycles: int | None = None) -> SplitTensors:
        """The folders' splits one after the other (episode ids offset), read in place from their own
        caches (see the module docstring); only the first ``max_cycles`` if given."""
        parts = [(i, d.split_tensors(split)) for i, d in self._parts(split)]
        if not parts:
            return self.datasets[0].split_tensors(split, max_cycles)
        shapes = {t.features.shape[1:] + t.control_points.shape[2:] for _, t in parts}
        if len(shapes) > 1:
            raise IrlsimError(
                f"split {split} has policies of other shapes in {', '.join(map(str, self.paths))}: "
                "aggregate datasets of one planner config"
            )
        if len(parts) == 1 and parts[0][0] == 0:  # the first folder's own split: its ids stay
            tensors = parts[0][1]
        else:
            tensors = SplitTensors(**{name: _rows(name, parts) for name in ARRAY_NAMES})
        return tensors if max_cycles is None else tensors.head(max_cycles)

    def read_cycles(self, split: str) -> pd.DataFrame:
        """The folders' cycles rows concatenated in order (episode ids offset)."""
        frames = []
        for i, d in self._parts(split):
            df = d.read_cycles(split)
            df["episode"] = (df["episode"].astype(np.int64) + i * EPISODE_OFFSET).astype(np.int32)
            frames.append(df)
        if not frames:
            return self.datasets[0].read_cycles(split)
        return pd.concat(frames, ignore_index=True)


def _rows(name: str, parts: list[tuple[int, SplitTensors]]) -> Any:
    """Array ``name`` of the parts (folder position, its split) one after the other: a view of the
    per-policy arrays, a concatenation in memory of the per-cycle ones (episode ids offset)."""
    arrays = [getattr(t, name) for _, t in parts]
    if name in POLICY_ARRAYS:
        return arrays[0] if len(arrays) == 1 else RowConcat(arrays)
    if name == "episode":
        arrays = [(a + i * EPISODE_OFFSET).astype(np.int32) for (i, _), a in zip(parts, arrays, strict=True)]
    out = np.concatenate(arrays)
    out.flags.writeable = False  # read-only, as the memory maps it stands beside
    return out


def open_datasets(
    paths: list[str | Path] | tuple[str | Path, ...],
    scenarios: tuple[str, ...] | None = None,
    demonstrators: tuple[str, ...] | None = None,
) -> Dataset | AggregateDataset:
    """One dataset folder (a :class:`Dataset`, memory-mapped) or several (an :class:`AggregateDataset`).
    The same folder twice is refused (its cycles would count twice). ``scenarios``: only the episodes of
    these scenarios (``--scenario-select``; a name no folder has is refused in one line);
    ``demonstrators``: only the folders of these demonstrators (``--demonstrator-select``, see
    :mod:`irlsim.data.by_demonstrator`; ``whole`` then holds the data unselected)."""
    whole = _open(paths, scenarios)
    if demonstrators is None:
        return whole
    parts = whole.datasets if isinstance(whole, AggregateDataset) else [whole]
    where = ", ".join(map(str, paths))
    chosen = check_demonstrators(where, known_demonstrators(parts), demonstrators)
    keep = [Dataset(d.path, d.manifest, d.selection) for d in parts if dataset_demonstrator(d) in chosen]
    selected = keep[0] if len(keep) == 1 else AggregateDataset(keep)
    selected.identity = demonstrator_selection_identity(whole_identity(whole), chosen)
    selected.legacy_identities = ()
    setattr(selected, "whole", whole)  # noqa: B010 (an attribute of a selection alone)
    return selected


def whole_identity(dataset: Dataset | AggregateDataset) -> str:
    """The identity a checkpoint records of ``dataset`` (its own, else its manifest's)."""
    own = getattr(dataset, "identity", None)
    return own if isinstance(own, str) else manifest_identity(dataset.manifest)


def _open(
    paths: list[str | Path] | tuple[str | Path, ...], scenarios: tuple[str, ...] | None
) -> Dataset | AggregateDataset:
    resolved = [Path(p).resolve() for p in paths]
    if not resolved:
        raise IrlsimError("no dataset given: pass --data FOLDER [FOLDER ...]")
    dup = next((p for i, p in enumerate(resolved) if p in resolved[:i]), None)
    if dup is not None:
        raise IrlsimError(f"dataset {dup} is given twice: name each folder once")
    if len(paths) == 1:
        return open_dataset(paths[0], scenarios)
    datasets = [open_dataset(p) for p in paths]
    if scenarios is not None:
        known = list(dict.fromkeys(n for d in datasets for n in d.scenarios))
        chosen = check_selection(", ".join(map(str, paths)), known, scenarios)
        datasets = [Dataset(d.path, d.manifest, chosen) for d in datasets]
    return AggregateDataset(datasets)


def remove_obsolete_caches(dataset: Dataset | AggregateDataset) -> int:
    """Remove the caches nobody reads any more from every folder of ``dataset`` (older versions' aggregate
    copies, caches of changed files: :func:`irlsim.data.prune.prune_caches`), one line each; returns
    the bytes freed. Training and evaluation call it once their inputs are checked, before their work."""
    parts = dataset.datasets if isinstance(dataset, AggregateDataset) else [dataset]
    return sum(prune_caches(d) for d in parts)


def any_selection_identities(dataset: Dataset | AggregateDataset) -> tuple[str, ...]:
    """The identities of the dataset(s) read whole or for any selection of their scenarios and of their
    demonstrators: a model trained on any of them is evaluated on ``dataset`` (``irlsim evaluate``; a
    selection of demonstrators: on the whole data it was selected from)."""
    dataset = getattr(dataset, "whole", dataset)
    parts = dataset.datasets if isinstance(dataset, AggregateDataset) else [dataset]
    whole = [manifest_identity(d.manifest) for d in parts]
    options = [whole] + [
        [selection_identity(d.manifest, chosen) for d in parts] for chosen in selections(dataset.scenarios)
    ]
    if isinstance(dataset, AggregateDataset):
        out = [aggregate_identity(ids) for ids in options]
    else:
        out = [ids[0] for ids in options]
    who = selections(known_demonstrators(parts))
    return tuple([*out, *(demonstrator_selection_identity(base, c) for base in out for c in who)])


def overlapping_identities(dataset: Dataset | AggregateDataset) -> set[str]:
    """The identities of every training set that shares scenarios' episodes with ``dataset`` as read (for
    ``irlsim evaluate --held-out``, which refuses a model trained on any of them): ``dataset``'s own, each
    folder's whole, and each folder's (and the aggregate's) selections that include a scenario read."""
    parts = dataset.datasets if isinstance(dataset, AggregateDataset) else [dataset]
    read = {n for d in parts for n in (d.selection or d.scenarios)}
    chosen_ok = [c for c in selections(dataset.scenarios) if read & set(c)]
    out = {identity for identity in (getattr(dataset, "identity", None),) if identity}
    out.update(getattr(dataset, "legacy_identities", ()))
    for d in parts:
        out.add(manifest_identity(d.manifest))
        out.update(selection_identity(d.manifest, c) for c in selections(d.scenarios) if read & set(c))
    if isinstance(dataset, AggregateDataset):
        out.add(aggregate_identity([manifest_identity(d.manifest) for d in parts]))
        out.update(aggregate_identity([selection_identity(d.manifest, c) for d in parts]) for c in chosen_ok)
    else:
        out.add(manifest_identity(dataset.manifest))
    return out
