"""Checkpoint files: atomic save, validated load, and which weights inference uses."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from irlsim import FEATURE_NAMES
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.errors import IrlsimError
from irlsim.models.registry import MODEL_NAMES, ModelConfig
from irlsim.utils import atomic_path

#: version of the checkpoint layout written here
CHECKPOINT_FORMAT = 1


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
