"""Checkpoint files: atomic save, validated load, and which weights inference uses."""

from __future__ import annotations

import hashlib
import io
import json
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import torch

from irlsim import FEATURE_NAMES, feature_names_of, feature_set_of
from irlsim.config import from_dict
from irlsim.data.demonstrator import collected_egos
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.errors import IrlsimError
from irlsim.models.registry import MODEL_NAMES, ModelConfig
from irlsim.train.dataset import TrainingData
from irlsim.train.layout import STAGE_FOLDERS
from irlsim.utils import atomic_write_bytes

#: version of the checkpoint layout written here. 2: the dataset identity ('dataset') and the resume
#: record ('resumes') are stored, the bytes hold no temporary file name
CHECKPOINT_FORMAT = 2


def dataset_identity(dataset: TrainingData) -> str | None:
    """What identifies a dataset in a checkpoint, by content: the sha256 of its manifest (canonical JSON:
    sorted keys, no spaces), which records the collection config, the episode seeds and splits and the
    counts; an aggregate's own ``identity`` (its folders' identities in order, no paths). None for an
    in-memory dataset without a manifest."""
    own = getattr(dataset, "identity", None)
    if isinstance(own, str):
        return own
    manifest = getattr(dataset, "manifest", None)
    if not manifest:
        return None
    text = json.dumps(manifest, sort_keys=True, separators=(",", ":"), default=str)
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


def legacy_identities(dataset: TrainingData) -> tuple[str, ...]:
    """Identities an older irlsim recorded for this dataset, still accepted (an aggregate's manifest
    hash with its paths as typed)."""
    return tuple(getattr(dataset, "legacy_identities", ()))


def dataset_seeds(dataset: TrainingData) -> list[int] | None:
    """Every episode seed of a dataset, all splits (from its manifest), sorted; None without a manifest.
    Stored in checkpoints so that ``irlsim drive`` can refuse evaluation seeds the model was trained,
    validated or tested on."""
    manifest = getattr(dataset, "manifest", None)
    seeds = manifest.get("seeds") if isinstance(manifest, dict) else None
    if not isinstance(seeds, dict):
        return None
    return sorted({int(x) for split in seeds.values() if isinstance(split, list) for x in split})


def dataset_egos(dataset: TrainingData) -> dict[str, list[str]] | None:
    """The recorded vehicles a dataset's episodes drove as egos (every split), by the sha256 of their
    recording, sorted; None where no folder of it is a recording's. Stored in checkpoints so that
    ``irlsim drive`` on a recording can refuse the cars the model learned from (a recording's seeds
    pick no car)."""
    egos: dict[str, set[str]] = {}
    for part in getattr(dataset, "datasets", None) or [dataset]:
        manifest = getattr(part, "manifest", None)
        found = collected_egos(manifest) if isinstance(manifest, dict) else None
        if found is not None:
            egos.setdefault(found[0], set()).update(found[1])
    return {sha: sorted(ids) for sha, ids in sorted(egos.items())} or None


def save_checkpoint(path: Path, payload: dict[str, Any]) -> None:
    """torch.save ``payload`` atomically (temporary file, then rename).

    Serialised into memory first: torch.save onto a path stores the file's name inside the archive (the
    temporary name here), which made identical runs differ in their bytes; from a buffer the archive is
    always named 'archive', so the same run gives the same bytes. The payload is pickled as its
    :func:`canonical` copy, so the bytes follow from its values alone, also after a resume."""
    payload = canonical({"format": CHECKPOINT_FORMAT, **payload})
    buf = io.BytesIO()
    torch.save(payload, buf)
    atomic_write_bytes(path, buf.getvalue())


def canonical(obj: Any) -> Any:
    """A copy of ``obj`` whose pickle depends on its values only: pickle writes an object seen before
    as a back-reference to it, by identity, so a resumed run (whose optimizer keys 'lr', 'weight_decay'
    were loaded from the checkpoint, not shared with the config's) pickled the same values to other
    bytes. Every dict, list and tuple here is a fresh object (never shared) and every string the
    interned one (shared exactly when equal); tensors are kept (stored by storage)."""
    if isinstance(obj, dict):
        return {canonical(k): canonical(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [canonical(v) for v in obj]
    if isinstance(obj, tuple):
        return tuple(canonical(v) for v in obj)
    if type(obj) is str:
        return sys.intern(obj)
    return obj


def _tensors(entry: Any, prefix: str = "") -> Iterator[tuple[str, torch.Tensor]]:
    if isinstance(entry, torch.Tensor):
        yield prefix, entry
    elif isinstance(entry, dict):
        for k, v in entry.items():
            yield from _tensors(v, f"{prefix}.{k}" if prefix else str(k))


def check_crc(path: Path) -> None:
    """Every record of the checkpoint's zip archive against the CRC-32 torch wrote for it (``torch.load``
    does not check them: a flipped bit in the weights loaded silently) -> one-line IrlsimError naming the
    file and the record. A checkpoint is a result, not a cache: it cannot be rebuilt, only retrained."""
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError) as e:
        reason = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise IrlsimError(
            f"checkpoint {path} is corrupt or unreadable ({reason}): delete it and train again"
        ) from None
    if bad is not None:
        raise IrlsimError(
            f"checkpoint {path} is corrupt (its record {bad} fails its CRC-32 check): "
            "delete it and train again"
        )


def read_checkpoint(
    path: str | Path,
    *,
    model: str | None = None,
    stage: int | None = None,
    dataset: str | None = None,
    legacy: tuple[str, ...] = (),
) -> dict[str, Any]:
    """Load a checkpoint written by this package and check what it is: missing, a folder, corrupt, of
    another format or feature set, with non-finite weights, or (when given) of another ``model``, ``stage``
    or ``dataset`` (identity from :func:`dataset_identity`; ``legacy``: its older identities, also
    accepted) -> IrlsimError (one line)."""
    path = Path(path)
    if path.is_dir():
        raise IrlsimError(f"checkpoint {path} is a folder, not a file: remove it and train again")
    if not path.is_file():
        raise IrlsimError(f"checkpoint {path} not found: run 'irlsim train' first (or check --runs)")
    check_crc(path)
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
    if feature_set_of(names) is None:
        like = feature_names_of(len(names), default=FEATURE_NAMES)
        differ = sorted(set(names) ^ set(like))
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
    check_identity(path, ckpt, model=model, stage=stage, dataset=dataset, legacy=legacy)
    for key in ("state_dict", "best", "base"):
        for name, t in _tensors(ckpt.get(key)):
            if t.is_floating_point() and not bool(torch.isfinite(t).all()):
                raise IrlsimError(
                    f"checkpoint {path} has non-finite weights ({key}.{name}): delete it and train again "
                    "(lower the learning rate if training diverged)"
                )
    return ckpt


def check_identity(
    path: Path,
    ckpt: dict[str, Any],
    *,
    model: str | None = None,
    stage: int | None = None,
    dataset: str | None = None,
    legacy: tuple[str, ...] = (),
) -> None:
    """Refuse (one line) a checkpoint that is not the ``model`` / ``stage`` / ``dataset`` asked for."""
    if model is not None and ckpt["model"] != model:
        raise IrlsimError(
            f"checkpoint {path} holds {ckpt['model']}, not {model} (a checkpoint copied into another "
            f"model's folder?): put it back into {ckpt['model']}/ or train {model}"
        )
    if stage is not None and int(ckpt.get("stage", 0)) != stage:
        raise IrlsimError(
            f"checkpoint {path} is a stage-{ckpt.get('stage')} checkpoint in a stage-{stage} folder: move it "
            f"to the stage{ckpt.get('stage')}/ folder or train stage {stage}"
        )
    have = ckpt.get("dataset")
    if dataset is not None and have is not None and have != dataset and have not in legacy:
        raise IrlsimError(
            f"checkpoint {path} was trained on another dataset ({str(have)[:19]}..., this one is "
            f"{dataset[:19]}...): use the --data it was trained on, or retrain on this one"
        )


def expected_identity(path: str | Path) -> tuple[str | None, int | None]:
    """(model, stage) a checkpoint must hold, from the folder it was found in: ``.../stage<S>/<model>/
    checkpoint.pt`` -> (model, S), ``.../<model>/checkpoint.pt`` -> (model, None); a folder that is not a
    model name (a checkpoint given by path) -> (None, None)."""
    parent = Path(path).absolute().parent
    model = parent.name if parent.name in MODEL_NAMES else None
    stages = {v: k for k, v in STAGE_FOLDERS.items()}
    stage = stages.get(parent.parent.name) if model is not None else None
    return model, stage


def model_config_from(d: dict[str, Any]) -> ModelConfig:
    return from_dict(ModelConfig, d)


def inference_state(entry: dict[str, Any]) -> dict[str, Any]:
    """The weights used for inference: the validation-selected ones (``entry['best']``) when the
    checkpoint has them, else the latest (``entry['state_dict']``, which resuming always uses)."""
    best = entry.get("best")
    return best["state_dict"] if best else entry["state_dict"]
