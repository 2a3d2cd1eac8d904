"""Evaluating trained models (``irlsim evaluate``): :func:`evaluate_runs` with :class:`EvaluateRun`.

Table I (model, trainable parameters, EVD, ED, OPD, DEMO) on the sequential test split with a history of
H cycles, reference rows, breakdowns, convergence plots and the OPD distribution per model
(:func:`irlsim.evaluate.evaluate_models`), plus temporal-weight strips of temporal models.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim import devices
from irlsim.data.aggregate import (
    any_selection_identities,
    manifest_identity,
    open_datasets,
    overlapping_identities,
    remove_obsolete_caches,
)
from irlsim.errors import IrlsimError
from irlsim.evaluate import evaluate_models
from irlsim.outputs import check_output_dir
from irlsim.train.checkpoint import dataset_identity, legacy_identities, read_checkpoint
from irlsim.train.dataset import TrainingData
from irlsim.train.layout import SUMMARY_NAME
from irlsim.viz.temporal import save_situation_strips


@dataclass(frozen=True)
class EvaluateRun:
    """One evaluation: what ``irlsim evaluate`` parses its arguments into."""

    data: tuple[Path, ...]
    """dataset folder(s): several are the aggregate the models were trained on"""
    runs: Path
    """the runs folder (stage1/<model>/, stage2/<model>/checkpoint.pt)"""
    out: Path | None = None
    """output folder (None: ``runs/eval``)"""
    split: str = "test"
    history: int | None = None
    """H [cycles] (None: the PTACNN's own H, else 10)"""
    threads: int = 2
    """torch CPU threads"""
    references: bool = True
    """the reference rows expert-theta, executed and oracle ('random policy' always)"""
    device: str = "auto"
    precision: str = "fp32"
    scenarios: tuple[str, ...] | None = None
    """evaluate on the episodes of these scenarios only (``--scenario-select``); None: all"""
    demonstrators: tuple[str, ...] | None = None
    """evaluate on the folders of these demonstrators only (``--demonstrator-select``); None: all"""
    held_out: bool = False
    """the models were trained on other data (``--held-out``): Table I of a reward on a road or dataset
    it never saw (each model keeps its own feature normalisation); False: a model trained on other data
    is refused"""


def evaluate_runs(run: EvaluateRun) -> Path:
    """Write Table I and the plots of ``run`` (printing the table); returns the output folder. Raises
    :class:`~irlsim.errors.IrlsimError` (one line) before any work for bad arguments or a missing runs
    folder."""
    if run.history is not None and run.history < 1:
        raise IrlsimError(f"--history must be >= 1, got {run.history}")
    if run.threads < 1:
        raise IrlsimError(f"--threads must be >= 1, got {run.threads}")
    device = devices.resolve(run.device, run.precision)
    out = run.out or run.runs / "eval"
    check_output_dir(out, "--out")
    if not run.runs.is_dir():
        raise IrlsimError(f"runs folder {run.runs} not found: train first with 'irlsim train --stage 1'")
    dataset = open_datasets(list(run.data), run.scenarios, run.demonstrators)
    trained = _trained_on(run.runs)
    own = overlapping_identities(dataset)
    mine = [path for path, ident in trained.items() if ident in own or _folders_trained_on(path) & own]
    if run.held_out and mine:
        raise IrlsimError(
            f"--held-out: {mine[0]} was trained on data that includes {', '.join(map(str, run.data))}, so "
            f"it is not held out: evaluate without --held-out (Table I on its {run.split} split) or pass "
            "data the models were not trained on"
        )
    # a model trained on the whole dataset or on any selection of its scenarios is evaluated on it
    accepted = {dataset_identity(dataset), *legacy_identities(dataset)}
    dataset.legacy_identities = tuple(
        [*legacy_identities(dataset), *(i for i in any_selection_identities(dataset) if i not in accepted)]
    )
    if run.held_out:  # transfer: accept what the runs folder's checkpoints were trained on
        dataset.legacy_identities = (*dataset.legacy_identities, *trained.values())
    remove_obsolete_caches(dataset)  # the inputs are checked: the work starts
    with devices.use(device, run.precision):
        evaluate_models(
            dataset,
            run.runs,
            out,
            H=run.history,
            split=run.split,
            threads=run.threads,
            references=run.references,
            strips=functools.partial(save_situation_strips, out),
            record=_record(run, dataset, trained),
        )
    print((out / "results.md").read_text())
    if run.held_out:
        print(f"evaluate: models of {run.runs} on held-out data {', '.join(map(str, run.data))}")
    print(
        f"wrote {out}/results.md, results.json, convergence.png, opd_distribution.png"
        " (and temporal_<model>_<situation>.png for temporal models)"
    )
    return out


def _trained_on(runs: Path) -> dict[str, str]:
    """{checkpoint path: the dataset identity it records} of every checkpoint below ``runs`` (a checkpoint
    that cannot be read is left to the evaluation, which names it in one line)."""
    out = {}
    for path in sorted(runs.glob("**/checkpoint.pt")):
        try:
            ident = read_checkpoint(path).get("dataset")
        except IrlsimError:
            continue
        if isinstance(ident, str):
            out[str(path)] = ident
    return out


def _summary(checkpoint: str) -> dict[str, Any]:
    """The summary.json of ``checkpoint``'s stage folder ({} when it cannot be read)."""
    try:
        summary = json.loads((Path(checkpoint).parent.parent / SUMMARY_NAME).read_text())
    except (OSError, ValueError):
        return {}
    return summary if isinstance(summary, dict) else {}


def _summary_data(checkpoint: str) -> str | list[str] | None:
    """The ``data`` that the summary.json of ``checkpoint``'s stage folder records (None: unreadable)."""
    data = _summary(checkpoint).get("data")
    return data if isinstance(data, (str, list)) else None


def _data_verified(checkpoint: str, identity: str) -> bool:
    """Whether the folders (and scenarios) that the stage's summary.json names are, read again now, the
    data whose identity the checkpoint records: summary.json carries no check of its own, the checkpoint
    (its CRC-32 checked) does."""
    summary, data = _summary(checkpoint), _summary_data(checkpoint)
    scenarios = summary.get("scenarios")
    if data is None or not (scenarios is None or isinstance(scenarios, list)):
        return False
    try:
        folders: list[str | Path] = [data] if isinstance(data, str) else [str(p) for p in data]
        read = open_datasets(folders, tuple(scenarios) if scenarios else None)
    except (IrlsimError, OSError, TypeError):
        return False
    return dataset_identity(read) == identity


def _folders_trained_on(checkpoint: str) -> set[str]:
    """The manifest identities of the folders an aggregate's checkpoint was trained on, from its stage's
    summary.json (the checkpoint records the aggregate's identity alone, which names no folder): one of
    them evaluated is not held out. Empty for one folder, or folders that cannot be read."""
    data = _summary_data(checkpoint)
    if not isinstance(data, list) or len(data) < 2:
        return set()
    out = set()
    for folder in data:
        try:
            manifest = json.loads((Path(str(folder)) / "manifest.json").read_text())
        except (OSError, ValueError):
            continue
        if isinstance(manifest, dict):
            out.add(manifest_identity(manifest))
    return out


def _record(run: EvaluateRun, dataset: TrainingData, trained: dict[str, str]) -> dict[str, object]:
    """What results.json records of the evaluation: the data evaluated, whether it is held out, and what
    each model was trained on (its checkpoint's dataset identity, its stage's summary.json ``data`` and
    whether those folders are that data, read again); ``note``: the same as a line of results.md."""
    data = [str(p) for p in run.data]
    on: dict[str, dict[str, object]] = {}
    other: set[str] = set()
    unknown = 0
    for path, ident in trained.items():
        paths, verified = _summary_data(path), _data_verified(path, ident)
        on[str(Path(path).parent.relative_to(run.runs))] = {
            "dataset": ident,
            "data": paths,
            "data_verified": verified,
        }
        if verified:  # a summary.json that does not match the checkpoint names no data
            other.update([paths] if isinstance(paths, str) else paths if isinstance(paths, list) else [])
        unknown += not verified
    if run.held_out:
        note = f"Held out: yes. Evaluated on {', '.join(data)}; the models were trained on "
        note += f"{', '.join(sorted(other)) or 'other data'}"
        note += f" ({unknown} of them on data their summary.json does not name)." if unknown else "."
    else:
        note = f"Held out: no. Evaluated on the {run.split} split of {', '.join(data)}, the data the models "
        note += "were trained on."
    return {
        "evaluated_on": {
            "data": data,
            "dataset": dataset_identity(dataset),
            "scenarios": list(run.scenarios) if run.scenarios else None,
            "held_out": run.held_out,
        },
        "trained_on": on,
        "note": note,
    }
