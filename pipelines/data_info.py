"""``irlsim data info <dataset>``: counts per split, per-feature statistics, the DEMO distribution."""

from __future__ import annotations

import argparse
from pathlib import Path

from irlsim.data.info import aggregate_info, dataset_info, format_aggregate, format_info
from irlsim.outputs import check_output_file
from irlsim.utils import write_json

HELP = "inspect a dataset: 'irlsim data info data/<name>'"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("action", choices=("info",), help="what to do (info)")
    p.add_argument(
        "path", type=Path, nargs="+", help="dataset folder; several: read as one, per demonstrator"
    )
    p.add_argument("--json", type=Path, default=None, help="also write the figures to this JSON file")


def run(args: argparse.Namespace) -> int:

    if args.json:  # before reading the dataset
        check_output_file(args.json, "--json", "info.json")
    if len(args.path) > 1:
        info = aggregate_info(args.path)
        print(format_aggregate(info))
    else:
        info = dataset_info(args.path[0])
        print(format_info(info))
    if args.json:
        write_json(args.json, info)
        print(f"wrote {args.json}")
    return 0
