"""What training reads from a dataset: :class:`TrainingData`.

A dataset folder (:class:`irlsim.data.reader.Dataset`), several folders as one
(:class:`irlsim.data.aggregate.AggregateDataset`) and the in-memory synthetic dataset
(:class:`irlsim.bench.synthetic.SyntheticDataset`) all satisfy it; nothing has to inherit from it.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any, Protocol

from irlsim.data.tensors import SplitTensors


class TrainingData(Protocol):
    """A dataset as the training code reads it.

    Required: ``split_tensors(split)``, the arrays of split 'train' or 'validation'
    (:class:`SplitTensors`); ``manifest``, its schema_version and feature_names (checked against this
    irlsim's) and what identifies it in a checkpoint (its content hash, the episode 'seeds' that drive
    refuses, the planner's N and K); ``splits``, the names of the splits it has.

    Read where present (an in-memory dataset has none of them): ``identity``, its own identity (a
    scenario selection's, an aggregate's) instead of the manifest's hash
    (:func:`irlsim.train.checkpoint.dataset_identity`); ``legacy_identities``, identities an older
    irlsim recorded for it, still accepted on resume; ``episodes(split)``, the episode ids of a split
    (preflight counts episodes, else cycles); ``path`` / ``paths``, the folder(s) error lines name.
    """

    @property
    def manifest(self) -> dict[str, Any]: ...

    @property
    def splits(self) -> Collection[str]: ...

    def split_tensors(self, split: str, /) -> SplitTensors: ...
