"""``irlsim evaluate``: Table I (model, trainable parameters, EVD, ED, OPD, DEMO) on the sequential test
split with a history of H cycles, convergence plots and the OPD distribution per model: the arguments
become an :class:`irlsim.workflows.evaluate.EvaluateRun` for
:func:`irlsim.workflows.evaluate.evaluate_runs`."""

from __future__ import annotations

import argparse
from pathlib import Path

from irlsim import devices
from irlsim.config import int_in
from irlsim.data.roads import parse_selection
from irlsim.workflows.evaluate import EvaluateRun, evaluate_runs

HELP = "evaluate every trained model on the sequential test split: Table I (Markdown, JSON) and plots"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--data",
        type=Path,
        nargs="+",
        action="extend",
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
    p.add_argument(
        "--scenario-select",
        default=None,
        metavar="A,B",
        help="evaluate on the episodes of these scenarios only (a dataset over several scenarios); models "
        "trained on any selection of the dataset's scenarios are accepted",
    )
    p.add_argument(
        "--demonstrator-select",
        default=None,
        metavar="A,B",
        help="evaluate on the folders of these demonstrators only (an identity as irlsim data "
        "info names it, or a kind: expert, sumo, recording); models trained on any selection are accepted",
    )
    p.add_argument(
        "--held-out",
        action="store_true",
        help="the models were trained on other data (a road they never saw): evaluate them on --data "
        "anyway, each with its own feature normalisation (without it such models are refused); refused "
        "for models trained on --data itself, which is not held out; results.json records which it was",
    )
    devices.add_arguments(p, "evaluation")


def request(args: argparse.Namespace) -> EvaluateRun:
    """The parsed arguments as the library's request."""
    return EvaluateRun(
        tuple(args.data),
        args.runs,
        args.out,
        args.split,
        args.history,
        args.threads,
        not args.no_references,
        args.device,
        args.precision,
        parse_selection(args.scenario_select),
        parse_selection(args.demonstrator_select, "--demonstrator-select", "demonstrators"),
        args.held_out,
    )


def run(args: argparse.Namespace) -> int:
    evaluate_runs(request(args))
    return 0
