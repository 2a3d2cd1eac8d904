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
from irlsim.models.registry import SEMI_SUPERVISED, build_model, count_parameters
from irlsim.train.batching import as_dataset, dataset_meta, gather_batch, get_split, predict_split
from irlsim.train.checkpoint import (
    dataset_identity,
    dataset_seeds,
    legacy_identities,
    read_checkpoint,
)
from irlsim.train.config import Stage1Config
from irlsim.train.layout import CHECKPOINT_NAME
from irlsim.train.loop import TrainingRun, scheduled_lr
from irlsim.train.preflight import check_trainable
from irlsim.train.repro import deterministic, provenance
from irlsim.train.warm_start import apply_warm_start, read_warm_start, warm_stats

#: the third word of the policy-sample draws' seed (seed, epoch, this): a stream of its own
POLICY_SAMPLE_STREAM = 0x5A3D


def validate_stage1(model: torch.nn.Module, split: Any, cfg: Stage1Config) -> dict[str, float]:
    """Sequential-split metrics of a stage-1 model with the H-cycle history mean of its thetas."""
    thetas = predict_split(model, split, cfg.eval_batch, keep=("theta",))["theta"]
    thetas = history_mean(thetas, np.asarray(split.episode), cfg.history)
    return {f"val/{k}": v for k, v in summarize(evaluate_thetas(thetas, split)).items()}


def _resume(path: Path, name: str, cfg: Stage1Config, n_policies: int) -> dict[str, Any] | None:
    if not path.exists():
        return None
    ckpt = read_checkpoint(path, model=name, stage=1)
    if ckpt["n_policies"] != n_policies:
        raise IrlsimError(
            f"checkpoint {path} was trained on N={ckpt['n_policies']} policies per cycle, the dataset has "
            f"{n_policies}: delete it (or choose another output folder) to train from scratch"
        )
    return ckpt


def train_one_stage1(name: str, dataset: Any, cfg: Stage1Config, out_dir: Path) -> dict[str, Any]:
    """Train (or resume) one stage-1 model into ``out_dir/<name>/``; returns its summary.

    Runs with ``cfg.threads`` torch threads and deterministic algorithms: the same seed, data, thread
    count and torch build give byte-identical weights in any process (see repro.provenance)."""
    with deterministic(cfg.threads):
        return _train_one_stage1(name, dataset, cfg, out_dir)


# size-ok: stage 1's epoch and checkpoint entries, closures over one TrainingRun (irlsim.train.loop)
def _train_one_stage1(name: str, dataset: Any, cfg: Stage1Config, out_dir: Path) -> dict[str, Any]:
    meta = dataset_meta(dataset)  # refuse another feature set or schema before any work
    run_dir = out_dir / name
    train = get_split(dataset, "train", cfg.safe_demos, cfg.stop_demos)
    validation = get_split(dataset, "validation")
    n_cycles, n_policies = train.features.shape[:2]
    if cfg.max_cycles:
        n_cycles = min(n_cycles, cfg.max_cycles)
    train_rows = np.flatnonzero(np.asarray(train.demo_index[:n_cycles]) >= 0)
    if len(train_rows) == 0:
        raise IrlsimError("the train split has no cycle with a demonstration: collect more data")

    ckpt = _resume(run_dir / CHECKPOINT_NAME, name, cfg, n_policies)
    k = train.control_points.shape[2]
    init = (
        read_warm_start(cfg.init_from, name, cfg.model, n_policies, k) if cfg.init_from and not ckpt else None
    )
    if ckpt:
        stats = FeatureStats.from_dict(ckpt["feature_stats"])
    else:
        stats = warm_stats(init) if init else compute_feature_stats(train, n_cycles)
    ident = dataset_identity(dataset)
    run = TrainingRun(
        name,
        1,
        cfg,
        run_dir,
        ckpt,
        lambda: build_model(name, cfg.model, n_policies, stats),
        ident,
        dataset_seeds(dataset),
        legacy_identities(dataset),
    )
    model = run.model
    warm = apply_warm_start(model, init, cfg.init_from) if init else (ckpt or {}).get("warm_start")
    set_encoder_layout(model, cfg.encoder_layout)
    semi = name in SEMI_SUPERVISED
    steps = -(-len(train_rows) // cfg.batch_size)  # optimizer steps per epoch

    def train_epoch(epoch: int) -> dict[str, float]:
        order = run.order(train_rows, epoch)
        draws = np.random.default_rng([cfg.seed, epoch, POLICY_SAMPLE_STREAM])  # resumes per epoch
        sums = {"train/nll": 0.0, "train/evd": 0.0, "train/attention_loss": 0.0}
        for i, start in enumerate(range(0, len(order), cfg.batch_size)):
            rows = np.sort(order[start : start + cfg.batch_size])
            mb = gather_batch(train, rows, cfg.policy_sample, draws)
            out = forward(model, mb["features"], mb["control_points"], mb["actions"])
            mb_metrics = cycle_metrics(
                out["theta"], mb["features"], mb["distances"], mb["demo_index"], mb.get("log_weights")
            )
            loss = mb_metrics["nll"].mean()
            att = torch.zeros(())
            if semi:
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
        if not semi:
            del row["train/attention_loss"]
        return row

    def checkpoint(epochs_done: int) -> dict[str, Any]:
        return {
            "model": name,
            "stage": 1,
            "config": to_dict(cfg),
            "model_config": to_dict(cfg.model),
            "n_policies": n_policies,
            "state_dict": model.state_dict(),
            "optimizer": run.optimizer.state_dict(),
            "epoch": epochs_done,
            "feature_stats": stats.to_dict(),
            "parameters": count_parameters(model),
            "metrics": run.log.rows,
            "best": run.best.best,
            "provenance": provenance(),
            **meta,
            **({"warm_start": warm} if warm else {}),
        }

    extra = {"warm_start": warm} if warm else None
    return run.fit(train_epoch, lambda: validate_stage1(model, validation, cfg), checkpoint, extra)


def train_stage1(dataset: Any, cfg: Stage1Config, out_dir: str | Path) -> dict[str, Any]:
    """Train every model of ``cfg.models`` into ``out_dir/<model>/`` (checkpoint.pt, metrics.csv,
    tensorboard/). Resumes from existing checkpoints. ``dataset``: an object with
    ``split_tensors(name)`` (train, validation) or a dataset path. Returns {model: summary}."""
    dataset = as_dataset(dataset)
    check_trainable(dataset, cfg)  # empty splits, sizes beyond the memory: one line, before any work
    out_dir = Path(out_dir)
    return {name: train_one_stage1(name, dataset, cfg, out_dir) for name in cfg.models}
