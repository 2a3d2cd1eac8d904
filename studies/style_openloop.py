r"""Open loop on a demonstrator's own cycles: what a learned reward chooses where its demonstrator drove.

For every cycle of a dataset's test split that has a demonstration, the reward's choice (argmax of
V = -theta^T f over the cycle's policy set) against the demonstrated policy: the route progress over the
horizon, the proximity cost and the velocity cost (distance to the scenario's target speed) of each,
averaged over the cycles. It tells whether a reward that drives unlike its demonstrator in closed loop
already chooses unlike it on the demonstrator's own states (the learning) or only drifts there in closed
loop. The demonstration is the collected one, before the training's demonstration rules.

    .venv/bin/python studies/style_openloop.py --data runs/styles/data/assertive/oval \
        --runs runs/styles/runs/assertive-seed0/stage1 runs/styles/runs/assertive-seed1/stage1
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq

from irlsim import FEATURE_NAMES
from irlsim.errors import IrlsimError
from irlsim.reward import load_reward

IDX = {n: i for i, n in enumerate(FEATURE_NAMES)}


def compare(data: Path, runs: Path, model: str = "PACNN+S") -> dict[str, Any]:
    """The reward's choice against the demonstration over the test split of ``data``: mean progress [m],
    proximity and velocity costs of each, and the shares of the cycles where the choice progresses more
    (or less) than the demonstration by over half a metre."""
    reward = load_reward(model, runs=str(runs))
    got = []
    for f in sorted((data / "test").glob("*.policies.parquet")):
        cycles = pq.read_table(f.with_name(f.name.replace("policies", "cycles"))).to_pandas()
        demos = cycles[cycles.has_demo].set_index("cycle").demo_index
        policies = pq.read_table(f).to_pandas()
        for c, g in policies[policies.cycle.isin(demos.index)].groupby("cycle"):
            feats = np.stack(g.features.to_numpy()).astype(np.float32)
            points = np.stack(g.control_points.to_numpy()).astype(np.float32).reshape(len(g), -1, 3)
            actions = np.stack(g.actions.to_numpy()).astype(np.float32).reshape(len(g), -1, 2)
            theta = reward.predict(feats, points, actions)
            k, d = int(np.argmax(-feats.astype(np.float64) @ theta)), int(demos[c])
            progress = g.progress.to_numpy()
            got.append(
                [progress[k], progress[d], *feats[[k, d]][:, [IDX["proximity"], IDX["velocity"]]].T.ravel()]
            )
    if not got:
        raise SystemExit(
            f"style_openloop: {data}/test has no cycle with a demonstration: give a dataset folder"
        )
    x = np.asarray(got, dtype=np.float64)
    means = {
        k: (x[:, i].mean(), x[:, i + 1].mean())
        for k, i in (("progress", 0), ("proximity", 2), ("velocity", 4))
    }
    more, less = float(np.mean(x[:, 0] > x[:, 1] + 0.5)), float(np.mean(x[:, 0] < x[:, 1] - 0.5))
    return {"cycles": len(x), **means, "more": more, "less": less}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True, help="a dataset folder (its test split is read)")
    p.add_argument("--runs", nargs="+", required=True, help="stage-1 run folders of the rewards to compare")
    p.add_argument("--model", default="PACNN+S")
    a = p.parse_args(argv)
    for where in [a.data, *a.runs]:
        if not Path(where).is_dir():
            sys.exit(f"style_openloop: {where} is not a folder: give a dataset and stage-1 run folders")
    head = (
        "| reward | cycles | progress [m] chosen / demonstrated | chosen more / less | proximity | velocity |"
    )
    lines = [head, "|---|---|---|---|---|---|"]
    for runs in a.runs:
        try:
            r = compare(Path(a.data), Path(runs), a.model)
        except IrlsimError as e:  # no such model in the run folder: irlsim's own one line
            sys.exit(f"style_openloop: {e}")
        cells = [
            runs,
            r["cycles"],
            "{:.2f} / {:.2f}".format(*r["progress"]),
            f"{r['more']:.2f} / {r['less']:.2f}",
        ]
        cells += ["{:.3f} / {:.3f}".format(*r["proximity"]), "{:.1f} / {:.1f}".format(*r["velocity"])]
        lines.append("| " + " | ".join(map(str, cells)) + " |")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
