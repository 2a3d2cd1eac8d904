"""Evaluating trained models (``irlsim evaluate``): :func:`evaluate_runs` with :class:`EvaluateRun`.

Table I (model, trainable parameters, EVD, ED, OPD, DEMO) on the sequential test split with a history of
H cycles, reference rows, breakdowns, convergence plots and the OPD distribution per model
(:func:`irlsim.evaluate.evaluate_models`), plus temporal-weight strips of temporal models.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

from irlsim import devices
from irlsim.data.aggregate import any_selection_identities, open_datasets, remove_obsolete_caches
from irlsim.errors import IrlsimError
from irlsim.evaluate import evaluate_models
from irlsim.outputs import check_output_dir
from irlsim.train.checkpoint import dataset_identity, legacy_identities, read_checkpoint
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
    dataset = open_datasets(list(run.data), run.scenarios)
    # a model trained on the whole dataset or on any selection of its scenarios is evaluated on it
    accepted = {dataset_identity(dataset), *legacy_identities(dataset)}
    dataset.legacy_identities = tuple(
        [*legacy_identities(dataset), *(i for i in any_selection_identities(dataset) if i not in accepted)]
    )
    if run.held_out:  # transfer: accept what the runs folder's checkpoints were trained on
        dataset.legacy_identities = (*dataset.legacy_identities, *_trained_on(run.runs))
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
        )
    print((out / "results.md").read_text())
    if run.held_out:
        print(f"evaluate: models of {run.runs} on held-out data {', '.join(map(str, run.data))}")
    print(
        f"wrote {out}/results.md, results.json, convergence.png, opd_distribution.png"
        " (and temporal_<model>_<situation>.png for temporal models)"
    )
    return out


def _trained_on(runs: Path) -> tuple[str, ...]:
    """The dataset identities recorded in every checkpoint below ``runs`` (a checkpoint that cannot be
    read is left to the evaluation, which names it in one line)."""
    out = []
    for path in sorted(runs.glob("**/checkpoint.pt")):
        try:
            ident = read_checkpoint(path).get("dataset")
        except IrlsimError:
            continue
        if isinstance(ident, str):
            out.append(ident)
    return tuple(out)
