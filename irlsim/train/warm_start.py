"""Warm start of a stage-1 model from an existing checkpoint (``Stage1Config.init_from``): a DAgger round
fine-tunes the previous round's reward instead of training a new one from random weights.

The network takes the checkpoint's inference weights (its validation-selected epoch) together with the
checkpoint's feature normalisation (buffers of the network, so the function it computes is exactly the
checkpoint's at the first step); the optimizer starts fresh. What it started from is recorded in the new
checkpoint (and the run's summary) as ``warm_start``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from torch import nn

from irlsim.config import to_dict
from irlsim.errors import IrlsimError
from irlsim.models.normalization import FeatureStats
from irlsim.train.checkpoint import inference_state, read_checkpoint


def read_warm_start(path: str, name: str, model_config: Any, n_policies: int, k: int) -> dict[str, Any]:
    """The checkpoint at ``path`` if it can initialise stage-1 model ``name`` of sizes ``model_config``
    for cycles of ``n_policies`` policies with ``k`` control points, else IrlsimError (one line)."""
    ckpt = read_checkpoint(Path(path))
    where = f"init_from {path}"
    if ckpt["model"] != name or int(ckpt.get("stage", 0)) != 1:
        raise IrlsimError(
            f"{where} holds the stage-{ckpt.get('stage')} {ckpt['model']}, not the stage-1 {name} being "
            f"trained: name a checkpoint of {name} (<runs>/stage1/{name}/checkpoint.pt)"
        )
    if ckpt.get("model_config") != to_dict(model_config):
        theirs, ours = ckpt.get("model_config") or {}, to_dict(model_config)
        diff = ", ".join(
            f"{f} {theirs.get(f)} vs {ours.get(f)}" for f in ours if theirs.get(f) != ours.get(f)
        )
        raise IrlsimError(
            f"{where} has other network sizes ({diff}): train with its [model] sizes or from scratch"
        )
    if int(ckpt["n_policies"]) != n_policies or int(ckpt["feature_stats"]["k"]) != k:
        raise IrlsimError(
            f"{where} was trained on N={ckpt['n_policies']} policies and K={ckpt['feature_stats']['k']} "
            f"control points per cycle, this dataset has N={n_policies}, K={k}: train from scratch"
        )
    return ckpt


def warm_stats(ckpt: dict[str, Any]) -> FeatureStats:
    """The feature normalisation a warm-started model keeps (the checkpoint's)."""
    return FeatureStats.from_dict(ckpt["feature_stats"])


def apply_warm_start(model: nn.Module, ckpt: dict[str, Any], path: str) -> dict[str, Any]:
    """Load ``ckpt``'s inference weights into ``model``; returns the record stored as 'warm_start'."""
    try:
        model.load_state_dict(inference_state(ckpt))
    except RuntimeError as e:  # shapes: a checkpoint of this model and sizes always fits
        first = str(e).strip().splitlines()[-1].strip()
        raise IrlsimError(
            f"init_from {path} does not fit the network ({first}): train from scratch"
        ) from None
    best = ckpt.get("best")
    return {
        "path": str(path),
        "model": str(ckpt["model"]),
        "epoch": int(best["epoch"]) if best else int(ckpt["epoch"]),
        "dataset": ckpt.get("dataset"),
    }
