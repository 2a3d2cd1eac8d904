"""Pool the episodes of several ``irlsim drive`` runs (same models, disjoint seeds) into one table.

    .venv/bin/python studies/combine_drives.py runs/default/accept10/drive.json \\
        runs/default/accept10b/drive.json

Per model: episodes, collisions, exits, stops, checkpoints in lane, mean speed (mean of the episodes' mean
speeds, as ``irlsim drive``'s summary), its ratio to the expert's on the same seeds, the composite score
(mean ± sample std over the episodes) and the seeds. Refuses runs that share a seed for a model.
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict

import numpy as np


def main(paths: list[str]) -> int:
    eps: dict[str, list[dict]] = defaultdict(list)
    for p in paths:
        for e in json.load(open(p))["episodes"]:
            eps[e["drive/model"]].append(e)
    speed = {m: {e["drive/seed"]: e["drive/mean_speed_kmh"] for e in es} for m, es in eps.items()}
    print(
        "| model | episodes | seeds | collisions | exits | stops | checkpoints in lane | km/h | "
        "of the expert's | score (mean ± std) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for m, es in eps.items():
        seeds = [e["drive/seed"] for e in es]
        if len(set(seeds)) != len(seeds):
            raise SystemExit(f"{m}: a seed appears twice in {paths}")

        def s(k: str, es: list[dict] = es) -> int:
            return sum(int(e[k]) for e in es)

        v = float(np.mean([e["drive/mean_speed_kmh"] for e in es]))
        ref = speed.get("expert", {})
        ratio = (
            np.mean([e["drive/mean_speed_kmh"] / ref[e["drive/seed"]] for e in es])
            if all(e["drive/seed"] in ref for e in es)
            else float("nan")
        )
        sc = np.array([e["score/score"] for e in es], dtype=float)
        print(
            f"| {m} | {len(es)} | {min(seeds)}-{max(seeds)} | {s('drive/collisions')} | {s('drive/exits')} | "
            f"{s('drive/stop_lines_compliant')}/{s('drive/stop_lines_passed')} | "
            f"{s('drive/checkpoints_in_lane')}/{s('drive/checkpoints_passed')} | {v:.1f} | {ratio:.2f} | "
            f"{sc.mean():.1f} ± {sc.std(ddof=1) if len(sc) > 1 else 0.0:.1f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
