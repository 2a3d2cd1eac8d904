"""``irlsim drive``'s check of its episode seeds against the data a learned reward was trained on."""

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
