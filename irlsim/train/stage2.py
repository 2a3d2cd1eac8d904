"""Stage 2: train PTACNN / PTACNN+S on the frozen PACNN / PACNN+S of stage 1.

Reads top to bottom: load the frozen PACNN -> its context vectors and thetas for every cycle of the
(sequential) train and validation splits -> H-cycle histories that never cross an episode boundary
(the first cycles of an episode repeat the episode's first cycle) -> train the temporal network with the
NLL of the next cycle t+1 (or the mean over t+1 .. t+target_ahead, plus an optional regulariser on
the temporal softmax) given the history ending at t -> checkpoint + metrics.csv each epoch.

Validation (and evaluation) convention: at cycle t every model may use cycles <= t; PTACNN's theta for
cycle t is its mixture over the history ending at t (the current cycle included), the same information
the stage-1 models' history mean uses.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch

from irlsim.config import to_dict
from irlsim.devices import forward, to_numpy
from irlsim.errors import IrlsimError
from irlsim.irl.objectives import cycle_metrics, evaluate_thetas, history_indices, summarize
from irlsim.models.networks import PTACNN
from irlsim.models.normalization import FeatureStats
from irlsim.models.registry import STAGE2_BASE, build_model
from irlsim.train.batching import as_dataset, get_split, predict_split, to_tensor
from irlsim.train.checkpoint import expected_identity, inference_state, read_checkpoint
from irlsim.train.config import Stage2Config
from irlsim.train.dataset import TrainingData
from irlsim.train.layout import CHECKPOINT_NAME
from irlsim.train.loading import rebuild_stage1
from irlsim.train.loop import DatasetRecord, RunSpec, TrainingRun, existing_checkpoint, train_model
from irlsim.train.preflight import check_trainable
from irlsim.train.repro import deterministic


@torch.no_grad()
def predict_temporal(
    model: torch.nn.Module, contexts: np.ndarray, thetas: np.ndarray, episode: np.ndarray, chunk: int = 1024
) -> tuple[np.ndarray, np.ndarray]:
    """PTACNN over a sequential split: for each cycle t the mixture over the history ending at t.

    contexts [C, Cc], thetas [C, F] (frozen PACNN outputs), episode [C] -> (theta [C, F], weights [C, H]).
    """
    model.eval()
    hist = history_indices(episode, cast(PTACNN, model).history)
    out_t, out_w = [], []
    for start in range(0, len(hist), chunk):
        h = hist[start : start + chunk]
        out = forward(model, to_tensor(contexts[h]), to_tensor(thetas[h]))
        out_t.append(to_numpy(out["theta"]))
        out_w.append(to_numpy(out["weights"]))
    if not out_t:
        return np.zeros((0, thetas.shape[-1]), np.float32), np.zeros((0, hist.shape[1]), np.float32)
    return np.concatenate(out_t), np.concatenate(out_w)


def target_rows(episode: np.ndarray, demo_index: np.ndarray, ahead: int) -> np.ndarray:
    """[C, ahead] rows t+1 .. t+ahead of every row t, -1 where that row leaves t's episode or the split
    or has no demonstration (the training targets of ``Stage2Config.target_ahead``)."""
    episode, demo_index = np.asarray(episode), np.asarray(demo_index)
    c = len(episode)
    idx = np.arange(c)[:, None] + np.arange(1, ahead + 1)[None, :]
    inside = idx < c
    j = np.minimum(idx, max(c - 1, 0))
    ok = inside & (episode[j] == episode[:, None]) & (demo_index[j] >= 0)
    return np.where(ok, idx, -1)


def weight_regulariser(weights: torch.Tensor, kind: str) -> torch.Tensor:
    """Per-sample regulariser of temporal softmax weights [B, H] -> [B]; 0 at uniform weights.
    'kl_uniform': KL(u || w) = -log H - mean_h log w_h; 'entropy': sum_h w_h log w_h + log H."""
    h = weights.shape[-1]
    logw = torch.log(weights.clamp_min(1e-12))
    if kind == "kl_uniform":
        return -math.log(h) - logw.mean(-1)
    return (weights * logw).sum(-1) + math.log(h)


def train_one_stage2(
    name: str, dataset: TrainingData, cfg: Stage2Config, out_dir: Path, base_dir: Path | None = None
) -> dict[str, Any]:
    """Train (or resume) one temporal model into ``out_dir/<name>/`` on the frozen stage-1 model in
    ``base_dir/<base>/`` (default ``out_dir``); returns its summary. Deterministic like stage 1."""
    with deterministic(cfg.threads):
        return train_model(Stage2(name, dataset, cfg, out_dir, out_dir if base_dir is None else base_dir))


def frozen_base(name: str, base_dir: Path, data: DatasetRecord) -> tuple[dict[str, Any], dict[str, Any]]:
    """The checkpoint of the stage-1 model that temporal model ``name`` trains on (in ``base_dir``,
    trained on the dataset ``data``), and its checkpoint entry 'base': the validation-selected weights
    and what rebuilds it. Missing folder or checkpoint, another dataset -> IrlsimError (one line)."""
    base_name = STAGE2_BASE[name]
    base_path = base_dir / base_name / CHECKPOINT_NAME
    if not base_dir.is_dir():
        raise IrlsimError(
            f"{name} needs the stage-1 folder {base_dir}, which does not exist: run 'irlsim train --stage 1' "
            "into it first (or point --base at the folder holding PACNN/ and PACNN+S/)"
        )
    if not base_path.exists():
        raise IrlsimError(
            f"{name} needs a trained {base_name} ({base_path} not found): run stage 1 with {base_name} in "
            "its models first (or point --base at the folder holding it)"
        )
    base_model, base_stage = expected_identity(base_path)
    base_ckpt = read_checkpoint(
        base_path, model=base_model or base_name, stage=base_stage, dataset=data.identity, legacy=data.legacy
    )
    entry = {k: base_ckpt[k] for k in ("model", "model_config", "n_policies", "feature_stats", "parameters")}
    # the frozen base is the validation-selected PACNN (what rebuild_stage1 loads)
    entry["state_dict"] = inference_state(base_ckpt)
    entry["selected_epoch"] = (base_ckpt.get("best") or {}).get("epoch", base_ckpt["epoch"])
    return base_ckpt, entry


class Stage2:
    """Stage 2's parts of one temporal model's training (:class:`irlsim.train.loop.Stage`): the frozen
    PACNN's contexts and thetas for every cycle of the sequential splits, the H-cycle histories and
    their target rows, the next-cycle NLL epoch and the temporal mixture's validation."""

    def __init__(
        self, name: str, dataset: TrainingData, cfg: Stage2Config, out_dir: Path, base_dir: Path
    ) -> None:
        data = DatasetRecord.of(dataset)  # refuse another feature set or schema before any work
        self.cfg = cfg
        self.base_ckpt, self.base_entry = frozen_base(name, base_dir, data)
        base = rebuild_stage1(self.base_ckpt)
        for p in base.parameters():
            p.requires_grad_(False)
        latent = int(self.base_ckpt["model_config"]["latent"])
        self.model_cfg = dataclasses.replace(cfg.model, latent=latent)
        self._frozen_outputs(base, dataset, STAGE2_BASE[name])
        self.spec = RunSpec(name, 2, cfg, out_dir / name, data)
        self.ckpt = existing_checkpoint(self.spec)
        if self.ckpt and not self._same_base(self.ckpt):
            raise IrlsimError(
                f"checkpoint {self.spec.run_dir / CHECKPOINT_NAME} was trained on another "
                f"{STAGE2_BASE[name]} or with other sizes: delete it to retrain"
            )

    def _frozen_outputs(self, base: torch.nn.Module, dataset: TrainingData, base_name: str) -> None:
        """The frozen base's outputs for every cycle of the sequential splits, the train histories and
        the (cycle, target cycles) pairs trained on."""
        cfg = self.cfg
        self.train = get_split(dataset, "train", cfg.safe_demos, cfg.stop_demos)
        self.validation = get_split(dataset, "validation")
        n_cycles = self.train.features.shape[0]
        n_cycles = min(cfg.max_cycles, n_cycles) if cfg.max_cycles else n_cycles
        keep = ("theta", "context")  # not the attention: 4 N bytes a cycle that stage 2 does not read
        self.tr = predict_split(base, self.train, cfg.eval_batch, desc=f"{base_name} on train", keep=keep)
        self.va = predict_split(
            base, self.validation, cfg.eval_batch, desc=f"{base_name} on validation", keep=keep
        )
        train_episode = np.asarray(self.train.episode)[:n_cycles]
        self.hist = history_indices(train_episode, self.model_cfg.history)
        demo = np.asarray(self.train.demo_index)[:n_cycles]
        self.targets = target_rows(train_episode, demo, cfg.target_ahead)
        self.pairs = np.flatnonzero((self.targets >= 0).any(1))
        if len(self.pairs) == 0:
            raise IrlsimError(
                "the train split has no (cycle, next cycle with a demonstration) pair: collect more"
            )

    def _same_base(self, ckpt: dict[str, Any]) -> bool:
        """Whether a checkpoint was trained with these sizes on these frozen base weights."""
        theirs, ours = ckpt["base"]["state_dict"], self.base_entry["state_dict"]
        return (
            ckpt["model_config"] == to_dict(self.model_cfg)
            and theirs.keys() == ours.keys()
            and all(torch.equal(theirs[k], v) for k, v in ours.items())
        )

    def build(self) -> torch.nn.Module:
        fstats = FeatureStats.from_dict(self.base_ckpt["feature_stats"])
        return build_model(self.spec.name, self.model_cfg, 1, fstats)

    def prepare(self, model: torch.nn.Module) -> None:
        """Nothing: a temporal model starts from its seeded initial weights (or the resumed ones)."""

    def train_epoch(self, run: TrainingRun, epoch: int) -> dict[str, float]:
        """Shuffled mini-batches of (history, target cycles) pairs, one optimizer step each on the mean
        NLL of each sample's targets (plus the weight regulariser) -> the epoch's mean train metrics."""
        cfg, train, tr, hist, targets = self.cfg, self.train, self.tr, self.hist, self.targets
        order = run.order(self.pairs, epoch)
        sums = {"train/nll": 0.0, "train/evd": 0.0}
        for start in range(0, len(order), cfg.batch_size):
            mb_t = np.sort(order[start : start + cfg.batch_size])
            out = forward(run.model, to_tensor(tr["context"][hist[mb_t]]), to_tensor(tr["theta"][hist[mb_t]]))
            # every (sample, target cycle) pair at once: rows t+1 .. t+target_ahead that exist
            tgt = targets[mb_t]  # [B, A]
            b_idx, a_idx = np.nonzero(tgt >= 0)
            rows = tgt[b_idx, a_idx]
            m = cycle_metrics(
                out["theta"][torch.as_tensor(b_idx)],
                to_tensor(train.features[rows]),
                to_tensor(train.distances[rows]),
                to_tensor(train.demo_index[rows], torch.int64),
            )
            # mean over each sample's targets, then over the batch
            nll = m["nll"]
            per = torch.zeros(len(mb_t), dtype=nll.dtype, device=nll.device)
            per = per.index_add_(0, to_tensor(b_idx, torch.int64), nll)
            per = per / to_tensor((tgt >= 0).sum(1), per.dtype)
            loss = per.mean()
            if cfg.weight_reg > 0:
                loss = loss + cfg.weight_reg * weight_regulariser(out["weights"], cfg.weight_reg_kind).mean()
            run.step(loss, epoch)
            sums["train/nll"] += per.detach().sum().item()
            sums["train/evd"] += m["evd"].detach().mean().item() * len(mb_t)
        return {k: v / len(order) for k, v in sums.items()}

    def validate(self, model: torch.nn.Module) -> dict[str, float]:
        va, episode = self.va, np.asarray(self.validation.episode)
        thetas, w = predict_temporal(model, va["context"], va["theta"], episode)
        row = {f"val/{k}": v for k, v in summarize(evaluate_thetas(thetas, self.validation)).items()}
        row["val/newest_weight"] = float(w[:, -1].mean()) if len(w) else float("nan")
        return row

    def entries(self) -> dict[str, Any]:
        return {
            "model_config": to_dict(self.model_cfg),
            "feature_stats": self.base_ckpt["feature_stats"],
            "base": self.base_entry,
        }

    def summary(self) -> dict[str, Any]:
        return {"base_parameters": int(self.base_ckpt["parameters"])}


def train_stage2(
    dataset: TrainingData | str | Path,
    cfg: Stage2Config,
    out_dir: str | Path,
    base_dir: str | Path | None = None,
) -> dict[str, Any]:
    """Train every model of ``cfg.models`` into ``out_dir/<model>/`` on the frozen stage-1 checkpoints
    ``base_dir/PACNN`` / ``base_dir/PACNN+S`` (``base_dir`` defaults to ``out_dir``; ``irlsim train --stage
    2 --out RUNS`` passes ``RUNS/stage2`` and ``RUNS/stage1``). Resumes from existing checkpoints.
    Returns {model: summary}."""
    dataset = as_dataset(dataset)
    check_trainable(dataset, cfg)  # empty splits, sizes beyond the memory: one line, before any work
    out, base = Path(out_dir), Path(base_dir) if base_dir is not None else None
    return {name: train_one_stage2(name, dataset, cfg, out, base) for name in cfg.models}
