"""Where the demonstrator drives on the approach to each checkpoint: the states a dataset shows.

    .venv/bin/python studies/mission_approaches.py data/default data/paper_me [--split train]

Per dataset and required lane of the target checkpoint, for bands of the remaining route distance to it:
the planning cycles in the band, how many of them the ego is off the required lane, and how many of those
it is off the lane at more than 10 m/s (an approach at speed in the wrong lane, what a learned driver that
keeps its lane too long reaches). The checkpoints (route position, required lane) come from the road
network; the remaining distance from the cycles table (``ego_s``, ``target_checkpoint``). Issue 12,
docs/RESULTS.md "The paper-scale mission": a cycle the demonstrator never drives is a state no
demonstration covers, which is what DAgger (``irlsim dagger``) adds.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from irlsim.road.geometry import load_road

BANDS = ((0.0, 50.0), (50.0, 110.0), (110.0, 200.0), (200.0, 400.0))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("data", nargs="+", type=Path, help="dataset folders (irlsim collect --out)")
    p.add_argument("--split", default="train", help="split to read (default train)")
    args = p.parse_args(argv)
    road = load_road()
    cs = np.array([c.s for c in road.checkpoints])
    cl = np.array([c.lane for c in road.checkpoints])
    lanes = sorted(set(cl.tolist()))
    print("| data | required lane | remaining [m] | cycles | off the lane | off the lane at > 10 m/s |")
    print("|---|---|---|---|---|---|")
    for data in args.data:
        files = sorted((data / args.split).glob("*.cycles.parquet"))
        if not files:
            raise SystemExit(f"{data}/{args.split} has no cycles files: give a dataset folder")
        t = pa.concat_tables(
            [pq.read_table(f, columns=["ego_s", "ego_v", "ego_lane", "target_checkpoint"]) for f in files]
        )
        k = t.column("target_checkpoint").to_numpy().astype(int)
        rem = (cs[k] - t.column("ego_s").to_numpy()) % road.lap_length
        req, lane = cl[k], t.column("ego_lane").to_numpy()
        fast = t.column("ego_v").to_numpy() > 10.0
        for q in lanes:
            for lo, hi in BANDS:
                m = (rem >= lo) & (rem < hi) & (req == q)
                off = m & (lane != q)
                share = f"{off.sum() / m.sum():.0%}" if m.sum() else "-"
                row = [str(data), str(q), f"{lo:.0f}-{hi:.0f}", str(m.sum()), f"{off.sum()} ({share})"]
                print("| " + " | ".join([*row, str((off & fast).sum())]) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
