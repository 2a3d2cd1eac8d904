"""``irlsim drive``'s check of what it drives against the data a learned reward was trained on: its
episode seeds, or on a recording its cars."""

from __future__ import annotations

import sys
from typing import Any

from irlsim.errors import IrlsimError


def check_seeds_unseen(models: list[Any], seed: int, episodes: int) -> None:
    """Refuse (one line) episode seeds seed..seed+episodes-1 that are seeds of the dataset a learned model
    was trained on (any split: train, validation or test), read from its checkpoint's ``dataset_seeds``.
    Checkpoints without them (trained on an in-memory dataset) are not checked."""
    asked = set(range(seed, seed + episodes))
    for model in models:
        recorded = model.trained or {}
        trained = set(recorded.get("dataset_seeds") or ())
        if recorded.get("dataset") and recorded.get("dataset_seeds") is None:
            print(
                f"note: {model.name} records no training seeds (trained before they were recorded): "
                "its seeds are not checked; retrain it to have them refused",
                file=sys.stderr,
            )
        overlap = sorted(asked & trained)
        if overlap:
            shown = ", ".join(map(str, sorted(trained)[:8])) + (", ..." if len(trained) > 8 else "")
            raise IrlsimError(
                f"--seed {seed} --episodes {episodes}: episode seed(s) {', '.join(map(str, overlap[:5]))} "
                f"are seeds of the data {model.name} was trained on ({shown}): evaluate on unseen seeds, "
                "choose another --seed"
            )


def check_egos_unseen(models: list[Any], file: str, sha256: str, egos: list[str]) -> None:
    """On a recording (``file``, its content's ``sha256``), refuse (one line) driving ``egos`` a learned
    model's training data drove as egos (any split), read from its checkpoint's ``dataset_egos``; a
    recording's episode seeds pick no car, so its cars are what keeps a drive unseen. Models trained on
    other recordings or on no recording are not concerned; checkpoints of a recording's data written
    before irlsim recorded its egos get a note."""
    for model in models:
        recorded = model.trained or {}
        if not recorded.get("dataset"):
            continue  # the expert, the demonstrator, an in-memory dataset's model
        by_recording = recorded.get("dataset_egos")
        if by_recording is None:
            print(
                f"note: {model.name} records no recorded cars of its training data (trained on no "
                "recording, or before irlsim recorded them): drive cars it did not learn from",
                file=sys.stderr,
            )
            continue
        learned = set(by_recording.get(sha256) or ())
        overlap = [v for v in egos if v in learned]
        if overlap:
            raise IrlsimError(
                f"recording {file}: car(s) {', '.join(overlap[:5])} are egos of the data {model.name} was "
                f"trained on ({len(learned)} cars of this recording): drive cars it did not learn from "
                "(demonstrator.ego)"
            )
