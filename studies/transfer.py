"""One reward, many roads: does a reward learned on some scenarios drive one it never saw?

For every held-out scenario X (every shipped scenario but the oval) three trainings are compared on X's
evaluation seeds, with the expert and the expert's hand-tuned reward in the same drive:

- zero-shot: trained on the oval alone;
- leave-one-out: trained on every shipped scenario but X;
- in-domain: trained on X alone.

Each scenario gets its own dataset (the collect config, its own base seed: 0, 1, 2, ... in the order
of ``shipped_scenarios()``), a training is ``irlsim train --data D1 --data D2 ...`` (the aggregate of
the datasets), and drives use ``irlsim drive --scenario X``. Every step is a separate command; a step
whose output exists is skipped, so the study resumes where it stopped. Run from the repository root:

    nice -n 5 .venv/bin/python studies/transfer.py --out runs/transfer [--seeds 0 1 2] [--epochs 6] \\
        [--episodes 10] [--threads 2] [--workers 2]

The table goes to ``<out>/transfer.md`` and ``<out>/transfer.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from irlsim.road.scenario import shipped_scenarios

MODELS = ("LIRL", "PACNN+S", "PTACNN+S")
EVAL_SEED = 1000  # the drives' first seed: no dataset of this study uses seeds in 1000..1999


def run(cmd: list[str]) -> None:
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def irlsim() -> str:
    return str(Path(sys.executable).parent / "irlsim")


def training_sets(scenarios: list[str]) -> dict[str, list[str]]:
    """name -> the scenarios it trains on."""
    held = [s for s in scenarios if s != "oval"]
    out = {"oval-only": ["oval"]}
    for x in held:
        out[f"loo-{x}"] = [s for s in scenarios if s != x]
        out[f"in-{x}"] = [x]
    return out


def collect(out: Path, scenarios: list[str], config: str) -> None:
    for k, s in enumerate(scenarios):
        data = out / "data" / s
        if (data / "manifest.json").is_file() and '"complete": true' in (data / "manifest.json").read_text():
            continue
        run(
            [irlsim(), "collect", "--config", config, "--scenario", s, "--set", f"seed={k}"]
            + ["--workers", "1", "--out", str(data)]
        )


def train(out: Path, name: str, sets: list[str], seed: int, epochs: int, threads: int) -> Path:
    runs = out / "runs" / f"{name}-seed{seed}"
    data = [a for s in sets for a in ("--data", str(out / "data" / s))]
    common = ["--set", f"seed={seed}", "--set", f"threads={threads}"]
    if not (runs / "stage1" / "PACNN+S" / "checkpoint.pt").is_file():
        run(
            [irlsim(), "train", "--stage", "1", "--config", "configs/train/stage1.toml", *data]
            + ["--out", str(runs), "--set", 'models=["LIRL","PACNN+S"]', "--set", f"epochs={epochs}", *common]
        )
    if not (runs / "stage2" / "PTACNN+S" / "checkpoint.pt").is_file():
        run(
            [irlsim(), "train", "--stage", "2", "--config", "configs/train/stage2.toml", *data]
            + ["--out", str(runs), "--set", 'models=["PTACNN+S"]', *common]
        )
    return runs


def drive(out: Path, runs: Path, x: str, episodes: int, config: str, workers: int) -> Path:
    target = out / "drive" / x / runs.name
    if not (target / "drive.json").is_file():
        run(
            [irlsim(), "drive", "--runs", str(runs), "--model", "expert," + ",".join(MODELS)]
            + ["--episodes", str(episodes), "--seed", str(EVAL_SEED), "--config", config]
            + ["--scenario", x, "--frames", "0", "--workers", str(workers), "--out", str(target)]
        )
    return target / "drive.json"


def row(x: str, training: str, summary: dict[str, Any], expert_kmh: float) -> dict[str, Any]:
    return {
        "scenario": x,
        "training": training,
        "model": summary["drive/model"],
        "episodes": summary["drive/episodes"],
        "collisions": summary["drive/collisions"],
        "exits": summary["drive/exits"],
        "red": summary.get("drive/red_crossings", 0),
        "stops": f"{summary['drive/stop_lines_compliant']}/{summary['drive/stop_lines_passed']}",
        "mission": f"{summary['drive/checkpoints_in_lane']}/{summary['drive/checkpoints_passed']}",
        "speed_vs_expert": round(summary["drive/mean_speed_kmh"] / max(expert_kmh, 1e-9), 3),
        "score": summary.get("score/score"),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/transfer")
    p.add_argument("--config", default="configs/collect/default.toml")
    p.add_argument("--seeds", type=int, nargs="+", default=[0], help="training seeds of the leave-one-out")
    p.add_argument("--epochs", type=int, default=6, help="stage-1 epochs")
    p.add_argument("--episodes", type=int, default=10, help="evaluation episodes per model and road")
    p.add_argument("--threads", type=int, default=1, help="torch threads of each training")
    p.add_argument("--workers", type=int, default=1, help="episodes driven in parallel")
    p.add_argument("--table-only", action="store_true", help="only the table of the drives already done")
    a = p.parse_args()
    out = Path(a.out)
    os.environ.setdefault("OMP_NUM_THREADS", str(a.threads))
    scenarios = list(shipped_scenarios())
    if not a.table_only:
        collect(out, scenarios, a.config)
    rows: list[dict[str, Any]] = []
    for name, sets in training_sets(scenarios).items():
        seeds = a.seeds if name.startswith("loo-") else a.seeds[:1]
        for seed in seeds:
            runs = out / "runs" / f"{name}-seed{seed}"
            if not a.table_only:
                train(out, name, sets, seed, a.epochs, a.threads)
            targets = (
                [name.split("-", 1)[1]] if name != "oval-only" else [s for s in scenarios if s != "oval"]
            )
            for x in targets:
                if a.table_only and not (out / "drive" / x / runs.name / "drive.json").is_file():
                    continue
                drive_json = drive(out, runs, x, a.episodes, a.config, a.workers)
                summaries = json.loads(drive_json.read_text())["summary"]
                expert = next(s for s in summaries if s["drive/model"] == "expert")
                rows += [row(x, f"{name} seed {seed}", s, expert["drive/mean_speed_kmh"]) for s in summaries]
    (out / "transfer.json").write_text(json.dumps(rows, indent=1) + "\n")
    cols = "scenario | training | model | episodes | collisions | exits | red | stops | mission"
    cols += " | speed / expert"
    lines = [f"| {cols} | score |", "|" + "---|" * 11]
    for r in sorted(rows, key=lambda r: (r["scenario"], r["training"], r["model"])):
        lines.append("| " + " | ".join(str(r[k]) for k in r) + " |")
    (out / "transfer.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / 'transfer.md'} and {out / 'transfer.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
