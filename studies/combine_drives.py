"""Pool the episodes of several ``irlsim drive`` runs (same models, disjoint seeds) into one table.

    .venv/bin/python studies/combine_drives.py runs/default/accept10/drive.json \\
        runs/default/accept10b/drive.json

Per model: episodes, collisions, exits, stops and checkpoints in lane (the counts of
``irlsim.drive.metrics.summarize``, as ``irlsim drive``'s table), mean speed (the plain mean of the
episodes' mean speeds, where ``irlsim drive`` weights them by steps), its ratio to the expert's on the same
seeds, the composite score (mean ± sample std over the episodes; ``drive.md`` prints the population std)
and the seeds. Refuses runs that share a seed for a model.
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict

import numpy as np

from irlsim.drive.metrics import summarize


def main(paths: list[str]) -> int:
    eps: dict[str, list[dict]] = defaultdict(list)
    for p in paths:
        for e in json.load(open(p))["episodes"]:
            eps[e["drive/model"]].append(e)
    ref = {e["drive/seed"]: e["drive/mean_speed_kmh"] for e in eps.get("expert", [])}  # expert's km/h by seed
    print(
        "| model | episodes | seeds | collisions | exits | stops | checkpoints in lane | km/h | "
        "of the expert's | score (mean ± std) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for m, es in eps.items():
        seeds = [e["drive/seed"] for e in es]
        if len(set(seeds)) != len(seeds):
            raise SystemExit(f"{m}: a seed appears twice in {paths}")
        t = summarize(es)
        v = float(np.mean([e["drive/mean_speed_kmh"] for e in es]))
        ratio = (
            np.mean([e["drive/mean_speed_kmh"] / ref[e["drive/seed"]] for e in es])
            if all(e["drive/seed"] in ref for e in es)
            else float("nan")
        )
        sc = np.array([e["score/score"] for e in es], dtype=float)
        print(
            f"| {m} | {len(es)} | {min(seeds)}-{max(seeds)} | {t['drive/collisions']} | {t['drive/exits']} | "
            f"{t['drive/stop_lines_compliant']}/{t['drive/stop_lines_passed']} | "
            f"{t['drive/checkpoints_in_lane']}/{t['drive/checkpoints_passed']} | {v:.1f} | {ratio:.2f} | "
            f"{sc.mean():.1f} ± {sc.std(ddof=1) if len(sc) > 1 else 0.0:.1f} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
