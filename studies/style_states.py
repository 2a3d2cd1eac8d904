r"""How many lane changes a learned reward expects, on its driver's states and on its own.

A reward learned from a driver changes lanes in closed loop only where its maximum-entropy distribution
puts mass on lane changes. On the driver's states (its dataset) the distribution's expected share of
lane-changing policies is what the fit matched; in closed loop the reward drives in states of its own
(its speed, its headway), where that share may differ. For every reward and every dataset given, over
the dataset's train split: the share of cycles whose argmax policy changes lanes, the distribution's
expected share, and the share of the ``expected`` choice (:mod:`irlsim.planner.choice`) with the
reward's lane-change bias calibrated on ``--calibrate-on`` (its training data); beside them the share of
the cycles with a demonstration whose demonstration changes lanes (a policy ending over ``SIDEWAYS`` m to
a side: what the driver did).

States of a reward's own driving: ``irlsim collect --driver <model> --runs <run> --round 1`` with the
scenario's config (the expert labels; only the states and policy sets are read here):

    .venv/bin/python studies/style_states.py --runs runs/styles/runs/assertive-seed0 \
        --data runs/styles/data/assertive/oval runs/styles/states/assertive-seed0/oval \
        --calibrate-on runs/styles/data/assertive/oval runs/styles/data/assertive/motorway
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.data.aggregate import open_datasets
from irlsim.errors import IrlsimError
from irlsim.planner.choice import SIDEWAYS, expected_choice, maneuver_masses
from irlsim.reward import load_reward
from irlsim.reward.choice import cycle_values, lane_change_bias


def shares(reward: Any, data: Path, bias: float) -> dict[str, float]:
    """Over the train split of ``data``: the shares of cycles whose argmax, expected choice change
    lanes, and the distribution's expected share of lane-changing policies."""
    got = []
    for value, points in cycle_values(reward, [data]):
        side = np.abs(points[:, -1, 0]) > SIDEWAYS
        _, _, offsets, mass = maneuver_masses(value, points)
        choice = expected_choice(value, points, bias)
        got.append([side[int(np.argmax(value))], mass[np.abs(offsets) > SIDEWAYS].sum(), side[choice]])
    x = np.asarray(got, dtype=np.float64)
    return {
        "cycles": len(x),
        "argmax": x[:, 0].mean(),
        "expected": x[:, 1].mean(),
        "expected choice": x[:, 2].mean(),
    }


def demonstrated(data: Path) -> float:
    """The share of the train split's cycles with a demonstration whose demonstration changes lanes."""
    t = open_datasets([data]).split_tensors("train")
    idx = np.asarray(t.demo_index)
    has = np.flatnonzero(idx >= 0)
    ends = np.array([float(np.asarray(t.control_points[c])[idx[c], -1, 0]) for c in has])  # per cycle
    return float((np.abs(ends) > SIDEWAYS).mean()) if len(ends) else float("nan")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", nargs="+", required=True, help="run folders of the rewards")
    p.add_argument("--data", nargs="+", required=True, help="datasets whose train splits give the states")
    p.add_argument("--calibrate-on", nargs="+", required=True, help="the rewards' training datasets")
    p.add_argument("--model", default="PACNN+S")
    a = p.parse_args(argv)
    for where in [*a.runs, *a.data, *a.calibrate_on]:
        if not Path(where).is_dir():
            sys.exit(f"style_states: {where} is not a folder: give run and dataset folders")
    lines = [
        "| reward | states | cycles | demonstrated | argmax | expected | expected choice | bias |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for runs in a.runs:
        try:
            reward = load_reward(a.model, runs=runs)
            bias = lane_change_bias(reward, list(a.calibrate_on))
            for data in a.data:
                r = shares(reward, Path(data), bias)
                cells = [
                    runs,
                    data,
                    r["cycles"],
                    f"{demonstrated(Path(data)):.3f}",
                    *(f"{r[k]:.3f}" for k in ("argmax", "expected", "expected choice")),
                ]
                lines.append("| " + " | ".join(map(str, [*cells, f"{bias:.3f}"])) + " |")
        except IrlsimError as e:
            sys.exit(f"style_states: {e}")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
