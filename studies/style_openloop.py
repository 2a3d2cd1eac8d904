r"""Open loop on a demonstrator's own cycles: where a learned reward's style parts from its demonstrator's.

For every cycle of a dataset's test split that has a demonstration, four policies of the cycle's set are
compared on the figures that carry a driving style: the demonstration as collected (the odometry's
projection), the demonstration after the training's rules (:func:`irlsim.data.demos.safe_demo_index`:
moved off a policy labelled as a predicted collision, or one crossing an active stop line without
standing; what the reward is trained on), what the reward expects (the mean under its maximum-entropy
distribution p ~ exp(-theta^T f) over the set: what maximum-entropy IRL fits to the demonstrations) and
what it chooses (argmax, what the planner drives). Each step of that chain says where a style is lost: in
the rules, in the learning, or in taking the most likely policy instead of the distribution. The
figures, averaged over the cycles (those the rules drop left out of their column): route progress over
the horizon [m], the proximity, velocity and lane-change delay costs, and the share of cycles whose policy
ends over 2 m sideways (a lane change: the planner's swerves are 0.8 and 1.6 m). Beside them, the reward's
weights theta (mean over the cycles) of those features: which weight carries a style shows as a
difference between the rewards of two demonstrators.

    .venv/bin/python studies/style_openloop.py --data runs/styles/data/assertive/oval \
        --runs runs/styles/runs/assertive-seed0/stage1 runs/styles/runs/assertive-seed1/stage1
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq

from irlsim import FEATURE_NAMES
from irlsim.data.demos import safe_demo_index
from irlsim.errors import IrlsimError
from irlsim.planner.choice import SIDEWAYS, expected_choice
from irlsim.reward import load_reward
from irlsim.reward.choice import lane_change_bias

IDX = {n: i for i, n in enumerate(FEATURE_NAMES)}
#: the feature costs compared (and whose weights are shown)
COSTS = ("proximity", "velocity", "lc_delay")
#: the policies compared in every cycle, in the chain's order ("chosen": argmax; "expected choice":
#: irlsim.planner.choice.expected_choice with the reward's calibrated lane-change bias)
WHICH = ("demonstrated", "after the rules", "expected", "chosen", "expected choice")


def cycle_figures(
    feats: np.ndarray,
    points: np.ndarray,
    progress: np.ndarray,
    theta: np.ndarray,
    demo: int,
    ruled: int,
    bias: float = 1.0,
) -> np.ndarray:
    """[len(WHICH), 2 + len(COSTS)] progress, share sideways and the costs of one cycle's demonstration,
    ruled demonstration (-1: dropped by the rules, NaN), the reward's expectation, its argmax and its
    expected choice with lane-change bias ``bias``; ``points`` [N, K, 3] the control points."""
    sideways = (np.abs(points[:, -1, 0]) > SIDEWAYS).astype(np.float64)
    f = np.column_stack([progress, sideways, feats[:, [IDX[c] for c in COSTS]]]).astype(np.float64)
    value = -feats.astype(np.float64) @ theta
    p = np.exp(value - value.max())
    p /= p.sum()
    ruled_row = f[ruled] if ruled >= 0 else np.full(f.shape[1], np.nan)
    choice = expected_choice(value, points, bias)
    return np.stack([f[demo], ruled_row, p @ f, f[int(np.argmax(value))], f[choice]])


def compare(
    data: Path, runs: Path, model: str = "PACNN+S", calibrate_on: list[Path] | None = None
) -> dict[str, Any]:
    """The chain demonstrated -> after the rules -> expected -> chosen over the test split of ``data``
    (means over the cycles with a demonstration) and the reward's mean weights of ``COSTS``; the expected
    choice's lane-change bias is calibrated on the train splits of ``calibrate_on`` (default: ``data``)."""
    reward = load_reward(model, runs=str(runs))
    bias = lane_change_bias(reward, list(calibrate_on or [data]))
    reward.reset()
    got, thetas = [], []
    for f in sorted((data / "test").glob("*.policies.parquet")):
        cycles = pq.read_table(f.with_name(f.name.replace("policies", "cycles"))).to_pandas()
        demos = cycles[cycles.has_demo].set_index("cycle").demo_index
        policies = pq.read_table(f).to_pandas()
        for c, g in policies[policies.cycle.isin(demos.index)].groupby("cycle"):
            feats = np.stack(g.features.to_numpy()).astype(np.float32)
            points = np.stack(g.control_points.to_numpy()).astype(np.float32).reshape(len(g), -1, 3)
            actions = np.stack(g.actions.to_numpy()).astype(np.float32).reshape(len(g), -1, 2)
            theta = np.asarray(reward.predict(feats, points, actions), dtype=np.float64)
            demo = int(demos[c])
            ruled = int(
                safe_demo_index(
                    np.array([demo]),
                    g.distance.to_numpy(np.float32)[None],
                    g.collision.to_numpy(bool)[None],
                    stop_line=feats[None, :, IDX["stop_line"]],
                )[0]
            )
            got.append(cycle_figures(feats, points, g.progress.to_numpy(), theta, demo, ruled, bias))
            thetas.append(theta[[IDX[c] for c in COSTS]])
    if not got:
        raise SystemExit(
            f"style_openloop: {data}/test has no cycle with a demonstration: give a dataset folder"
        )
    x = np.stack(got)  # [C, len(WHICH), F]
    means = np.nanmean(x, axis=0)
    names = ("progress", "sideways", *COSTS)
    return {
        "cycles": len(x),
        "dropped by the rules": int(np.isnan(x[:, 1, 0]).sum()),
        "moved by the rules": float(np.mean(np.any(x[:, 0] != x[:, 1], axis=1) & ~np.isnan(x[:, 1, 0]))),
        **{n: dict(zip(WHICH, means[:, i].tolist(), strict=True)) for i, n in enumerate(names)},
        "theta": dict(zip(COSTS, np.mean(thetas, axis=0).tolist(), strict=True)),
        "lane_change_bias": bias,
    }


def markdown(results: dict[str, dict[str, Any]]) -> str:
    """One table of the chain per figure (a row per reward), then the rewards' weights."""
    fmt = {"progress": "{:.2f}", "sideways": "{:.3f}", "proximity": "{:.3f}", "velocity": "{:.1f}"}
    lines = [
        "| reward | cycles (moved / dropped by the rules) | figure | " + " | ".join(WHICH) + " |",
        "|---|---|---|" + "---|" * len(WHICH),
    ]
    for runs, r in results.items():
        for n in ("progress", "sideways", *COSTS):
            cells = [fmt.get(n, "{:.3f}").format(r[n][w]) for w in WHICH]
            head = f"{r['cycles']} ({r['moved by the rules']:.3f} / {r['dropped by the rules']})"
            lines.append(f"| {runs} | {head} | {n} | " + " | ".join(cells) + " |")
    lines += ["", "| reward | " + " | ".join(f"theta {c}" for c in COSTS) + " | lane-change bias |"]
    lines.append("|---|" + "---|" * (len(COSTS) + 1))
    for runs, r in results.items():
        cells = [f"{r['theta'][c]:.4g}" for c in COSTS] + [f"{r['lane_change_bias']:.3f}"]
        lines.append(f"| {runs} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True, help="a dataset folder (its test split is read)")
    p.add_argument("--runs", nargs="+", required=True, help="stage-1 run folders of the rewards to compare")
    p.add_argument("--model", default="PACNN+S")
    p.add_argument("--json", help="also write the figures to this JSON file")
    p.add_argument(
        "--calibrate-on", nargs="+", help="datasets whose train splits calibrate the expected choice's "
        "lane-change bias (the reward's training data; default: --data)",
    )  # fmt: skip
    a = p.parse_args(argv)
    for where in [a.data, *a.runs]:
        if not Path(where).is_dir():
            sys.exit(f"style_openloop: {where} is not a folder: give a dataset and stage-1 run folders")
    results = {}
    for runs in a.runs:
        try:
            calibrate_on = [Path(x) for x in a.calibrate_on] if a.calibrate_on else None
            results[runs] = compare(Path(a.data), Path(runs), a.model, calibrate_on)
        except IrlsimError as e:  # no such model in the run folder: irlsim's own one line
            sys.exit(f"style_openloop: {e}")
    print(markdown(results))
    if a.json:
        Path(a.json).write_text(json.dumps({"data": a.data, "model": a.model, "rewards": results}, indent=1))
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
