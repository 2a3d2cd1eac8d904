r"""Does a recording's position noise cost its demonstrations, and what window do the recorded ego's rates
need?

A recorded ego's policy set starts from its state, whose rates (acceleration, lateral velocity and
acceleration) are fitted to its recorded track over ``demonstrator.rate_window``
(:func:`irlsim.data.recorded.local_rates`; 0: finite differences over one 0.1 s step). SUMO alone drives
30 one-lap trips of the oval (one every 4 s, SUMO's routing and default driver, SUMO seed 101: a
recording no other study uses) at a 0.04 s step, as a 25 Hz tracker records, and at its default 1 s step.
The 25 Hz FCD is written as the columnar format as recorded, with 0.2 m of Gaussian noise on the positions,
and with 0.5 m on the positions, 0.3 m/s on the speeds and 0.05 rad on the headings (numpy seed 0); the 1 s
FCD is read as SUMO wrote it. Each is collected at every window of ``--windows`` (6 training episodes of at
most 400 cycles, 500 policies, the planner's top speed at 35 m/s as for the style study's recording) and
the training split's cycles with a demonstration and their distance are printed. About 4 minutes;
``--learn 0 1`` also learns PACNN+S from each 25 Hz recording at 2 s and with finite differences (those
training seeds) and evaluates it on the clean recording's validation and test episodes (2 more minutes):

    .venv/bin/python studies/recording_noise.py --out runs/recording-noise [--learn 0 1]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).parent))
from styles import complete, irlsim  # noqa: E402
from sumo_alone import sumo_alone  # noqa: E402

from irlsim.data.recording_read import read_rows  # noqa: E402
from irlsim.road import load_road  # noqa: E402

CARS, SECONDS, SEED = 30, 150, 101
#: name -> (position [m], speed [m/s], heading [rad]) noise of the 25 Hz recording's columnar copies
NOISE = {"25 Hz": (0.0, 0.0, 0.0), "25 Hz, 0.2 m": (0.2, 0.0, 0.0), "25 Hz, 0.5 m": (0.5, 0.3, 0.05)}
CONFIG = """seed = 0
workers = {workers}
train_episodes = 6
validation_episodes = 1
test_episodes = 1
max_cycles = 400

[planner]
n_policies = 500
v_max = 35.0

[demonstrator]
kind = "recording"
file = "{file}"
rate_window = {window}
"""


def columnar(fcd: Path, out: Path, noise: tuple[float, float, float]) -> Path:
    """The FCD as the columnar format with Gaussian ``noise`` on positions, speeds and headings (once)."""
    if out.is_file():
        return out
    rows = read_rows(fcd)  # SUMO's angle as the ENU heading, as irlsim reads it
    arrays = {k: getattr(rows, k) for k in ("id", "t", "x", "y", "v", "heading")}
    rng, n = np.random.default_rng(0), len(rows.t)
    for k, sigma in (("x", noise[0]), ("y", noise[0]), ("v", noise[1]), ("heading", noise[2])):
        arrays[k] = arrays[k] + rng.normal(0.0, sigma, n) if sigma else arrays[k]
    arrays["v"] = np.maximum(arrays["v"], 0.0)
    arrays["heading"] = (arrays["heading"] + math.pi) % (2 * math.pi) - math.pi
    pacsv.write_csv(pa.table(arrays), out)
    return out


def demonstrations(data: Path) -> tuple[int, int, float]:
    """(cycles, cycles with a demonstration, the median demonstration distance [m]) of the training split."""
    cycles = [
        pq.read_table(p, columns=["has_demo", "demo_distance"])
        for p in (data / "train").glob("*.cycles.parquet")
    ]
    has = np.concatenate([c.column("has_demo").to_numpy() for c in cycles])
    dist = np.concatenate([c.column("demo_distance").to_numpy() for c in cycles])
    return len(has), int(has.sum()), float(np.median(dist[has]))


def run() -> None:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter
    )
    p.add_argument("--out", type=Path, required=True, help="the recordings, configs and datasets")
    p.add_argument("--windows", type=float, nargs="+", default=[0.0, 0.5, 1.0, 2.0], help="rate windows [s]")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--learn", type=int, nargs="*", metavar="SEED", help="also learn (training seeds)")
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    road = load_road()
    files = {}
    for step, name in ((0.04, "fcd-0.04s.xml"), (None, "fcd-1s.xml")):
        if not (args.out / name).is_file():
            sumo_alone(args.out / name, road, CARS, SECONDS, SEED, step)
    for label, noise in NOISE.items():
        files[label] = columnar(
            args.out / "fcd-0.04s.xml", args.out / f"rec-{'-'.join(map(str, noise))}.csv", noise
        )
    files["SUMO's FCD at 1 s"] = args.out / "fcd-1s.xml"
    rows = []
    for label, file in files.items():
        for window in args.windows:
            data = args.out / "data" / f"{file.stem}-w{window:g}"
            cfg = data.parent / f"{data.name}.toml"
            cfg.parent.mkdir(parents=True, exist_ok=True)
            cfg.write_text(CONFIG.format(workers=args.workers, file=file.resolve(), window=window))
            if not complete(data):
                subprocess.run([irlsim(), "collect", "--config", str(cfg), "--out", str(data)], check=True)
            rows.append((label, window, *demonstrations(data)))
    print("\n| recording | rate window [s] | training cycles | with a demonstration | median distance [m] |")
    print("|---|---|---|---|---|")
    for label, window, n, has, med in rows:
        print(f"| {label} | {window:g} | {n} | {has} ({has / n:.2f}) | {med:.2f} |")
    if args.learn:
        learn(args.out, files, args.learn)
    print(f"\nwrote {args.out}")


def quiet(cmd: list[str], log: Path) -> None:
    """Run an irlsim command with its output in ``log`` (named where it fails)."""
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("w") as f:
        if subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode:
            raise SystemExit(f"{' '.join(cmd)} failed: see {log}")


def learn(out: Path, files: dict[str, Path], seeds: list[int]) -> None:
    """PACNN+S learned from each 25 Hz recording (at 2 s and with finite differences; training seeds
    ``seeds``, ``configs/train/stage1.toml`` for 6 epochs) and evaluated (Table I's OPD and ED) on the clean
    recording's validation and test episodes: do rewards learned from noisy positions predict the driving
    itself?"""
    clean = out / "data" / f"{files['25 Hz'].stem}-w2"
    print("\n| learned from | window [s] | validation OPD / ED [m], seed by seed | test OPD / ED [m] |")
    print("|---|---|---|---|")
    for label in NOISE:
        for window in (2.0, 0.0):
            data = out / "data" / f"{files[label].stem}-w{window:g}"
            cells: dict[str, list[str]] = {"validation": [], "test": []}
            for seed in seeds:
                runs = out / "runs" / f"{data.name}-s{seed}"
                if not (runs / "stage1" / "PACNN+S" / "checkpoint.pt").is_file():
                    cmd = [irlsim(), "train", "--stage", "1", "--config", "configs/train/stage1.toml"]
                    cmd += ["--set", 'models=["PACNN+S"]', "--set", "epochs=6", "--set", f"seed={seed}"]
                    quiet([*cmd, "--data", str(data), "--out", str(runs)], runs.with_suffix(".train.log"))
                for split in cells:
                    res = runs / f"eval-clean-{split}"
                    if not (res / "results.json").is_file():
                        cmd = [
                            irlsim(),
                            "evaluate",
                            "--data",
                            str(clean),
                            "--runs",
                            str(runs),
                            "--split",
                            split,
                        ]
                        cmd += ["--no-references", "--out", str(res)] + (
                            ["--held-out"] if data != clean else []
                        )
                        quiet(cmd, res.with_suffix(".log"))
                    row = json.loads((res / "results.json").read_text())["rows"][0]
                    cells[split].append(f"{row['opd']:.2f} / {row['ed']:.2f}")
            print(f"| {label} | {window:g} | " + " | ".join(", ".join(c) for c in cells.values()) + " |")


if __name__ == "__main__":
    run()
