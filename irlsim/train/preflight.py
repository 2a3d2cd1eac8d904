"""What training checks before any work (nothing written, no folder made): the splits it needs hold
episodes, and the networks' sizes fit the memory there is.

:func:`check_split_sizes` is the check on episode counts alone, for a caller that knows them before the
data exists (DAgger before collecting a round: the expert data's counts plus the round's planned ones);
:func:`check_trainable` runs it on a dataset (one folder or an aggregate) and adds the memory estimate
(:func:`training_bytes`) of every model asked, against :func:`irlsim.config.available_memory`, like the
planner's ``n_policies`` check of collection.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import torch

from irlsim import N_FEATURES
from irlsim.config import require_memory
from irlsim.errors import IrlsimError
from irlsim.models.registry import STAGE2_BASE, ModelConfig, build_model
from irlsim.train.dataset import TrainingData

#: the splits training reads: the train split's demonstrations, the validation split for model
#: selection and the validation metrics
TRAINING_SPLITS = ("train", "validation")
#: float32 copies of the parameters training holds: weights, gradients, Adam's two moments, the best
#: epoch's weights, the checkpoint being serialised
PARAMETER_COPIES = 6
#: float32 values kept per activation for the backward pass and its gradient (and headroom)
ACTIVATION_COPIES = 4
#: control points per policy when a dataset does not say (irlsim.data.schema.N_CONTROL_POINTS)
DEFAULT_K = 10


def check_split_sizes(episodes: Mapping[str, int], where: str) -> None:
    """Refuse (one line) a split training needs that holds no episode. ``episodes``: split -> episode
    count (a missing split counts as 0); ``where``: the data named in the message (folders, or a DAgger
    round's plan)."""
    for split in TRAINING_SPLITS:
        if int(episodes.get(split, 0)) <= 0:
            fix = (
                "collect validation episodes (validation_episodes >= 1), or train on it together with a "
                "dataset that has them (--data EXPERT_DATA ROUND_DATA)"
                if split == "validation"
                else "collect train episodes (train_episodes >= 1) or add a dataset that has them"
            )
            raise IrlsimError(f"{where} has an empty {split} split (no episodes), training needs one: {fix}")


def split_episode_counts(dataset: TrainingData) -> dict[str, int]:
    """split -> episodes of a dataset (a folder or an aggregate: its ``splits`` and ``episodes``)."""
    splits, episodes = dataset.splits or (), getattr(dataset, "episodes", None)
    if not callable(episodes):  # in memory (irlsim.bench.synthetic): by cycles
        return {s: len(dataset.split_tensors(s).demo_index) if s in splits else 0 for s in TRAINING_SPLITS}
    return {s: len(episodes(s)) if s in splits else 0 for s in TRAINING_SPLITS}


def _where(dataset: TrainingData) -> str:
    paths = getattr(dataset, "paths", None) or [getattr(dataset, "path", "the dataset")]
    return "dataset " + " + ".join(map(str, paths))


def training_bytes(name: str, model: ModelConfig, n_policies: int, k: int, batch: int) -> int:
    """About the memory [bytes] training model ``name`` takes: its parameters (counted on torch's meta
    device, nothing allocated; a stage-2 model with its frozen base) times ``PARAMETER_COPIES``, plus the
    activations of ``batch`` cycles of ``n_policies`` policies (inputs, and the policy encoder's)."""
    params = 0
    for part in (name, STAGE2_BASE.get(name)):
        if part is None:
            continue
        with torch.device("meta"):
            net = build_model(part, model, n_policies, None)
        params += sum(p.numel() for p in net.parameters())
    per_policy = N_FEATURES + 5 * k  # the inputs (the paper's feature set: an estimate); LIRL has no encoder
    if name != "LIRL":
        per_policy += 2 * model.hidden_channels + 2 * model.latent + model.attention_hidden
    activations = batch * n_policies * per_policy
    return 4 * (PARAMETER_COPIES * params + ACTIVATION_COPIES * activations)


def check_trainable(dataset: TrainingData, cfg: Any) -> None:
    """Everything training checks before any work: the train and validation splits hold episodes
    (:func:`check_split_sizes`) and each model of ``cfg.models`` fits the available memory
    (:func:`training_bytes` with ``cfg.model``, the dataset's policies per cycle and the larger of
    ``batch_size`` and ``eval_batch``). One line (IrlsimError) naming what is wrong and the fix."""
    check_split_sizes(split_episode_counts(dataset), _where(dataset))
    manifest = getattr(dataset, "manifest", None) or {}
    planner = (manifest.get("config") or {}).get("planner") or {}
    n_policies, k = planner.get("n_policies"), planner.get("n_control_points", DEFAULT_K)
    if not isinstance(n_policies, int):
        return  # an in-memory dataset: its arrays are already allocated
    batch = max(int(cfg.batch_size), int(cfg.eval_batch))
    cycles = largest_split_cycles(manifest)
    if cycles:  # a batch never holds more cycles than a split has
        batch = min(batch, cycles)
    for name in cfg.models:
        try:
            need = training_bytes(name, cfg.model, n_policies, int(k), batch)
        except (RuntimeError, ValueError, OverflowError) as exc:  # sizes torch cannot even shape
            raise IrlsimError(
                f"config: [model] sizes cannot build {name} ({exc}): use smaller sizes"
            ) from None
        field = largest_field(name, cfg.model, n_policies, int(k), batch, need)
        require_memory(
            f"training {name} ([model] {field}={getattr(cfg.model, field)} makes it this large; "
            f"{n_policies} policies x {batch} cycles per batch)",
            need,
            f"lower [model] {field} (default {getattr(ModelConfig(), field)}), a smaller batch_size / "
            "eval_batch, or fewer policies per cycle",
        )


def largest_split_cycles(manifest: Mapping[str, Any]) -> int:
    """The most planning cycles of a split the manifest counts (0 where it counts none)."""
    counts = manifest.get("counts") or {}
    return max((int(c.get("cycles") or 0) for c in counts.values() if isinstance(c, Mapping)), default=0)


def largest_field(name: str, model: ModelConfig, n_policies: int, k: int, batch: int, need: int) -> str:
    """The [model] field whose value, set back to its default alone, lowers the memory ``need`` of model
    ``name`` the most: the one that makes it large (the first size field where none lowers it)."""
    default = ModelConfig()
    best, best_need = "hidden_channels", need
    for f in dataclasses.fields(ModelConfig):
        value = getattr(default, f.name)
        if not isinstance(value, int) or getattr(model, f.name) == value:
            continue
        try:
            smaller: ModelConfig = dataclasses.replace(model, **{f.name: value})  # type: ignore[arg-type]
            trial = training_bytes(name, smaller, n_policies, k, batch)
        except (RuntimeError, ValueError, OverflowError):
            continue
        if trial < best_need:
            best, best_need = f.name, trial
    return best
