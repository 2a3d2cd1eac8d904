"""Shared pieces of the training stages: split access, batched prediction, checkpoints, metric logs."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from irlsim import FEATURE_NAMES
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.errors import IrlsimError
from irlsim.models.normalization import FeatureStats
from irlsim.models.registry import MODEL_NAMES, STAGE2_BASE, ModelConfig, build_model
from irlsim.utils import atomic_path, atomic_write_text

CHECKPOINT_NAME = "checkpoint.pt"
METRICS_NAME = "metrics.csv"
#: version of the checkpoint layout written here
CHECKPOINT_FORMAT = 1
#: sub-folders of a runs folder, one per training stage (``<runs>/stage1/<model>/``, ...)
STAGE_FOLDERS: dict[int, str] = {1: "stage1", 2: "stage2"}


# ------------------------------------------------------------------------------------------ runs layout


def stage_dir(runs: str | Path, stage: int) -> Path:
    """The output folder of training stage ``stage`` (1 or 2) inside the runs folder ``runs``."""
    return Path(runs) / STAGE_FOLDERS[stage]


def model_stage(name: str) -> int:
    return 2 if name in STAGE2_BASE else 1


def find_checkpoint(runs: str | Path, name: str) -> Path | None:
    """Where model ``name``'s checkpoint is in ``runs``, or None: ``<runs>/stage{1,2}/<name>/checkpoint.pt``
    (what ``irlsim train --out RUNS`` writes) if ``runs`` has a stage folder, else
    ``<runs>/<name>/checkpoint.pt`` (``runs`` is itself a stage folder, or a flat folder written by the
    library's ``train_stage1`` / ``train_stage2`` or by irlsim before the stage folders). A runs folder
    with stage folders is read only through them, so a stale checkpoint of the flat layout beside them is
    never mixed into a table."""
    runs = Path(runs)
    if any(stage_dir(runs, s).is_dir() for s in STAGE_FOLDERS):
        path = stage_dir(runs, model_stage(name)) / name / CHECKPOINT_NAME
    else:
        path = runs / name / CHECKPOINT_NAME
    return path if path.is_file() else None


# -------------------------------------------------------------------------------------- reproducibility


def provenance() -> dict[str, Any]:
    """What besides seeds and data decides the trained bytes: torch's version, its CPU thread count and
    the vector instruction set its kernels dispatch to. The same seed and data give the same weights on
    every run with these three equal; a different thread count or instruction set (another CPU) changes
    the float summation order of convolutions and matrix products, so the weights differ in the last bits
    and the selected epoch (and Table I) can differ visibly."""
    return {
        "torch": str(torch.__version__),  # a TorchVersion, which weights_only loading refuses
        "threads": int(torch.get_num_threads()),
        "cpu_capability": str(torch.backends.cpu.get_cpu_capability()),
    }


@contextmanager
def num_threads(threads: int) -> Iterator[None]:
    """Run torch with ``threads`` CPU threads; restores the caller's count after."""
    old = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        yield
    finally:
        torch.set_num_threads(old)


@contextmanager
def deterministic(threads: int) -> Iterator[None]:
    """Run torch with ``threads`` CPU threads and deterministic algorithms only (an op without a
    deterministic CPU kernel raises instead of silently varying between runs); restores both after."""
    old_det = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)
    try:
        with num_threads(threads):
            yield
    finally:
        torch.use_deterministic_algorithms(old_det)


def as_dataset(dataset: Any) -> Any:
    """A dataset object (anything with ``split_tensors(name)``), or a path opened with the data reader."""
    if isinstance(dataset, (str, Path)):
        from irlsim.data.reader import open_dataset  # lazy: the data layer is optional for the math

        return open_dataset(dataset)
    return dataset


def get_split(dataset: Any, name: str) -> Any:
    """The SplitTensors of split ``name`` (train / validation / test)."""
    split = dataset.split_tensors(name)
    c, n = split.features.shape[:2]
    assert split.distances.shape == (c, n) and split.demo_index.shape == (c,), f"split {name} is inconsistent"
    return split


def dataset_meta(dataset: Any) -> dict[str, Any]:
    """Schema version and feature names stored in checkpoints (from ``dataset.manifest``; an in-memory
    dataset without one is taken to be current)."""
    manifest = getattr(dataset, "manifest", None) or {}
    names = list(manifest.get("feature_names", FEATURE_NAMES))
    version = manifest.get("schema_version", SCHEMA_VERSION)
    if names != list(FEATURE_NAMES):
        raise IrlsimError(
            f"dataset features {names} differ from this irlsim's {list(FEATURE_NAMES)}: "
            "re-run 'irlsim collect'"
        )
    if version != SCHEMA_VERSION:
        raise IrlsimError(
            f"dataset schema version {version} differs from this irlsim's {SCHEMA_VERSION}: "
            "re-run 'irlsim collect'"
        )
    return {"schema_version": version, "feature_names": names}


def check_split_shape(name: str, entry: dict[str, Any], split: Any, split_name: str) -> None:
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
    return torch.as_tensor(np.ascontiguousarray(a), dtype=dtype)


def gather_batch(split: Any, rows: np.ndarray) -> dict[str, torch.Tensor]:
    """Mini-batch of cycles ``rows`` (prefix ``b_``-style tensors): features, control_points, actions,
    distances, demo_index."""
    rows = np.asarray(rows)
    return {
        "features": to_tensor(split.features[rows]),
        "control_points": to_tensor(split.control_points[rows]),
        "actions": to_tensor(split.actions[rows]),
        "distances": to_tensor(split.distances[rows]),
        "demo_index": to_tensor(split.demo_index[rows], torch.int64),
    }


@torch.no_grad()
def predict_split(
    model: nn.Module, split: Any, chunk: int = 64, desc: str | None = None
) -> dict[str, np.ndarray]:
    """Run a stage-1 model over every cycle of ``split`` in chunks.

    -> {'theta': [C, 15] float32, and for PACNN 'context': [C, Cc], 'attention': [C, N] float32}.
    """
    from irlsim.utils import progress

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
        out = model(b["features"], b["control_points"], b["actions"])
        for k in ("theta", "context", "attention"):
            if k in out:
                parts.setdefault(k, []).append(out[k].numpy())
    return (
        {k: np.concatenate(v) for k, v in parts.items()}
        if parts
        else {"theta": np.zeros((0, 15), np.float32)}
    )


# ------------------------------------------------------------------------------------------- checkpoints


def save_checkpoint(path: Path, payload: dict[str, Any]) -> None:
    """torch.save ``payload`` atomically (temporary file, then rename)."""
    payload = {"format": CHECKPOINT_FORMAT, **payload}
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)


def read_checkpoint(path: str | Path) -> dict[str, Any]:
    """Load a checkpoint written by this package; missing or corrupt -> IrlsimError (one line)."""
    path = Path(path)
    if not path.is_file():
        raise IrlsimError(f"checkpoint {path} not found: run 'irlsim train' first (or check --runs)")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises many types for truncated / garbage files
        raise IrlsimError(
            f"checkpoint {path} is corrupt or unreadable ({type(e).__name__}): delete it and train again"
        ) from None
    if not isinstance(ckpt, dict) or "state_dict" not in ckpt or ckpt.get("model") not in MODEL_NAMES:
        raise IrlsimError(f"checkpoint {path} is not an irlsim model checkpoint: delete it and train again")
    if ckpt.get("format") != CHECKPOINT_FORMAT:
        raise IrlsimError(
            f"checkpoint {path} has format {ckpt.get('format')}, this irlsim reads {CHECKPOINT_FORMAT}: "
            "retrain"
        )
    # its theta weighs the features by position: another feature set or schema makes it meaningless
    names = list(ckpt.get("feature_names") or ())
    if names != list(FEATURE_NAMES):
        differ = sorted(set(names) ^ set(FEATURE_NAMES))
        what = f"features {', '.join(differ)} differ" if differ else "its features are in another order"
        raise IrlsimError(
            f"checkpoint {path} was trained on another feature set than this irlsim's ({what}): delete it "
            "and retrain on a dataset collected by this irlsim"
        )
    if ckpt.get("schema_version") != SCHEMA_VERSION:
        raise IrlsimError(
            f"checkpoint {path} was trained on dataset schema version {ckpt.get('schema_version')}, this "
            f"irlsim reads {SCHEMA_VERSION}: delete it and retrain on a dataset collected by this irlsim"
        )
    return ckpt


def model_config_from(d: dict[str, Any]) -> ModelConfig:
    from irlsim.config import from_dict

    return from_dict(ModelConfig, d)


def inference_state(entry: dict[str, Any]) -> dict[str, Any]:
    """The weights used for inference: the validation-selected ones (``entry['best']``) when the
    checkpoint has them, else the latest (``entry['state_dict']``, which resuming always uses)."""
    best = entry.get("best")
    return best["state_dict"] if best else entry["state_dict"]


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


def rebuild_stage1(entry: dict[str, Any]) -> nn.Module:
    """Stage-1 model from a checkpoint (or a stage-2 checkpoint's 'base' entry), in eval mode."""
    model = build_model(
        entry["model"],
        model_config_from(entry["model_config"]),
        int(entry["n_policies"]),
        FeatureStats.from_dict(entry["feature_stats"]),
    )
    model.load_state_dict(inference_state(entry))
    return model.eval()


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


def load_model(checkpoint_path: str | Path) -> LoadedModel:
    """Load any model checkpoint (``<runs>/<model>/checkpoint.pt``) for inference (eval mode, CPU)."""
    ckpt = read_checkpoint(checkpoint_path)
    name = ckpt["model"]
    try:
        if name in STAGE2_BASE:
            base = rebuild_stage1(ckpt["base"])
            cfg = model_config_from(ckpt["model_config"])
            model = build_model(name, cfg, 1, FeatureStats.from_dict(ckpt["base"]["feature_stats"]))
            model.load_state_dict(inference_state(ckpt))
            return LoadedModel(name, model.eval(), base, cfg.history, ckpt)
        return LoadedModel(name, rebuild_stage1(ckpt), None, None, ckpt)
    except (KeyError, RuntimeError, TypeError) as e:
        raise IrlsimError(
            f"checkpoint {checkpoint_path} does not match this irlsim's {name} ({type(e).__name__}): retrain"
        ) from None


# --------------------------------------------------------------------------------------------- metric logs


class MetricsLog:
    """Per-epoch metric rows -> ``metrics.csv`` (rewritten atomically each epoch) and TensorBoard.

    Keys are namespaced (``train/nll``, ``val/ed``); an epoch without validation leaves the ``val/``
    columns empty. TensorBoard is used only if ``torch.utils.tensorboard`` imports (tensorboard installed);
    otherwise it is skipped silently.
    """

    def __init__(self, out_dir: Path, rows: list[dict[str, Any]] | None, tensorboard: bool) -> None:
        self.path = out_dir / METRICS_NAME
        self.rows = list(rows or [])
        self.writer = None
        if tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter

                self.writer = SummaryWriter(str(out_dir / "tensorboard"))
            except Exception:  # tensorboard not installed (or broken): CSV only
                self.writer = None

    def add(self, row: dict[str, Any]) -> None:
        self.rows.append(row)
        keys: list[str] = []
        for r in self.rows:
            keys += [k for k in r if k not in keys]
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
        w.writeheader()
        for r in self.rows:
            w.writerow({k: ("" if v is None else v) for k, v in r.items()})
        atomic_write_text(self.path, buf.getvalue())
        if self.writer is not None:
            for k, v in row.items():
                if k != "epoch" and isinstance(v, (int, float)) and np.isfinite(v):
                    self.writer.add_scalar(k, v, int(row["epoch"]))
            self.writer.flush()

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


def read_metrics(path: str | Path) -> list[dict[str, float]]:
    """metrics.csv -> rows of floats (empty cells -> NaN); missing file -> []."""
    path = Path(path)
    if not path.is_file():
        return []
    with path.open() as f:
        return [
            {k: (float(v) if v not in ("", None) else float("nan")) for k, v in r.items()}
            for r in csv.DictReader(f)
        ]


def check_finite(loss: torch.Tensor, model: str, epoch: int, lr: float, stage: str) -> None:
    if not torch.isfinite(loss):
        raise IrlsimError(
            f"{model}: the loss became {loss.item()} in epoch {epoch + 1}: lower {stage}.lr (now {lr:g}) "
            "or check the dataset for non-finite features"
        )
