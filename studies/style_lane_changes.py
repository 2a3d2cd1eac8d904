"""How a demonstrator's lane changes land on the policy set: the demonstrations of the style study's
datasets (studies/styles.py) around lane changes against the rest.

For every dataset folder ``<out>/data/<demonstrator>/<road>/`` (the recording's ``<out>/data/recording/``)
and split, the planning cycles are split in two: those whose next ``--horizon`` seconds hold a lane change
of the demonstrator (its lane index changes) and the others. For each part the table gives the cycles, the
share with a demonstration (a policy within ``demo.max_distance`` of what the demonstrator drove) and the
median and 90th percentile of the demonstration distance. A driver whose lane changes project badly is
taught fewer of them. Run from the repository root, after the study:

    .venv/bin/python studies/style_lane_changes.py --out runs/styles

The table goes to ``<out>/lane_changes.md`` and ``<out>/lane_changes.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq

COLUMNS = ["t", "ego_lane", "has_demo", "demo_distance"]


def change_ahead(t: np.ndarray, lane: np.ndarray, horizon: float) -> np.ndarray:
    """[C] bool: the lane index changes within (t_i, t_i + horizon] (one episode's cycles in order)."""
    changes = np.concatenate([[0], np.cumsum(lane[1:] != lane[:-1])])  # changes up to each cycle
    last = np.searchsorted(t, t + horizon, side="right") - 1  # the last cycle inside the horizon
    return changes[last] > changes


def folder_rows(folder: Path, split: str, horizon: float) -> dict[str, Any]:
    """The two parts of one dataset split (module docstring)."""
    ahead, has, dist = [], [], []
    for f in sorted((folder / split).glob("*.cycles.parquet")):
        c = pq.read_table(f, columns=COLUMNS)
        t, lane = c["t"].to_numpy(), c["ego_lane"].to_numpy()
        ahead.append(change_ahead(t, lane, horizon))
        has.append(c["has_demo"].to_numpy())
        dist.append(c["demo_distance"].to_numpy())
    a, h, d = (np.concatenate(x) for x in (ahead, has, dist))
    out = {}
    for name, part in (("lane change ahead", a), ("no lane change ahead", ~a)):
        out[name] = {
            "cycles": int(part.sum()),
            "with_demo": float(h[part].mean()) if part.any() else None,
            "distance_median_m": float(np.nanmedian(d[part])) if part.any() else None,
            "distance_p90_m": float(np.nanpercentile(d[part], 90)) if part.any() else None,
        }
    return out


def markdown(rows: dict[str, dict[str, Any]]) -> str:
    head = "| dataset | cycles | with a demonstration | distance median [m] | distance p90 [m] |"
    lines = [head, "|---|---|---|---|---|"]
    for name, parts in rows.items():
        for part, r in parts.items():
            if r["cycles"]:
                lines.append(
                    f"| {name}, {part} | {r['cycles']} | {100 * r['with_demo']:.1f} % "
                    f"| {r['distance_median_m']:.2f} | {r['distance_p90_m']:.2f} |"
                )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/styles", help="the style study's folder")
    p.add_argument("--split", default="train")
    p.add_argument("--horizon", type=float, default=5.0, help="[s] the planner's horizon")
    a = p.parse_args(argv)
    out = Path(a.out)
    folders = sorted(m.parent for m in (out / "data").glob("**/manifest.json"))
    if not folders:
        sys.exit(f"style_lane_changes: no dataset under {out / 'data'}: run studies/styles.py first")
    rows = {str(f.relative_to(out / "data")): folder_rows(f, a.split, a.horizon) for f in folders}
    (out / "lane_changes.json").write_text(json.dumps(rows, indent=1) + "\n")
    (out / "lane_changes.md").write_text(markdown(rows))
    print(markdown(rows) + f"wrote {out / 'lane_changes.md'} and {out / 'lane_changes.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
