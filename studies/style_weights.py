"""Which feature weight carries a style: the learned rewards of the style study (studies/styles.py) read
on one common set of planning cycles.

For every run folder ``<out>/runs/<demonstrator>-seed<s>/`` and ``--model``, the model predicts theta on
every cycle of one split (``--data``, default: the expert's oval test split of the study: the same
situations for every reward), and for each of its features (the paper's 15, or the lane pair's 17) the
table gives its **value share**: the spread over a cycle's policies of theta_k * f_k (the part of the
policy values feature k moves), averaged over the cycles, as a share of the sum over the features. A
style lives in the features with the largest shares, and a reward that drives unlike its demonstrator,
or unsafely, shows which weight it put where.
Run from the repository root, after the study:

    .venv/bin/python studies/style_weights.py --out runs/styles

The table goes to ``<out>/weights.md`` and ``<out>/weights.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from irlsim import feature_names_of
from irlsim.evaluate.table import predict_sequential
from irlsim.train.batching import as_dataset, get_split
from irlsim.train.layout import find_checkpoint
from irlsim.train.loading import load_model


def value_shares(thetas: np.ndarray, features: Any, chunk: int = 256) -> np.ndarray:
    """[F] each feature's share of the policy values' spread: mean over cycles of the standard
    deviation over the policies of theta_k * f_k, normalised to sum 1 (``thetas`` [C, F], ``features``
    [C, N, F])."""
    total = np.zeros(thetas.shape[1])
    for start in range(0, len(thetas), chunk):
        f = np.asarray(features[start : start + chunk], dtype=np.float64)
        total += (f * thetas[start : start + chunk, None, :]).std(axis=1).sum(axis=0)
    return total / total.sum()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="the style study's folder")
    p.add_argument("--data", default=None, help="the common cycles (default: <out>/data/expert/oval)")
    p.add_argument("--split", default="test")
    p.add_argument("--model", default="PACNN+S")
    a = p.parse_args()
    out = Path(a.out)
    ds = as_dataset(Path(a.data) if a.data else out / "data" / "expert" / "oval")
    data = get_split(ds, a.split)
    rows = {}
    for runs in sorted((out / "runs").glob("*-seed*")):
        ckpt = find_checkpoint(runs, a.model)
        if ckpt is None:
            continue
        thetas = predict_sequential(load_model(ckpt), data, 10)  # read on cycles it was not trained on
        rows[runs.name] = value_shares(thetas, data.features).tolist()
        print(f"{runs.name}: {' '.join(f'{x:.2f}' for x in rows[runs.name])}", flush=True)
    head = ["learned reward", *feature_names_of(data.features.shape[-1])]  # the dataset's feature set
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, shares in rows.items():
        lines.append(f"| {name} | " + " | ".join(f"{100 * x:.0f}" for x in shares) + " |")
    n = len(data.demo_index)
    text = f"{a.model}: each feature's share [%] of the policy values' spread on {n} cycles\n\n"
    (out / "weights.md").write_text(text + "\n".join(lines) + "\n")
    (out / "weights.json").write_text(json.dumps({"model": a.model, "rows": rows}, indent=1) + "\n")
    print(f"wrote {out / 'weights.md'} and {out / 'weights.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
