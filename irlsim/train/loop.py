"""The one training loop of both stages: seed, build, resume, epochs of optimizer steps, validation,
model selection, the metrics log and an atomic checkpoint after every epoch (:class:`TrainingRun`).

A stage supplies what differs through the small :class:`Stage` protocol (stage1.Stage1,
stage2.Stage2): how to build its network, what one epoch of mini-batches is, how it validates and
what its checkpoint carries besides the common entries, which are written here only
(:meth:`TrainingRun.payload`, in ``ENTRY_ORDER``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch
from torch import nn

from irlsim.config import to_dict
from irlsim.devices import current_device
from irlsim.errors import IrlsimError
from irlsim.models.registry import count_parameters
from irlsim.train.batching import dataset_meta
from irlsim.train.checkpoint import (
    dataset_egos,
    dataset_identity,
    dataset_seeds,
    legacy_identities,
    read_checkpoint,
    save_checkpoint,
)
from irlsim.train.config import TrainConfig
from irlsim.train.dataset import TrainingData
from irlsim.train.layout import CHECKPOINT_NAME
from irlsim.train.metrics_log import MetricsLog
from irlsim.train.repro import provenance
from irlsim.utils import progress


class BestTracker:
    """Model selection on the validation split: keeps a copy of the weights of the epoch with the lowest
    ``metric`` seen so far (ties keep the earlier epoch). ``metric='last'`` keeps nothing."""

    def __init__(self, metric: str, previous: dict[str, Any] | None = None) -> None:
        self.metric = metric
        self.best = previous if metric != "last" else None

    def update(self, row: dict[str, Any], model: nn.Module) -> None:
        value = row.get(self.metric)
        if self.metric == "last" or value is None or not np.isfinite(value):
            return
        if self.best is None or value < self.best["value"]:
            state = {k: v.detach().clone() for k, v in model.state_dict().items()}
            self.best = {
                "metric": self.metric,
                "value": float(value),
                "epoch": int(row["epoch"]),
                "state_dict": state,
            }

    @property
    def epoch(self) -> int | None:
        return None if self.best is None else int(self.best["epoch"])


def check_finite(loss: torch.Tensor, model: str, epoch: int, lr: float, stage: str) -> None:
    if not torch.isfinite(loss):
        raise IrlsimError(
            f"{model}: the loss became {loss.item()} in epoch {epoch + 1}: lower {stage}.lr (now {lr:g}) "
            "or check the dataset for non-finite features"
        )


#: config fields a resume refuses to change (one line naming the field): they decide what the finished
#: epochs mean (the seed fixes the initial weights and every epoch's shuffle, max_cycles the train rows and
#: the feature normalisation, select_by / history what the stored best epoch was selected by, model the
#: network, safe_demos / stop_demos the demonstrations trained on). A field a checkpoint written before it
#: existed does not record is not refused (recorded as changed from None). Every other field (epochs, lr,
#: weight_decay, grad_clip, batch_size, the attention loss weights, validate_every, threads, eval_batch,
#: tensorboard, models) may change: the remaining epochs use the new value and the checkpoint's 'resumes'
#: records {epoch, changed: {field: [old, new]}}.
REFUSED_ON_RESUME = ("seed", "max_cycles", "select_by", "history", "model", "safe_demos", "stop_demos")


def check_resume(
    path: Path,
    ckpt: dict[str, Any],
    config: dict[str, Any],
    dataset: str | None,
    legacy: tuple[str, ...] = (),
) -> dict[str, list[Any]]:
    """Compare an existing checkpoint with what is asked: another dataset or a field of
    ``REFUSED_ON_RESUME`` -> IrlsimError (one line naming the difference); returns the other changed
    fields as {field: [old, new]}. ``legacy``: older identities of the same dataset, also accepted."""
    have = ckpt.get("dataset")
    if dataset is not None and have != dataset and have not in legacy:
        raise IrlsimError(
            f"{path} was trained on another dataset ({str(have)[:19]}..., --data is {dataset[:19]}...): "
            "train into another --out, delete the model's folder, or pass the dataset it was trained on"
        )
    old = ckpt.get("config") or {}
    changed = {k: [old.get(k), v] for k, v in config.items() if old.get(k) != v}
    for key in REFUSED_ON_RESUME:
        if key in changed and key in old:
            was, now = changed[key]
            what = "model sizes" if key == "model" else key
            raise IrlsimError(
                f"{path} was trained with {what} {_short(was)}, asked {_short(now)}: resuming cannot change "
                f"{what}; train into another --out, delete the model's folder, or set {key} back"
            )
    return changed


def _short(v: Any) -> str:
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}={x}" for k, x in v.items()) + "}"
    return repr(v)


def resume_view(cfg: TrainConfig, ckpt: dict[str, Any]) -> dict[str, Any]:
    """The asked config as compared with a checkpoint's: its stored fields, and an option left out
    at its default (irlsim.config.STORED_IF_SET) where the checkpoint recorded that option."""
    stored, recorded = to_dict(cfg), ckpt.get("config") or {}
    return {k: v for k, v in to_dict(cfg, all_fields=True).items() if k in stored or k in recorded}


def scheduled_lr(cfg: TrainConfig, step: int, steps_per_epoch: int) -> float:
    """The learning rate of optimizer step ``step`` (0-based, counted over all epochs) of a run of
    ``cfg.epochs`` epochs: ``cfg.lr`` for the 'constant' ``lr_schedule``; 'cosine':
    lr * (1 + cos(pi * step / total)) / 2, from lr down towards 0 at the last step."""
    total = cfg.epochs * steps_per_epoch
    if getattr(cfg, "lr_schedule", "constant") == "constant" or total <= 0:
        return cfg.lr
    return cfg.lr * 0.5 * (1.0 + math.cos(math.pi * min(step, total) / total))


@dataclass(frozen=True)
class DatasetRecord:
    """What every checkpoint records of the dataset it was trained on: its identity (the content hash,
    or the dataset's own ``identity``), every episode seed (drive refuses them), older identities still
    accepted on resume, and ``meta`` (schema version, feature names)."""

    identity: str | None
    seeds: list[int] | None
    legacy: tuple[str, ...]
    meta: dict[str, Any]
    #: a recording's data: the cars its episodes drove, by recording (drive refuses them); else None
    egos: dict[str, list[str]] | None = None

    @classmethod
    def of(cls, dataset: TrainingData) -> DatasetRecord:
        """The record of ``dataset``; another feature set or schema -> IrlsimError (one line)."""
        meta = dataset_meta(dataset)
        seeds, egos = dataset_seeds(dataset), dataset_egos(dataset)
        return cls(dataset_identity(dataset), seeds, legacy_identities(dataset), meta, egos)


@dataclass(frozen=True)
class RunSpec:
    """What one model's training is: model ``name`` of stage ``stage`` (1 or 2) with ``cfg``, into
    ``run_dir`` (checkpoint.pt, metrics.csv), on the dataset ``data``."""

    name: str
    stage: int
    cfg: TrainConfig
    run_dir: Path
    data: DatasetRecord


class Stage(Protocol):
    """What a stage supplies to :class:`TrainingRun` for one model (stage1.Stage1, stage2.Stage2): its
    ``spec``; ``ckpt``, the model's existing checkpoint (read and checked against the stage's own
    entries) or None; ``build()`` the network (torch is seeded with ``cfg.seed`` just before);
    ``prepare(model)`` once the network is built and resumed (a warm start, a layout); one epoch of
    optimizer steps ``train_epoch(run, epoch)`` -> its train metrics; ``validate(model)`` -> validation
    metrics; its own checkpoint ``entries()`` (by name in ``ENTRY_ORDER``) and ``summary()`` entries."""

    spec: RunSpec
    ckpt: dict[str, Any] | None

    def build(self) -> nn.Module: ...

    def prepare(self, model: nn.Module) -> None: ...

    def train_epoch(self, run: TrainingRun, epoch: int) -> dict[str, float]: ...

    def validate(self, model: nn.Module) -> dict[str, float]: ...

    def entries(self) -> dict[str, Any]: ...

    def summary(self) -> dict[str, Any]: ...


#: every checkpoint entry in the order written (the checkpoint's bytes follow it): the common ones and,
#: where a stage has them, its own (model_config, n_policies, feature_stats, base, warm_start)
ENTRY_ORDER = (
    "model",
    "stage",
    "config",
    "model_config",
    "n_policies",
    "state_dict",
    "optimizer",
    "epoch",
    "feature_stats",
    "parameters",
    "base",
    "metrics",
    "best",
    "provenance",
    "schema_version",
    "feature_names",
    "warm_start",
    "dataset",
    "dataset_seeds",
    "dataset_egos",
    "resumes",
)


def existing_checkpoint(spec: RunSpec) -> dict[str, Any] | None:
    """The checkpoint already in ``spec.run_dir`` (checked to be model ``spec.name`` of its stage), or
    None."""
    path = spec.run_dir / CHECKPOINT_NAME
    return read_checkpoint(path, model=spec.name, stage=spec.stage) if path.exists() else None


def train_model(stage: Stage) -> dict[str, Any]:
    """Train (or resume) one model with the stage's parts; returns its summary."""
    return TrainingRun(stage).fit()


class TrainingRun:
    """One model's training into ``stage.spec.run_dir``: seeds torch with ``cfg.seed``, builds the
    stage's network, resumes from ``stage.ckpt`` (weights, optimizer state, metrics, best epoch) and
    ``fit`` runs the remaining epochs."""

    def __init__(self, stage: Stage) -> None:
        spec, ckpt = stage.spec, stage.ckpt
        self.stage, self.spec = stage, spec
        self.name, self.cfg = spec.name, spec.cfg
        self.resumes: list[dict[str, Any]] = list(ckpt.get("resumes") or []) if ckpt else []
        self.ckpt_path = spec.run_dir / CHECKPOINT_NAME
        torch.manual_seed(self.cfg.seed)
        self.model = stage.build().to(current_device())
        self.optimizer = torch.optim.Adam(
            self.model.parameters(), lr=self.cfg.lr, weight_decay=self.cfg.weight_decay
        )
        self.start_epoch = 0
        if ckpt:
            self._resume(ckpt)
        self.log = MetricsLog(spec.run_dir, ckpt["metrics"] if ckpt else [], self.cfg.tensorboard)
        self.best = BestTracker(self.cfg.select_by, ckpt.get("best") if ckpt else None)
        stage.prepare(self.model)

    def _resume(self, ckpt: dict[str, Any]) -> None:
        cfg = self.cfg
        data = self.spec.data
        changed = check_resume(self.ckpt_path, ckpt, resume_view(cfg, ckpt), data.identity, data.legacy)
        self.model.load_state_dict(ckpt["state_dict"])
        self.optimizer.load_state_dict(ckpt["optimizer"])
        for group in self.optimizer.param_groups:  # the asked values, not the stored ones
            group["lr"], group["weight_decay"] = cfg.lr, cfg.weight_decay
        self.start_epoch = int(ckpt["epoch"])
        if changed and self.start_epoch < cfg.epochs:
            self.resumes.append({"epoch": self.start_epoch, "changed": changed})
            print(
                f"{self.name}: resuming after epoch {self.start_epoch} with "
                + ", ".join(f"{k} {_short(a)} -> {_short(b)}" for k, (a, b) in changed.items()),
                flush=True,
            )

    def payload(self, epochs_done: int) -> dict[str, Any]:
        """The checkpoint after ``epochs_done`` epochs: the entries every checkpoint carries and the
        stage's own, in ``ENTRY_ORDER``. Metric rows are stored without their wall times (``time/*``),
        which differ between identical runs: metrics.csv keeps them."""
        spec, data = self.spec, self.spec.data
        common = {
            "model": spec.name,
            "stage": spec.stage,
            "config": to_dict(spec.cfg),
            "state_dict": self.model.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "epoch": epochs_done,
            "parameters": count_parameters(self.model),
            "metrics": [{k: v for k, v in r.items() if not k.startswith("time/")} for r in self.log.rows],
            "best": self.best.best,
            "provenance": provenance(),
            **data.meta,
            "dataset": data.identity,
            "dataset_seeds": data.seeds,
            # only on a recording's data: every other checkpoint keeps its bytes
            **({"dataset_egos": data.egos} if data.egos else {}),
            "resumes": self.resumes,
        }
        own = self.stage.entries()
        if own.keys() & common.keys():
            raise ValueError(f"stage entries {sorted(own.keys() & common.keys())} would replace common ones")
        entries = {**common, **own}
        ordered = {k: entries.pop(k) for k in ENTRY_ORDER if k in entries}
        return {**ordered, **entries}

    def order(self, rows: np.ndarray, epoch: int) -> np.ndarray:
        """The epoch's shuffled ``rows``; depends only on (seed, epoch), so a resumed run sees the same
        batches."""
        return np.random.default_rng([self.cfg.seed, epoch]).permutation(rows)

    def step(self, loss: torch.Tensor, epoch: int, lr: float | None = None) -> None:
        """One optimizer step on ``loss`` (refused if not finite), with gradient clipping; ``lr``: this
        step's learning rate (a schedule's), else the one the optimizer has."""
        check_finite(loss, self.name, epoch, self.cfg.lr, f"stage{self.spec.stage}")
        if lr is not None:
            for group in self.optimizer.param_groups:
                group["lr"] = lr
        self.optimizer.zero_grad()
        loss.backward()
        if self.cfg.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(self.model.parameters(), self.cfg.grad_clip)
        self.optimizer.step()

    def fit(self) -> dict[str, Any]:
        """Epochs ``start_epoch .. cfg.epochs``: the stage's ``train_epoch`` -> the epoch's train
        metrics; its ``validate`` every ``validate_every`` epochs and after the last; then the metrics
        row, model selection and the checkpoint. Returns the model's summary."""
        cfg, stage = self.cfg, self.stage
        desc = f"stage {self.spec.stage} {self.name}"
        for epoch in progress(range(self.start_epoch, cfg.epochs), desc=desc, unit="epoch"):
            t0 = time.perf_counter()
            self.model.train()
            row: dict[str, Any] = {"epoch": epoch + 1, **stage.train_epoch(self, epoch)}
            if (epoch + 1) % cfg.validate_every == 0 or epoch + 1 == cfg.epochs:
                row.update(stage.validate(self.model))
            row["time/epoch_s"] = time.perf_counter() - t0
            self.log.add(row)
            self.best.update(row, self.model)
            save_checkpoint(self.ckpt_path, self.payload(epoch + 1))
        self.log.close()
        if not self.ckpt_path.exists():  # epochs == 0: still leave an (untrained) checkpoint behind
            save_checkpoint(self.ckpt_path, self.payload(0))
        return {
            "checkpoint": str(self.ckpt_path),
            **({"resumes": self.resumes} if self.resumes else {}),
            "epochs": max(cfg.epochs, self.start_epoch),
            "parameters": count_parameters(self.model),
            **stage.summary(),
            "selected_epoch": self.best.epoch,
            "final": self.log.rows[-1] if self.log.rows else {},
            "provenance": provenance(),
        }
