"""``irlsim evaluate``: Table I (model, trainable parameters, EVD, ED, OPD, DEMO) on the sequential test
split with a history of H cycles, convergence plots and the OPD distribution per model."""

from __future__ import annotations

import argparse
import functools
from pathlib import Path

from irlsim import devices
from irlsim.config import int_in
from irlsim.data.aggregate import open_datasets
from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_dir
from irlsim.train.evaluate import evaluate_models
from irlsim.viz.temporal import save_situation_strips

HELP = "evaluate every trained model on the sequential test split: Table I (Markdown, JSON) and plots"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--data",
        type=Path,
        nargs="+",
        required=True,
        help="dataset folder; several: the aggregate the models were trained on (DAgger rounds add no test "
        "episodes, so its test split is the first folder's)",
    )
    p.add_argument(
        "--runs",
        type=Path,
        required=True,
        help="runs folder of 'irlsim train --out' (stage1/<model>/, stage2/<model>/checkpoint.pt)",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default: <runs>/eval)")
    p.add_argument("--split", default="test", help="split to evaluate on (default: test)")
    p.add_argument(
        "--history",
        type=int_in(1),
        default=None,
        help="H: history of predicted thetas [cycles] (default: the PTACNN's own H, else 10; "
        "a PTACNN trained with another H is refused)",
    )
    p.add_argument("--threads", type=int_in(1, 1024), default=2, help="torch CPU threads")
    p.add_argument(
        "--no-references",
        action="store_true",
        help="leave out the reference rows expert-theta, executed and oracle (the oracle's per-cycle fit "
        "is the slow part); 'random policy' stays",
    )
    devices.add_arguments(p, "evaluation")


def run(args: argparse.Namespace) -> int:

    if args.history is not None and args.history < 1:
        raise IrlsimError(f"--history must be >= 1, got {args.history}")
    if args.threads < 1:
        raise IrlsimError(f"--threads must be >= 1, got {args.threads}")
    device = devices.resolve_device(args.device)
    out = args.out or args.runs / "eval"
    check_output_dir(out, "--out")
    if not args.runs.is_dir():
        raise IrlsimError(f"runs folder {args.runs} not found: train first with 'irlsim train --stage 1'")
    with devices.use(device, args.precision):
        evaluate_models(
            open_datasets(args.data),
            args.runs,
            out,
            H=args.history,
            split=args.split,
            threads=args.threads,
            references=not args.no_references,
            strips=functools.partial(save_situation_strips, out),
        )
    print((out / "results.md").read_text())
    print(
        f"wrote {out}/results.md, results.json, convergence.png, opd_distribution.png"
        " (and temporal_<model>_<situation>.png for temporal models)"
    )
    return 0
