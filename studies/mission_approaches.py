"""Where the demonstrator drives on the approach to each checkpoint: the states a dataset shows.

    .venv/bin/python studies/mission_approaches.py data/default data/paper_me [--split train]
    .venv/bin/python studies/mission_approaches.py data/paper_me --split validation \
        --model runs/paper_me_stop/stage1/PACNN+S/checkpoint.pt

Per dataset and required lane of the target checkpoint, for bands of the remaining route distance to it:
the planning cycles in the band, how many of them the ego is off the required lane, and how many of those
it is off the lane at more than 10 m/s (an approach at speed in the wrong lane, what a learned driver that
keeps its lane too long reaches). The checkpoints (route position, required lane) come from the road
network; the remaining distance from the cycles table (``ego_s``, ``target_checkpoint``). See
docs/results/dagger.md "DAgger: the paper-scale mission": a cycle the demonstrator never drives is a state no
demonstration covers, which is what DAgger (``irlsim dagger``) adds.

With ``--model`` (a stage-1 checkpoint) the table also has the model's theta on those cycles (one
dataset): the mean weights of mission_lane, velocity and jerk_lon and the median ratio mission_lane /
velocity (the learned price of a lane against a unit of squared speed error).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from irlsim import FEATURE_NAMES
from irlsim.data.reader import open_dataset
from irlsim.reward import load_reward
from irlsim.road.geometry import load_road
from irlsim.road.scenario import DEFAULT_SCENARIO

BANDS = ((0.0, 50.0), (50.0, 110.0), (110.0, 200.0), (200.0, 400.0))
ML, VEL, JERK = (FEATURE_NAMES.index(n) for n in ("mission_lane", "velocity", "jerk_lon"))


def predict_theta(ds: Any, split: str, checkpoint: Path) -> np.ndarray:
    """[C, 15] the checkpoint's theta on every cycle of the split of dataset ``ds``, ordered as its
    cycles table (episode, cycle)."""
    t = ds.split_tensors(split)
    model = load_reward(str(checkpoint), str(checkpoint.parent), n_policies=int(t.features.shape[1]))
    assert not model.is_expert, f"{checkpoint} is no learned model"
    print(f"theta of {checkpoint} on {t.n_cycles} {split} cycles ...", flush=True)
    return np.array(
        [model.predict(t.features[i], t.control_points[i], t.actions[i]) for i in range(t.n_cycles)]
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("data", nargs="+", type=Path, help="dataset folders (irlsim collect --out)")
    p.add_argument("--split", default="train", help="split to read (default train)")
    p.add_argument("--model", type=Path, default=None, help="stage-1 checkpoint: add its theta (one dataset)")
    args = p.parse_args(argv)
    if args.model is not None and len(args.data) != 1:
        raise SystemExit("--model reads one dataset: give one data folder")
    road = load_road(scenario=_scenario_of(args.data[0]))
    cs = np.array([c.s for c in road.checkpoints])
    cl = np.array([c.lane for c in road.checkpoints])
    lanes = sorted(set(cl.tolist()))
    datasets = []
    for data in args.data:
        try:
            datasets.append(open_dataset(data))
        except Exception as e:  # a study: say what is wrong in one line
            raise SystemExit(f"{data}: {e}") from None
    theta = None if args.model is None else predict_theta(datasets[0], args.split, args.model)
    head = ["data", "required lane", "remaining [m]", "cycles", "off the lane", "off the lane at > 10 m/s"]
    if args.model is not None:
        head += ["theta mission_lane", "theta velocity", "theta jerk_lon", "mission_lane / velocity (median)"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for data, ds in zip(args.data, datasets, strict=True):
        try:
            t = ds.read_cycles_table(args.split)
        except Exception as e:
            raise SystemExit(f"{data}: {e}") from None
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
                row.append(str((off & fast).sum()))
                if theta is not None and m.any():
                    th = theta[m]
                    ratio = np.median(th[:, ML] / np.maximum(th[:, VEL], 1e-3))
                    row += [
                        f"{th[:, ML].mean():.2f}",
                        f"{th[:, VEL].mean():.3f}",
                        f"{th[:, JERK].mean():.3f}",
                    ]
                    row.append(f"{ratio:.1f}")
                print("| " + " | ".join(row) + " |")
    return 0


def _scenario_of(data: Path) -> str:
    """The road a dataset was collected on (its manifest's config; the default road when it names none)."""
    try:
        manifest = json.loads((data / "manifest.json").read_text())
    except (OSError, ValueError):
        return DEFAULT_SCENARIO
    return str(((manifest.get("config") or {}).get("scenario") or {}).get("name", DEFAULT_SCENARIO))


if __name__ == "__main__":
    raise SystemExit(main())
