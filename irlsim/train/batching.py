"""Split access and batching: splits as arrays, mini-batches as tensors, whole-split prediction."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from irlsim import FEATURE_NAMES, FEATURE_SETS, feature_set_of
from irlsim.data.demos import safe_demo_index
from irlsim.data.npy import take_per_row
from irlsim.data.reader import open_dataset
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.data.tensors import SplitTensors
from irlsim.devices import forward, to_device, to_numpy
from irlsim.errors import IrlsimError
from irlsim.irl.objectives import sample_policies
from irlsim.train.dataset import TrainingData
from irlsim.utils import progress

STOP_LINE = FEATURE_NAMES.index("stop_line")


def as_dataset(dataset: TrainingData | str | Path) -> TrainingData:
    """A dataset object (:class:`irlsim.train.dataset.TrainingData`), or a path opened with the data
    reader."""
    if isinstance(dataset, (str, Path)):
        return open_dataset(dataset)
    return dataset


def get_split(
    dataset: TrainingData, name: str, safe_demos: bool = False, stop_demos: bool = False
) -> SplitTensors:
    """The SplitTensors of split ``name`` (train / validation / test); ``safe_demos``: demonstrations
    labelled as a predicted collision moved to the closest unlabelled policy; ``stop_demos``:
    demonstrations crossing an active stop line without standing (stop_line feature > 0) moved to the
    closest policy that does not (both: to the closest that does neither;
    :func:`irlsim.data.demos.safe_demo_index`)."""
    split = dataset.split_tensors(name)
    c, n = split.features.shape[:2]
    assert split.distances.shape == (c, n) and split.demo_index.shape == (c,), f"split {name} is inconsistent"
    if safe_demos or stop_demos:
        demo = safe_demo_index(
            split.demo_index,
            split.distances,
            split.labels[:, :, 0] if safe_demos else None,
            stop_line=split.features[:, :, STOP_LINE] if stop_demos else None,
        )
        split = dataclasses.replace(split, demo_index=demo)
    return split


def dataset_meta(dataset: TrainingData) -> dict[str, Any]:
    """Schema version and feature names stored in checkpoints (from ``dataset.manifest``; an in-memory
    dataset without one is taken to be current)."""
    manifest = getattr(dataset, "manifest", None) or {}
    names = list(manifest.get("feature_names", FEATURE_NAMES))
    version = manifest.get("schema_version", SCHEMA_VERSION)
    if feature_set_of(names) is None:
        raise IrlsimError(
            f"dataset features {names} are none of this irlsim's feature sets ({', '.join(FEATURE_SETS)}): "
            "re-run 'irlsim collect'"
        )
    if version != SCHEMA_VERSION:
        raise IrlsimError(
            f"dataset schema version {version} differs from this irlsim's {SCHEMA_VERSION}: "
            "re-run 'irlsim collect'"
        )
    return {"schema_version": version, "feature_names": names}


def check_split_shape(name: str, entry: dict[str, Any], split: SplitTensors, split_name: str) -> None:
    """Refuse (one line) a split whose policies per cycle N or control points K differ from those the
    stage-1 ``entry`` (a checkpoint, or a stage-2 checkpoint's 'base') was trained on."""
    n, k = split.features.shape[1], split.control_points.shape[2]
    trained_n, trained_k = int(entry["n_policies"]), int(entry["feature_stats"]["k"])
    if trained_n != n:
        raise IrlsimError(
            f"{name} was trained on N={trained_n} policies per cycle, the {split_name} split has {n}: "
            f"evaluate on a dataset collected with planner.n_policies={trained_n}, or retrain on this one"
        )
    if trained_k != k:
        raise IrlsimError(
            f"{name} was trained on K={trained_k} control points per policy, the {split_name} split has "
            f"{k}: evaluate on the dataset it was trained on, or retrain on this one"
        )


def to_tensor(a: Any, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """``a`` as a tensor on the current device (irlsim.devices; pinned, non-blocking on CUDA)."""
    return to_device(torch.as_tensor(np.ascontiguousarray(a), dtype=dtype))


def gather_batch(
    split: SplitTensors, rows: np.ndarray, sample: int = 0, rng: Any = None
) -> dict[str, torch.Tensor]:
    """Mini-batch of cycles ``rows`` (prefix ``b_``-style tensors): features, control_points, actions,
    distances, demo_index.

    ``sample`` > 0 (every row with a demonstration; ``rng`` a numpy Generator): each cycle's demonstration
    and ``sample - 1`` of its other policies drawn uniformly (:func:`irlsim.irl.objectives.sample_policies`),
    in their progress order, with the demonstration's index among them and their 'log_weights' for the
    importance-weighted max-ent normaliser. ``sample`` >= N is the whole set, as with 0."""
    rows = np.asarray(rows)
    n = split.features.shape[1]
    demo = np.asarray(split.demo_index[rows])
    if not 0 < sample < n:
        return {
            "features": to_tensor(split.features[rows]),
            "control_points": to_tensor(split.control_points[rows]),
            "actions": to_tensor(split.actions[rows]),
            "distances": to_tensor(split.distances[rows]),
            "demo_index": to_tensor(demo, torch.int64),
        }
    policies, demo, log_w = sample_policies(n, sample, demo, rng)
    return {  # each row's sampled policies taken as the row is read (a compressed row is not copied whole)
        "features": to_tensor(take_per_row(split.features, rows, policies)),
        "control_points": to_tensor(take_per_row(split.control_points, rows, policies)),
        "actions": to_tensor(take_per_row(split.actions, rows, policies)),
        "distances": to_tensor(take_per_row(split.distances, rows, policies)),
        "demo_index": to_tensor(demo, torch.int64),
        "log_weights": to_tensor(log_w),
    }


@torch.no_grad()
def predict_split(
    model: nn.Module,
    split: SplitTensors,
    chunk: int = 64,
    desc: str | None = None,
    keep: tuple[str, ...] = ("theta", "context", "attention"),
) -> dict[str, np.ndarray]:
    """Run a stage-1 model over every cycle of ``split`` in chunks.

    -> {'theta': [C, F] float32, and for PACNN 'context': [C, Cc], 'attention': [C, N] float32}, the
    outputs named in ``keep`` only (the attention is 4 N bytes a cycle, 0.4 GB over the paper's DAgger
    round-2 train split: a caller that does not read it leaves it out).
    """
    model.eval()
    n, n_policies = split.features.shape[:2]
    built_for = getattr(model, "n_policies", n_policies)
    if built_for != n_policies:  # 1DCNN / Bi1DCNN would fail on a raw shape error deep inside
        raise IrlsimError(
            f"{type(model).__name__} was trained on N={built_for} policies per cycle, the split has "
            f"{n_policies}: use a dataset collected with planner.n_policies={built_for}, or retrain"
        )
    parts: dict[str, list[np.ndarray]] = {}
    starts = range(0, n, chunk)
    for start in progress(starts, desc=desc, disable=desc is None, leave=False):
        rows = np.arange(start, min(start + chunk, n))
        b = gather_batch(split, rows)
        out = forward(model, b["features"], b["control_points"], b["actions"])
        for k in keep:
            if k in out:
                parts.setdefault(k, []).append(to_numpy(out[k]))
    return (
        {k: np.concatenate(v) for k, v in parts.items()}
        if parts
        else {"theta": np.zeros((0, split.features.shape[-1]), np.float32)}
    )
