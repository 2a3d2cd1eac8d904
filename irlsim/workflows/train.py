"""Training one stage into a runs folder (``irlsim train``): :func:`train_models` with :class:`TrainRun`.

Each stage has its own config (``configs/train/stage1.toml``, ``stage2.toml``) and its own output folder
inside the runs folder ``out``: stage 1 writes ``out/stage1/<model>/``, stage 2 writes
``out/stage2/<model>/`` and reads its frozen PACNN / PACNN+S from ``base`` (default ``out/stage1``).
Each model folder holds ``checkpoint.pt`` (atomic, resumable), ``metrics.csv`` and ``tensorboard/``;
``out/stage<N>/summary.json`` records the config, the data and each model's summary. One training at a
time per runs folder (``out/.lock``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim import devices
from irlsim.config import to_dict
from irlsim.data.aggregate import open_datasets, remove_obsolete_caches
from irlsim.errors import IrlsimError
from irlsim.models.registry import STAGE1_MODELS, STAGE2_BASE, format_parameters
from irlsim.outputs import check_output_dir
from irlsim.train.checkpoint import dataset_identity
from irlsim.train.config import Stage1Config, Stage2Config
from irlsim.train.layout import SUMMARY_NAME, find_checkpoint, stage_dir
from irlsim.train.preflight import check_trainable
from irlsim.train.stage1 import train_stage1
from irlsim.train.stage2 import train_stage2
from irlsim.utils import LockBusy, exclusive_lock, write_json

#: the lock file of a runs folder while a training writes it (as collect's in a dataset folder)
LOCK_NAME = ".lock"
#: [bytes] disk a model's folder may take (checkpoint with latest + best weights and optimizer state,
#: metrics.csv): an upper estimate for the default sizes (PACNN's checkpoint is ~1 MB)
CHECKPOINT_BYTES = 16 << 20


@dataclass(frozen=True)
class TrainRun:
    """One stage's training: what ``irlsim train`` parses its arguments into."""

    config: Stage1Config | Stage2Config
    """the stage's config; its type says the stage"""
    data: tuple[Path, ...]
    """dataset folders (several are aggregated: DAgger's expert data and its rounds' data)"""
    out: Path
    """the runs folder"""
    base: Path | None = None
    """stage 2: the folder of the frozen stage-1 models (default ``out/stage1``)"""
    device: str = "auto"
    """torch device (:func:`irlsim.devices.resolve_device`)"""
    precision: str = "fp32"
    """fp32 or bf16 (autocast forward passes)"""
    scenarios: tuple[str, ...] | None = None
    """train on the episodes of these scenarios only (``--scenario-select``); None: all"""
    demonstrators: tuple[str, ...] | None = None
    """train on the folders of these demonstrators only (``--demonstrator-select``); None: all"""

    @property
    def stage(self) -> int:
        return 2 if isinstance(self.config, Stage2Config) else 1


def stage_models(stage: int) -> tuple[str, ...]:
    return STAGE1_MODELS if stage == 1 else tuple(STAGE2_BASE)


def parameter_lines(summary: dict[str, dict[str, Any]]) -> list[str]:
    """One line per trained model: its trainable parameters (and the frozen base's, for stage 2)."""

    lines = []
    for name, s in summary.items():
        n = int(s["parameters"])
        line = f"  {name:<9} {format_parameters(n):>8} trainable parameters ({n:,})"
        if "base_parameters" in s:
            line += f" on a frozen base of {format_parameters(int(s['base_parameters']))}"
        lines.append(line + f", selected epoch {s['selected_epoch'] or s['epochs']} of {s['epochs']}")
    return lines


def train_models(run: TrainRun) -> dict[str, dict[str, Any]]:
    """Train (or resume) the models of ``run.config`` and write the stage's ``summary.json``; prints
    one line per model. Returns the summary per model. Raises
    :class:`~irlsim.errors.IrlsimError` (one line) before any work for a missing device, stage-1 folder,
    dataset or an unusable or busy runs folder."""
    device = devices.resolve(run.device, run.precision)  # one line, before any work
    with devices.use(device, run.precision):
        return _train(run)


def _train(run: TrainRun) -> dict[str, dict[str, Any]]:
    cfg, stage = run.config, run.stage
    base = run.base if run.base is not None else stage_dir(run.out, 1)
    if stage == 2 and not base.is_dir():
        hint = "pass --base" if run.base is not None else f"run 'irlsim train --stage 1 --out {run.out}'"
        raise IrlsimError(f"stage 2 needs the stage-1 folder {base}, which does not exist: {hint} first")
    data = list(run.data)
    dataset = open_datasets(tuple(data), run.scenarios, run.demonstrators)
    check_trainable(dataset, cfg)  # empty splits, sizes beyond the memory: before anything is written
    check_output_dir(run.out, "--out", CHECKPOINT_BYTES * len(cfg.models))
    remove_obsolete_caches(dataset)  # the inputs are checked: the work starts
    out = stage_dir(run.out, stage)
    try:  # one training at a time per runs folder (both stages: stage 2 reads stage 1's checkpoints)
        with exclusive_lock(run.out / LOCK_NAME):
            out.mkdir(parents=True, exist_ok=True)
            if isinstance(cfg, Stage1Config):
                summary = train_stage1(dataset, cfg, out)
                extra: dict[str, Any] = {}
            else:
                summary = train_stage2(dataset, cfg, out, base)
                extra = {"base": str(base)}
            # models trained into this stage folder earlier and not by this call stay as they were: named
            # here, so summary.json does not pass for the whole folder
            others = [m for m in stage_models(stage) if m not in summary and find_checkpoint(out, m)]
            if others:
                extra["other_models"] = others
            write_json(
                out / SUMMARY_NAME,
                {
                    "config": to_dict(cfg),
                    "data": str(data[0]) if len(data) == 1 else [str(p) for p in data],
                    "dataset": dataset_identity(dataset),
                    **({"scenarios": list(run.scenarios)} if run.scenarios is not None else {}),
                    **({"demonstrators": list(run.demonstrators)} if run.demonstrators is not None else {}),
                    **extra,
                    "models": summary,
                },
            )
    except LockBusy as busy:
        raise IrlsimError(
            f"another 'irlsim train' is writing {run.out} (pid {busy.holder}): wait for it, or train into "
            "another --out"
        ) from None
    print(f"stage {stage}: trained {', '.join(summary)}; checkpoints and metrics in {out}/<model>/")
    print("\n".join(parameter_lines(summary)))
    return summary
