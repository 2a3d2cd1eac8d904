"""The temporal-attention study (docs/results/temporal-attention.md, "The temporal network study").

Trains PTACNN+S in stage 2 with every configuration below on ONE frozen stage-1 PACNN+S (stage 2 is
cheap), evaluates each on the VALIDATION split (with that stage-1 model's H-mean row beside it), and
writes the table of validation figures. The default is then chosen by validation OPD and reported on
test separately (docs/results/temporal-attention.md gives the commands). Run from the repository root:

    nice -n 5 .venv/bin/python studies/temporal_attention.py --data data/default \\
        --base runs/default/stage1 --out runs/study [--only NAME ...]

Each configuration lives in ``<out>/<name>/`` (stage2/PTACNN+S/ and val/results.{md,json}); a finished
one is skipped when run again. ``--set KEY=VALUE`` adds an override to every configuration (e.g. a
seed). The table goes to ``<out>/study.md`` and ``<out>/study.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

#: name -> --set overrides of configs/train/stage2.toml (PTACNN+S only)
VARIANTS: dict[str, list[str]] = {
    "paper H=10": [],
    "H=1": ["model.history=1"],
    "H=5": ["model.history=5"],
    "H=20": ["model.history=20"],
    "target t+1..t+5": ["target_ahead=5"],
    "target t+1..t+10": ["target_ahead=10"],
    "KL to uniform 0.1": ["weight_reg=0.1"],
    "KL to uniform 1": ["weight_reg=1.0"],
    "entropy 0.1": ["weight_reg=0.1", "weight_reg_kind='entropy'"],
    "drop newest 0.3": ["model.drop_newest=0.3"],
    "inputs theta": ["model.tan_inputs='theta'"],
    "inputs context": ["model.tan_inputs='context'"],
    "inputs context+theta+delta": ["model.tan_inputs='context+theta+delta'"],
}


def slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name).strip("_")


def run(cmd: list[str]) -> None:
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def train_and_evaluate(args: argparse.Namespace, folder: Path, sets: list[str]) -> None:
    """Stage 2's PTACNN+S of one variant on the frozen base, then Table I on the validation split."""
    irlsim = str(Path(sys.executable).with_name("irlsim"))
    stage1 = folder / "stage1"
    folder.mkdir(parents=True, exist_ok=True)
    if not stage1.exists():  # the frozen base, so evaluate shows its H-mean row beside PTACNN+S
        stage1.mkdir()
        os.symlink(Path(args.base).resolve() / "PACNN+S", stage1 / "PACNN+S")
    cmd = [irlsim, "train", "--stage", "2", "--config", args.config, "--data", args.data]
    cmd += ["--out", str(folder), "--base", args.base, "--set", 'models=["PTACNN+S"]']
    cmd += ["--set", f"threads={args.threads}"]
    for s in sets:
        cmd += ["--set", s]
    run(cmd)
    evaluate = [irlsim, "evaluate", "--data", args.data, "--runs", str(folder), "--split", "validation"]
    run([*evaluate, "--out", str(folder / "val"), "--threads", str(args.threads), "--no-references"])


def markdown(table: list[dict]) -> str:
    """The study's table, one row per variant."""
    lines = [
        "| configuration | val OPD [m] | val ED [m] | PACNN+S H-mean OPD / ED [m] "
        "| plan change [m] (at switches) "
        "| PACNN+S plan change [m] | theta change (PACNN+S) | newest weight (at switches) "
        "| weight shift (at switches) | epoch |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in table:
        lines.append(
            f"| {r['name']} | {r['opd']:.3f} | {r['ed']:.3f} | {r['base_opd']:.3f} / {r['base_ed']:.3f} | "
            f"{r['plan_change']:.3f} ({r['plan_change_switch']:.3f}) | {r['base_plan_change']:.3f} | "
            f"{r['theta_change']:.3f} ({r['base_theta_change']:.3f}) | "
            f"{r['newest_weight']:.3f} ({r['newest_weight_switch']:.3f}) | "
            f"{r['weight_shift']:.3f} ({r['weight_shift_switch']:.3f}) | {r['epoch']} |"
        )
    return "\n".join(lines) + "\n"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True)
    p.add_argument("--base", required=True, help="stage-1 folder holding PACNN+S/")
    p.add_argument("--out", required=True)
    p.add_argument("--config", default="configs/train/stage2.toml")
    p.add_argument("--threads", type=int, default=1, help="torch threads of training and evaluation")
    p.add_argument("--only", nargs="*", help="names of VARIANTS to run (default: all)")
    p.add_argument("--set", action="append", default=[], help="extra override for every variant")
    args = p.parse_args()
    out = Path(args.out)
    names = args.only or list(VARIANTS)
    table = []
    for name in names:
        sets = [*VARIANTS[name], *args.set]
        folder = out / slug(name)
        res = folder / "val" / "results.json"
        if not res.exists():
            train_and_evaluate(args, folder, sets)
        rows = {r["model"]: r for r in json.loads(res.read_text())["rows"]}
        t, b = rows["PTACNN+S"], rows["PACNN+S"]
        table.append(
            {
                "name": name,
                "set": sets,
                "opd": t["opd"],
                "ed": t["ed"],
                "base_opd": b["opd"],
                "base_ed": b["ed"],
                "plan_change": t["stability"]["plan_change"],
                "plan_change_switch": t["stability"]["plan_change_switch"],
                "base_plan_change": b["stability"]["plan_change"],
                "theta_change": t["stability"]["theta_change"],
                "base_theta_change": b["stability"]["theta_change"],
                "newest_weight": t["temporal"]["newest_weight"],
                "newest_weight_switch": t["temporal"]["newest_weight_switch"],
                "weight_shift": t["temporal"]["weight_shift"],
                "weight_shift_switch": t["temporal"]["weight_shift_switch"],
                "epoch": t.get("selected_epoch"),
            }
        )
    md = markdown(table)
    print(md)
    if not args.only:
        from irlsim.utils import atomic_write_text, write_json

        atomic_write_text(out / "study.md", md)
        write_json(out / "study.json", table)
        print(f"wrote {out / 'study.md'} and {out / 'study.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
