"""DAgger's aggregation: several dataset folders read as one (``irlsim train --data A B ...``).

The simplest honest design: nothing is copied or rewritten. Each folder stays a complete dataset of its
own (its manifest, seeds, ``demo_source``), and :class:`AggregateDataset` concatenates, per split, their
arrays in the order given. Episode ids are made unique by adding ``EPISODE_OFFSET`` x (the folder's
position) to each folder's ids (a split holds fewer than 100,000 episodes), so a temporal model's
histories never run across two folders. The arrays are held in memory (the sum of the folders' split
sizes, checked against the free memory before reading); a single folder keeps the reader's memory maps.

The aggregate's identity (what a checkpoint records as the dataset it was trained on) is the list of the
folders' manifest hashes in order; the folders must share the schema, the features and the planner
(the policies and features mean the same) and may differ in everything else (seeds, counts, DAgger round).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from irlsim.config import require_memory
from irlsim.data.reader import Dataset, SplitTensors, open_dataset
from irlsim.errors import IrlsimError

#: episode ids of the i-th folder become i * EPISODE_OFFSET + id
EPISODE_OFFSET = 100_000


def manifest_identity(manifest: dict[str, Any]) -> str:
    """sha256 of a manifest's canonical JSON (the identity a checkpoint records of its dataset)."""
    text = json.dumps(manifest, sort_keys=True, separators=(",", ":"), default=str)
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
        self.path = first.path
        self.paths = [d.path for d in datasets]
        splits = sorted({s for d in datasets for s in d.splits})
        self.manifest: dict[str, Any] = {
            "schema_version": first.manifest["schema_version"],
            "feature_names": first.manifest["feature_names"],
            "config": first.manifest.get("config"),
            "aggregate": [{"path": str(d.path), "identity": manifest_identity(d.manifest)} for d in datasets],
            "splits": {s: self._ids(s) for s in splits},
            "complete": True,
        }

    @property
    def splits(self) -> list[str]:
        return list(self.manifest["splits"])

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
        """The folders' splits concatenated in order (episode ids offset, see the module docstring)."""
        parts = [(i, d.split_tensors(split)) for i, d in self._parts(split)]
        if not parts:
            return self.datasets[0].split_tensors(split)
        shapes = {t.features.shape[1:] + t.control_points.shape[2:] for _, t in parts}
        if len(shapes) > 1:
            raise IrlsimError(
                f"split {split} has policies of other shapes in {', '.join(map(str, self.paths))}: "
                "aggregate datasets of one planner config"
            )
        need = sum(sum(a.nbytes for a in (getattr(t, f.name) for f in fields(t))) for _, t in parts)
        require_memory(
            f"aggregating the {split} split of {len(parts)} datasets", need, "aggregate fewer datasets"
        )
        arrays: dict[str, np.ndarray] = {}
        for f in fields(SplitTensors):
            cols = [np.asarray(getattr(t, f.name)) for _, t in parts]
            if f.name == "episode":
                cols = [
                    (c + i * EPISODE_OFFSET).astype(np.int32) for (i, _), c in zip(parts, cols, strict=True)
                ]
            arrays[f.name] = np.concatenate(cols)
        tensors = SplitTensors(**arrays)
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


def open_datasets(paths: list[str | Path] | tuple[str | Path, ...]) -> Dataset | AggregateDataset:
    """One dataset folder (a :class:`Dataset`, memory-mapped) or several (an :class:`AggregateDataset`).
    The same folder twice is refused (its cycles would count twice)."""
    resolved = [Path(p).resolve() for p in paths]
    if not resolved:
        raise IrlsimError("no dataset given: pass --data FOLDER [FOLDER ...]")
    dup = next((p for i, p in enumerate(resolved) if p in resolved[:i]), None)
    if dup is not None:
        raise IrlsimError(f"dataset {dup} is given twice: name each folder once")
    if len(paths) == 1:
        return open_dataset(paths[0])
    return AggregateDataset([open_dataset(p) for p in paths])
