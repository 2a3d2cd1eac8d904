"""What a DAgger round was asked and what it made (its ``round.json``), and the checks before any round:
a round is finished only when its outputs exist and match what it recorded; a re-run with other inputs
(model, seed, epochs, episodes, configs, the data or the driver) is refused in one line; the ``--runs``
model must have been trained on ``--data`` and the collect config must be the data's.

Identities are by content (configs by their values, checkpoints by their bytes, datasets by their
manifest identities), never paths, so a copied or moved DAgger folder is the same rounds, and a config
whose comments were edited is the same config.
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import Any

from irlsim.config import load_config
from irlsim.data.aggregate import aggregate_identity, manifest_identity
from irlsim.data.collection import CollectConfig, data_config, first_difference
from irlsim.data.demonstrator import SUMO, resolve
from irlsim.errors import IrlsimError
from irlsim.road.scenario import Scenarios
from irlsim.train.checkpoint import read_checkpoint
from irlsim.train.layout import find_checkpoint
from irlsim.train.preflight import check_split_sizes

#: collect-config keys a DAgger round sets itself (episode counts, workers, the round): not compared
ROUND_SET_KEYS = ("train_episodes", "validation_episodes", "test_episodes", "workers", "dagger_round")


def file_sha(path: Path) -> str:
    return "sha256:" + hashlib.sha256(Path(path).read_bytes()).hexdigest()


def config_identity(path: Path) -> str:
    """A TOML config by its values: comments, order and layout do not change it (by its bytes if it is
    not TOML; loading it names that in one line first)."""
    try:
        values = tomllib.loads(Path(path).read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        return file_sha(path)
    text = json.dumps(values, sort_keys=True, default=str)
    return "values:sha256:" + hashlib.sha256(text.encode()).hexdigest()


def _bytes_recorded_as_values(had: dict[str, Any], asked: dict[str, Any], cfg: Any) -> None:
    """A record of an older irlsim names configs by their bytes: where those are the file's bytes now,
    it is the same config (recorded again by its values)."""
    configs = had.get("configs")
    if not isinstance(configs, dict):
        return
    for name, value in configs.items():
        path = Path(str(getattr(cfg, name, "")))
        if str(value).startswith("sha256:") and path.is_file() and value == file_sha(path):
            configs[name] = asked["configs"].get(name)


def _manifest(folder: Path) -> dict[str, Any] | None:
    try:
        data = json.loads((folder / "manifest.json").read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _expert_folders(run: Any) -> tuple[Path, ...]:
    return tuple(getattr(run, "expert_data", (run.data,)))


def expert_identity(run: Any) -> str | None:
    """The identity a model trained on ``run``'s expert data records: the manifest's of one folder, the
    aggregate's of several (None when a manifest cannot be read)."""
    manifests = [_manifest(f) for f in _expert_folders(run)]
    if any(m is None for m in manifests):
        return None
    ids = [manifest_identity(m) for m in manifests if m is not None]
    return ids[0] if len(ids) == 1 else aggregate_identity(ids)


def round_inputs(run: Any, r: int, driver: Path) -> dict[str, Any]:
    """Everything round r's outputs depend on, by content."""
    cfg = run.config
    return {
        "model": cfg.model,
        "seed": cfg.seed,
        "epochs": cfg.epochs[r - 1] if cfg.epochs else None,
        "episodes": cfg.round_episodes(r),
        "validation_episodes": cfg.validation_episodes,
        "stage2_models": list(cfg.stage2_models),
        "scenario": cfg.scenario,
        "configs": {
            name: config_identity(Path(getattr(cfg, name)))
            for name in ("collect_config", "stage1_config", "stage2_config")
        },
        "data": expert_identity(run),
        "driver": file_sha(driver),
        # only when set, so a round recorded before the option existed is still the same round
        **({"fine_tune": True} if getattr(cfg, "fine_tune", False) else {}),
    }


def round_outputs(run: Any, r: int, here: Path) -> dict[str, Any] | None:
    """Round r's outputs by content, or None when one is missing: its dataset's manifest identity and
    the checkpoint hash of every model the round trains."""
    manifest = _manifest(here / "data")
    if manifest is None or not manifest.get("complete"):
        return None
    names = [run.config.stage1_model, *run.config.round_stage2(r)]
    ckpts = {name: find_checkpoint(here / "runs", name) for name in names}
    if any(p is None for p in ckpts.values()):
        return None
    return {
        "data": manifest_identity(manifest),
        "checkpoints": {n: file_sha(p) for n, p in ckpts.items() if p},
    }


def round_finished(run: Any, r: int, here: Path, driver: Path | None) -> bool:
    """True when round r's record is there, was made with these inputs and its outputs match it; False
    when it has to run (no record, or outputs missing or changed: said in one line); a record of other
    inputs is refused (one line)."""
    try:
        record = json.loads((here / "round.json").read_text())
    except (OSError, ValueError):
        return False
    if driver is None:  # the previous round's model is gone: this one cannot be checked, it runs again
        return False
    asked = round_inputs(run, r, driver)
    had = record.get("inputs") if isinstance(record, dict) else None
    if not isinstance(had, dict):
        print(f"dagger: round {r} in {here} records no inputs (an older irlsim): running it again")
        return False
    _bytes_recorded_as_values(had, asked, run.config)
    diff = first_difference(had, asked)
    if diff is not None and diff[0].startswith("configs."):
        name = diff[0].split(".", 1)[1]
        older = " (or an older irlsim recorded it by its bytes)" if str(diff[1]).startswith("sha256:") else ""
        raise IrlsimError(
            f"dagger: round {r} in {here} was run with another {name} than {getattr(run.config, name)}: "
            f"their values differ{older}; choose another --out, or delete {here} to run it again"
        )
    if diff is not None:
        key, was, now = diff
        raise IrlsimError(
            f"dagger: round {r} in {here} was run with {key} = {was!r}, now {now!r}: choose another --out, "
            f"or delete {here} to run it again with the new inputs"
        )
    made = round_outputs(run, r, here)
    if made is None or not _same_outputs(made, record.get("outputs")):
        print(
            f"dagger: round {r} in {here}: its outputs are missing or changed since it finished: "
            "running it again"
        )
        return False
    return True


def _same_outputs(made: dict[str, Any], had: Any) -> bool:
    """The outputs asked for now are the recorded ones: the same data, and each checkpoint the round
    trains now as recorded (a round that also trained stage-2 models, as the last round of a shorter
    run, is finished for a longer run that does not ask for them)."""
    if not isinstance(had, dict) or not isinstance(had.get("checkpoints"), dict):
        return False
    recorded = had["checkpoints"]
    return made["data"] == had.get("data") and all(
        recorded.get(n) == h for n, h in made["checkpoints"].items()
    )


def check_driver_and_data(run: Any) -> None:
    """Before any work: the ``--runs`` model was trained on ``--data`` (its checkpoint's dataset identity),
    and the collect config is the one ``--data`` was collected with (episode counts aside)."""
    cfg = run.config
    for folder in _expert_folders(run):
        if _manifest(folder) is None:
            raise IrlsimError(f"--data {folder} has no readable manifest.json: pass the expert dataset")
    manifest = _manifest(run.data) or {}
    ckpt = find_checkpoint(run.runs, cfg.model)
    if ckpt is None:
        return  # named by run_dagger's own check
    trained = read_checkpoint(ckpt).get("dataset")
    if trained is not None and trained != expert_identity(run):
        given = " ".join(map(str, _expert_folders(run)))
        raise IrlsimError(
            f"{ckpt} was trained on another dataset than --data {given}: pass the --data it was trained "
            "on (several in the order of its training), or train it on this one first"
        )
    ours = {
        k: v for k, v in data_config(_as_collected(cfg.collect_config)).items() if k not in ROUND_SET_KEYS
    }
    theirs = {k: v for k, v in data_config(manifest.get("config") or {}).items() if k not in ROUND_SET_KEYS}
    if cfg.scenario:  # the learner's road may be another (DAgger on a road the reward never saw)
        ours.pop("scenario", None)
        theirs.pop("scenario", None)
    diff = first_difference(theirs, ours)
    if diff is not None:
        key, was, now = diff
        raise IrlsimError(
            f"collect_config {cfg.collect_config} differs from the config --data {run.data} was collected "
            f"with ({key} = {was!r} there, {now!r} in the file): set collect_config to the data's config"
        )


def _as_collected(path: str | Path) -> CollectConfig:
    """A collect config as its manifest records it: a SUMO demonstrator resolved as collection resolves
    it (SUMO's default models filled in, a vType file read, numbers as floats; SUMO's refusal of the type
    as one line), so a config that names no lane-change model is the config of the data collected with
    it."""
    ccfg = load_config(CollectConfig, path)
    if ccfg.demonstrator.kind != SUMO:
        return ccfg
    roads = tuple(Scenarios()(name) for name in ccfg.scenario_names)
    return replace(ccfg, demonstrator=resolve(ccfg.demonstrator, roads)[0])


def check_round_splits(run: Any, r: int) -> None:
    """Before round r collects: the data its training reads (``--data`` and rounds 1..r) has train and
    validation episodes."""
    counts = {"train": 0, "validation": 0}
    for folder in _expert_folders(run):
        splits = (_manifest(folder) or {}).get("splits") or {}
        for s in counts:
            counts[s] += len(splits.get(s) or [])
    counts["train"] += sum(run.config.round_episodes(k) for k in range(1, r + 1))
    counts["validation"] += run.config.validation_episodes * r
    check_split_sizes(counts, f"DAgger round {r}'s training data ({run.data} and rounds 1..{r})")
