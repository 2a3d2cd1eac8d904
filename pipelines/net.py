"""``irlsim net``: build the oval's SUMO network from sumo_net/ and describe it."""

from __future__ import annotations

import argparse

from irlsim.road import load_road
from irlsim.road.network import build_net

HELP = "build the SUMO network of the oval course (sumo_net/oval.net.xml) and describe it"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", action="store_true", help="rebuild even when the network is up to date")


def run(args: argparse.Namespace) -> int:

    path = build_net(force=args.force)
    road = load_road(path)
    print(f"network: {path}")
    for key, value in road.describe().items():
        print(f"  {key}: {value}")
    return 0
