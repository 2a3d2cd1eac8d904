r"""Does the style distance know a driver from the others? Each demonstrator's own driving, half its
episodes against every demonstrator's other half, under both normalisers of the distance.

The style table asks whether a learned reward's driving is nearest its own demonstrator's. A distance
that answers it should first take a driver's own driving on some episodes for that driver's driving on
others. This reads a ``studies/styles.py`` run's references (each demonstrator's own episodes on
``--eval-base``'s seeds; nothing is driven), and ``--splits`` times per road splits each demonstrator's
episodes at random into halves: one half, pooled, is the row; every demonstrator's other half, pooled, a
reference. It counts the rows nearest their own demonstrator and the ratio of the distance to their own
over that to the nearest other (below 1: nearest their own), under the distance as defined (each figure
divided by its spread over the references' episodes, :func:`irlsim.rollout.style.style_spread`) and the
pooled normaliser (each figure divided by its spread over the row and the references, the definition until
2026-12-01):

    .venv/bin/python studies/style_split_half.py --out runs/styles-dev2 --eval-base 2000 \
        --demonstrators expert-lanes cautious-lanes assertive-lanes

prints the counts and writes them to ``<out>/style-split-half[-s<base>]-<demonstrators>.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import style_norms  # noqa: E402
import styles  # noqa: E402

from irlsim.rollout.style import pool_styles, style_distances, style_spread  # noqa: E402

KINDS = ("as defined", "pooled")


def split_half(episodes: dict[str, list[dict[str, Any]]], splits: int, seed: int) -> dict[str, Any]:
    """Over ``splits`` random halvings: per normaliser, rows nearest their own and the own / nearest-other
    ratios' median and 90th percentile (``episodes``: each demonstrator's single episodes)."""
    rng = np.random.default_rng(seed)
    names = list(episodes)
    n_lanes = max(len(e["style/lane_share"]) for v in episodes.values() for e in v)
    hits = dict.fromkeys(KINDS, 0)
    ratios: dict[str, list[float]] = {k: [] for k in KINDS}
    for _ in range(splits):
        rows, refs, ref_eps = [], [], []
        for d in names:
            idx = rng.permutation(len(episodes[d]))
            half = len(idx) // 2
            rows.append(pool_styles([episodes[d][i] for i in idx[:half]]))
            other = [episodes[d][i] for i in idx[half:]]
            refs.append(pool_styles(other))
            ref_eps += other
        spread = style_spread(ref_eps, n_lanes)
        for k, row in enumerate(rows):
            for kind, norm in zip(KINDS, (spread, None), strict=True):
                dist = style_distances([row, *refs], norm)[0, 1:]
                hits[kind] += int(np.argmin(dist) == k)
                ratios[kind].append(float(dist[k] / np.delete(dist, k).min()))
    total = splits * len(names)
    return {
        kind: {
            "own_nearest": hits[kind],
            "rows": total,
            "ratio_median": float(np.median(ratios[kind])),
            "ratio_p90": float(np.percentile(ratios[kind], 90)),
        }
        for kind in KINDS
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="a studies/styles.py run's folder")
    p.add_argument("--roads", nargs="+", default=[styles.DEFAULT_SCENARIO, "motorway"])
    p.add_argument("--demonstrators", nargs="+", default=["expert", "cautious", "assertive"])
    p.add_argument(
        "--eval-base", type=int, default=styles.EVAL_BASE, help="the references' episode seed base"
    )
    p.add_argument("--splits", type=int, default=200, help="random halvings per road")
    p.add_argument("--seed", type=int, default=0, help="the halvings' seed")
    a = p.parse_args(argv)
    out = Path(a.out)
    at = "" if a.eval_base == styles.EVAL_BASE else f"-s{a.eval_base}"
    if missing := style_norms.missing_driving(out, a.demonstrators, a.roads, at):
        sys.exit(f"style_split_half: no driving of {missing} in {out} for these seeds: run studies/styles.py")
    result = {}
    for road in a.roads:
        eps = {d: style_norms.reference_episodes(out, d, road, at) for d in a.demonstrators}
        short = [d for d, e in eps.items() if len(e) < 4]
        if short:
            sys.exit(f"style_split_half: {short[0]} drove fewer than 4 episodes on {road}: nothing to halve")
        result[road] = split_half(eps, a.splits, a.seed)
        for kind, r in result[road].items():
            print(
                f"{road}, {kind}: own nearest in {r['own_nearest']} of {r['rows']} halves; own / nearest "
                f"other median {r['ratio_median']:.2f}, 90th percentile {r['ratio_p90']:.2f}"
            )
    path = out / f"style-split-half{at}-{'-'.join(a.demonstrators)}.json"
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
