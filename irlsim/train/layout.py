"""Where training writes: the runs folder's stage sub-folders and each model's files in them."""

from __future__ import annotations

from pathlib import Path

from irlsim.models.registry import STAGE2_BASE

CHECKPOINT_NAME = "checkpoint.pt"
METRICS_NAME = "metrics.csv"
SUMMARY_NAME = "summary.json"
#: sub-folders of a runs folder, one per training stage (``<runs>/stage1/<model>/``, ...)
STAGE_FOLDERS: dict[int, str] = {1: "stage1", 2: "stage2"}


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
    never mixed into a table. A ``checkpoint.pt`` that exists but is not a file is returned (so the reader
    refuses it in one line instead of the model being left out silently)."""
    runs = Path(runs)
    if any(stage_dir(runs, s).is_dir() for s in STAGE_FOLDERS):
        path = stage_dir(runs, model_stage(name)) / name / CHECKPOINT_NAME
    else:
        path = runs / name / CHECKPOINT_NAME
    # a folder named checkpoint.pt is returned too: reading it is a one-line error, not a silent skip
    return path if path.exists() else None
