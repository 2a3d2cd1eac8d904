"""Trained models for inference: a checkpoint rebuilt into its network (and its frozen base)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from torch import nn

from irlsim.devices import current_device
from irlsim.errors import IrlsimError
from irlsim.models.normalization import FeatureStats
from irlsim.models.registry import STAGE2_BASE, build_model
from irlsim.train.checkpoint import (
    dataset_identity,
    expected_identity,
    inference_state,
    legacy_identities,
    model_config_from,
    read_checkpoint,
)
from irlsim.train.dataset import TrainingData


def rebuild_stage1(entry: dict[str, Any]) -> nn.Module:
    """Stage-1 model from a checkpoint (or a stage-2 checkpoint's 'base' entry), in eval mode."""
    model = build_model(
        entry["model"],
        model_config_from(entry["model_config"]),
        int(entry["n_policies"]),
        FeatureStats.from_dict(entry["feature_stats"]),
    )
    model.load_state_dict(inference_state(entry))
    return model.to(current_device()).eval()


@dataclass
class LoadedModel:
    """A trained model ready for inference.

    name: registry name; model: the network (stage 1, or PTACNN for stage 2); base: the frozen PACNN of a
    PTACNN (None for stage-1 models); history: H of a PTACNN (None otherwise); checkpoint: the raw dict.
    """

    name: str
    model: nn.Module
    base: nn.Module | None
    history: int | None
    checkpoint: dict[str, Any]

    @property
    def parameters(self) -> tuple[int, int]:
        """(policy network, temporal network) trainable parameters; the second is 0 for stage 1."""
        if self.base is None:
            return int(self.checkpoint["parameters"]), 0
        return int(self.checkpoint["base"]["parameters"]), int(self.checkpoint["parameters"])


def load_model(checkpoint_path: str | Path, dataset: TrainingData | None = None) -> LoadedModel:
    """Load any model checkpoint (``<runs>/<model>/checkpoint.pt``) for inference: eval mode, on
    the current device (irlsim.devices); read onto the CPU first, so a checkpoint written on any device
    loads on any other.

    Refused (one line) when it is not the model (and stage) of the folder it was found in
    (:func:`expected_identity`), has non-finite weights, or, with ``dataset`` (the dataset object it will
    be used with), was trained on another dataset."""
    folder_model, folder_stage = expected_identity(checkpoint_path)
    ident = dataset_identity(dataset) if dataset is not None else None
    legacy = legacy_identities(dataset) if dataset is not None else ()
    ckpt = read_checkpoint(
        checkpoint_path, model=folder_model, stage=folder_stage, dataset=ident, legacy=legacy
    )
    name = ckpt["model"]
    try:
        if name in STAGE2_BASE:
            base = rebuild_stage1(ckpt["base"])
            cfg = model_config_from(ckpt["model_config"])
            model = build_model(name, cfg, 1, FeatureStats.from_dict(ckpt["base"]["feature_stats"]))
            model.load_state_dict(inference_state(ckpt))
            return LoadedModel(name, model.to(current_device()).eval(), base, cfg.history, ckpt)
        return LoadedModel(name, rebuild_stage1(ckpt), None, None, ckpt)
    except (KeyError, RuntimeError, TypeError) as e:
        raise IrlsimError(
            f"checkpoint {checkpoint_path} does not match this irlsim's {name} ({type(e).__name__}): retrain"
        ) from None
