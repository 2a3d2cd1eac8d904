"""Stage 1: train LIRL, 1DCNN, Bi1DCNN, PACNN and PACNN+S with the path-integral max-ent IRL NLL.

Reads top to bottom: for each model -> build (or resume) -> epochs of shuffled mini-batches of train
cycles that have a demonstration -> per-epoch train metrics, validation every ``validate_every`` epochs
-> atomic checkpoint + metrics.csv each epoch.

Metrics (namespaced):
    train/nll, train/evd, train/attention_loss  means over the epoch's mini-batches (theta before the step)
    val/ed, val/opd, val/evd, val/nll, val/demo  on the sequential validation split with the mean of the
                                                 last H predicted thetas within each episode (H = history)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

import numpy as np
import torch

from irlsim.config import to_dict
from irlsim.data.tensors import SplitTensors
from irlsim.devices import forward
from irlsim.errors import IrlsimError
from irlsim.irl.objectives import (
    attention_loss,
    attention_target,
    cycle_metrics,
    evaluate_thetas,
    history_mean,
    summarize,
)
from irlsim.models.networks import PACNN, set_encoder_layout
from irlsim.models.normalization import FeatureStats, compute_feature_stats
from irlsim.models.registry import SEMI_SUPERVISED, build_model
from irlsim.train.batching import as_dataset, gather_batch, get_split, predict_split
from irlsim.train.config import Stage1Config
from irlsim.train.dataset import TrainingData
from irlsim.train.layout import CHECKPOINT_NAME
from irlsim.train.loop import (
    DatasetRecord,
    RunSpec,
    TrainingRun,
    existing_checkpoint,
    scheduled_lr,
    train_model,
)
from irlsim.train.preflight import check_trainable
from irlsim.train.repro import deterministic
from irlsim.train.warm_start import apply_warm_start, read_warm_start, warm_stats

#: the third word of the policy-sample draws' seed (seed, epoch, this): a stream of its own
POLICY_SAMPLE_STREAM = 0x5A3D


def validate_stage1(model: torch.nn.Module, split: SplitTensors, cfg: Stage1Config) -> dict[str, float]:
    """Sequential-split metrics of a stage-1 model with the H-cycle history mean of its thetas."""
    thetas = predict_split(model, split, cfg.eval_batch, keep=("theta",))["theta"]
    thetas = history_mean(thetas, np.asarray(split.episode), cfg.history)
    return {f"val/{k}": v for k, v in summarize(evaluate_thetas(thetas, split)).items()}


def _resume(spec: RunSpec, n_policies: int) -> dict[str, Any] | None:
    ckpt = existing_checkpoint(spec)
    if ckpt and ckpt["n_policies"] != n_policies:
        raise IrlsimError(
            f"checkpoint {spec.run_dir / CHECKPOINT_NAME} was trained on N={ckpt['n_policies']} policies "
            f"per cycle, the dataset has {n_policies}: delete it (or choose another output folder) to train "
            "from scratch"
        )
    return ckpt


def train_one_stage1(name: str, dataset: TrainingData, cfg: Stage1Config, out_dir: Path) -> dict[str, Any]:
    """Train (or resume) one stage-1 model into ``out_dir/<name>/``; returns its summary.

    Runs with ``cfg.threads`` torch threads and deterministic algorithms: the same seed, data, thread
    count and torch build give byte-identical weights in any process (see repro.provenance)."""
    with deterministic(cfg.threads):
        return train_model(Stage1(name, dataset, cfg, out_dir))


class Stage1:
    """Stage 1's parts of one model's training (:class:`irlsim.train.loop.Stage`): the train cycles
    that have a demonstration, the feature normalisation (the train split's, a warm start's or the
    resumed checkpoint's), the NLL (+ attention loss for PACNN+S) epoch and the history-mean
    validation."""

    def __init__(self, name: str, dataset: TrainingData, cfg: Stage1Config, out_dir: Path) -> None:
        data = DatasetRecord.of(dataset)  # refuse another feature set or schema before any work
        self.cfg = cfg
        self.train = get_split(dataset, "train", cfg.safe_demos, cfg.stop_demos)
        self.validation = get_split(dataset, "validation")
        n_cycles, n_policies = self.train.features.shape[:2]
        self.n_policies: int = n_policies
        if cfg.max_cycles:
            n_cycles = min(n_cycles, cfg.max_cycles)
        self.rows = np.flatnonzero(np.asarray(self.train.demo_index[:n_cycles]) >= 0)
        if len(self.rows) == 0:
            raise IrlsimError("the train split has no cycle with a demonstration: collect more data")
        self.spec = RunSpec(name, 1, cfg, out_dir / name, data)
        self.ckpt = _resume(self.spec, self.n_policies)
        k = self.train.control_points.shape[2]
        use_init = cfg.init_from and not self.ckpt
        self.init = read_warm_start(cfg.init_from, name, cfg.model, self.n_policies, k) if use_init else None
        if self.ckpt:
            self.stats = FeatureStats.from_dict(self.ckpt["feature_stats"])
        else:
            self.stats = warm_stats(self.init) if self.init else compute_feature_stats(self.train, n_cycles)
        self.semi = name in SEMI_SUPERVISED
        self.warm: dict[str, Any] | None = None

    def build(self) -> torch.nn.Module:
        return build_model(self.spec.name, self.cfg.model, self.n_policies, self.stats)

    def prepare(self, model: torch.nn.Module) -> None:
        """The warm start (or the resumed checkpoint's record of one) and the encoder's memory layout."""
        if self.init:
            self.warm = apply_warm_start(model, self.init, self.cfg.init_from)
        else:
            self.warm = (self.ckpt or {}).get("warm_start")
        set_encoder_layout(model, self.cfg.encoder_layout)

    def train_epoch(self, run: TrainingRun, epoch: int) -> dict[str, float]:
        """Shuffled mini-batches of the train cycles with a demonstration (of ``policy_sample``
        policies each, drawn per epoch), one optimizer step each -> the epoch's mean train metrics."""
        cfg, model = self.cfg, run.model
        steps = -(-len(self.rows) // cfg.batch_size)  # optimizer steps per epoch
        order = run.order(self.rows, epoch)
        draws = np.random.default_rng([cfg.seed, epoch, POLICY_SAMPLE_STREAM])  # resumes per epoch
        sums = {"train/nll": 0.0, "train/evd": 0.0, "train/attention_loss": 0.0}
        for i, start in enumerate(range(0, len(order), cfg.batch_size)):
            rows = np.sort(order[start : start + cfg.batch_size])
            mb = gather_batch(self.train, rows, cfg.policy_sample, draws)
            out = forward(model, mb["features"], mb["control_points"], mb["actions"])
            mb_metrics = cycle_metrics(
                out["theta"], mb["features"], mb["distances"], mb["demo_index"], mb.get("log_weights")
            )
            loss = mb_metrics["nll"].mean()
            att = torch.zeros(())
            if self.semi:
                target = attention_target(mb["distances"], cast(PACNN, model).pool, cfg.attention_tau)
                att = attention_loss(out["attention_pooled"], target).mean()
                loss = loss + cfg.attention_loss_weight * att
            at = epoch * steps + i
            run.step(loss, epoch, None if cfg.lr_schedule == "constant" else scheduled_lr(cfg, at, steps))
            n = len(mb["demo_index"])
            sums["train/nll"] += mb_metrics["nll"].detach().sum().item()
            sums["train/evd"] += mb_metrics["evd"].detach().sum().item()
            sums["train/attention_loss"] += att.item() * n
        row = {k: v / len(order) for k, v in sums.items()}
        if not self.semi:
            del row["train/attention_loss"]
        return row

    def validate(self, model: torch.nn.Module) -> dict[str, float]:
        return validate_stage1(model, self.validation, self.cfg)

    def entries(self) -> dict[str, Any]:
        return {
            "model_config": to_dict(self.cfg.model),
            "n_policies": self.n_policies,
            "feature_stats": self.stats.to_dict(),
            **({"warm_start": self.warm} if self.warm else {}),
        }

    def summary(self) -> dict[str, Any]:
        return {"warm_start": self.warm} if self.warm else {}


def train_stage1(
    dataset: TrainingData | str | Path, cfg: Stage1Config, out_dir: str | Path
) -> dict[str, Any]:
    """Train every model of ``cfg.models`` into ``out_dir/<model>/`` (checkpoint.pt, metrics.csv,
    tensorboard/). Resumes from existing checkpoints. ``dataset``: an object with
    ``split_tensors(name)`` (train, validation) or a dataset path. Returns {model: summary}."""
    dataset = as_dataset(dataset)
    check_trainable(dataset, cfg)  # empty splits, sizes beyond the memory: one line, before any work
    out_dir = Path(out_dir)
    return {name: train_one_stage1(name, dataset, cfg, out_dir) for name in cfg.models}
