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

import time
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch

from irlsim.config import to_dict
from irlsim.errors import IrlsimError
from irlsim.irl.objectives import (
    attention_loss,
    attention_target,
    cycle_metrics,
    evaluate_thetas,
    history_mean,
    summarize,
)
from irlsim.models.networks import PACNN
from irlsim.models.normalization import FeatureStats, compute_feature_stats
from irlsim.models.registry import SEMI_SUPERVISED, build_model, count_parameters
from irlsim.train.common import (
    CHECKPOINT_NAME,
    BestTracker,
    MetricsLog,
    as_dataset,
    check_finite,
    dataset_meta,
    deterministic,
    gather_batch,
    get_split,
    predict_split,
    provenance,
    read_checkpoint,
    save_checkpoint,
)
from irlsim.train.config import Stage1Config
from irlsim.utils import progress


def validate_stage1(model: torch.nn.Module, split: Any, cfg: Stage1Config) -> dict[str, float]:
    """Sequential-split metrics of a stage-1 model with the H-cycle history mean of its thetas."""
    thetas = predict_split(model, split, cfg.eval_batch)["theta"]
    thetas = history_mean(thetas, np.asarray(split.episode), cfg.history)
    return {f"val/{k}": v for k, v in summarize(evaluate_thetas(thetas, split)).items()}


def _resume(path: Path, name: str, cfg: Stage1Config, n_policies: int) -> dict[str, Any] | None:
    if not path.exists():
        return None
    ckpt = read_checkpoint(path)
    if (
        ckpt["model"] != name
        or ckpt["model_config"] != to_dict(cfg.model)
        or ckpt["n_policies"] != n_policies
    ):
        raise IrlsimError(
            f"checkpoint {path} was trained with other model sizes or another dataset: "
            "delete it (or choose another output folder) to train from scratch"
        )
    return ckpt


def train_one_stage1(name: str, dataset: Any, cfg: Stage1Config, out_dir: Path) -> dict[str, Any]:
    """Train (or resume) one stage-1 model into ``out_dir/<name>/``; returns its summary.

    Runs with ``cfg.threads`` torch threads and deterministic algorithms: the same seed, data, thread
    count and torch build give byte-identical weights in any process (see common.provenance)."""
    with deterministic(cfg.threads):
        return _train_one_stage1(name, dataset, cfg, out_dir)


# size-ok: to be replaced by the one training loop of issue 15 point 3 (wt/reliability)
def _train_one_stage1(name: str, dataset: Any, cfg: Stage1Config, out_dir: Path) -> dict[str, Any]:
    meta = dataset_meta(dataset)  # refuse another feature set or schema before any work
    run_dir = out_dir / name
    ckpt_path = run_dir / CHECKPOINT_NAME
    train = get_split(dataset, "train")
    validation = get_split(dataset, "validation")
    n_cycles, n_policies = train.features.shape[:2]
    if cfg.max_cycles:
        n_cycles = min(n_cycles, cfg.max_cycles)
    train_rows = np.flatnonzero(np.asarray(train.demo_index[:n_cycles]) >= 0)
    if len(train_rows) == 0:
        raise IrlsimError("the train split has no cycle with a demonstration: collect more data")

    ckpt = _resume(ckpt_path, name, cfg, n_policies)
    stats = FeatureStats.from_dict(ckpt["feature_stats"]) if ckpt else compute_feature_stats(train, n_cycles)
    torch.manual_seed(cfg.seed)
    model = build_model(name, cfg.model, n_policies, stats)
    optimizer = torch.optim.Adam(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    start_epoch = 0
    if ckpt:
        model.load_state_dict(ckpt["state_dict"])
        optimizer.load_state_dict(ckpt["optimizer"])
        start_epoch = int(ckpt["epoch"])
    log = MetricsLog(run_dir, ckpt["metrics"] if ckpt else [], cfg.tensorboard)
    best = BestTracker(cfg.select_by, ckpt.get("best") if ckpt else None)
    semi = name in SEMI_SUPERVISED

    def checkpoint(epochs_done: int) -> dict[str, Any]:
        return {
            "model": name,
            "stage": 1,
            "config": to_dict(cfg),
            "model_config": to_dict(cfg.model),
            "n_policies": n_policies,
            "state_dict": model.state_dict(),
            "optimizer": optimizer.state_dict(),
            "epoch": epochs_done,
            "feature_stats": stats.to_dict(),
            "parameters": count_parameters(model),
            "metrics": log.rows,
            "best": best.best,
            "provenance": provenance(),
            **meta,
        }

    for epoch in progress(range(start_epoch, cfg.epochs), desc=f"stage 1 {name}", unit="epoch"):
        t0 = time.perf_counter()
        model.train()
        # shuffling depends only on (seed, epoch), so a resumed run sees the same batches
        order = np.random.default_rng([cfg.seed, epoch]).permutation(train_rows)
        sums = {"train/nll": 0.0, "train/evd": 0.0, "train/attention_loss": 0.0}
        for start in range(0, len(order), cfg.batch_size):
            mb = gather_batch(train, np.sort(order[start : start + cfg.batch_size]))
            out = model(mb["features"], mb["control_points"], mb["actions"])
            mb_metrics = cycle_metrics(out["theta"], mb["features"], mb["distances"], mb["demo_index"])
            loss = mb_metrics["nll"].mean()
            att = torch.zeros(())
            if semi:
                target = attention_target(mb["distances"], cast(PACNN, model).pool, cfg.attention_tau)
                att = attention_loss(out["attention_pooled"], target).mean()
                loss = loss + cfg.attention_loss_weight * att
            check_finite(loss, name, epoch, cfg.lr, "stage1")
            optimizer.zero_grad()
            loss.backward()
            if cfg.grad_clip > 0:
                torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
            optimizer.step()
            n = len(mb["demo_index"])
            sums["train/nll"] += mb_metrics["nll"].detach().sum().item()
            sums["train/evd"] += mb_metrics["evd"].detach().sum().item()
            sums["train/attention_loss"] += att.item() * n
        row: dict[str, Any] = {"epoch": epoch + 1, **{k: v / len(order) for k, v in sums.items()}}
        if not semi:
            del row["train/attention_loss"]
        if (epoch + 1) % cfg.validate_every == 0 or epoch + 1 == cfg.epochs:
            row.update(validate_stage1(model, validation, cfg))
        row["time/epoch_s"] = time.perf_counter() - t0
        log.add(row)
        best.update(row, model)
        save_checkpoint(ckpt_path, checkpoint(epoch + 1))
    log.close()
    if not ckpt_path.exists():  # epochs == 0: still leave an (untrained) checkpoint behind
        save_checkpoint(ckpt_path, checkpoint(0))
    return {
        "checkpoint": str(ckpt_path),
        "epochs": max(cfg.epochs, start_epoch),
        "parameters": count_parameters(model),
        "selected_epoch": best.epoch,
        "final": log.rows[-1] if log.rows else {},
        "provenance": provenance(),
    }


def train_stage1(dataset: Any, cfg: Stage1Config, out_dir: str | Path) -> dict[str, Any]:
    """Train every model of ``cfg.models`` into ``out_dir/<model>/`` (checkpoint.pt, metrics.csv,
    tensorboard/). Resumes from existing checkpoints. ``dataset``: an object with
    ``split_tensors(name)`` (train, validation) or a dataset path. Returns {model: summary}."""
    dataset = as_dataset(dataset)
    out_dir = Path(out_dir)
    return {name: train_one_stage1(name, dataset, cfg, out_dir) for name in cfg.models}
