"""``irlsim net``: build the oval's SUMO network from sumo_net/ and describe it
(:func:`irlsim.workflows.net.build_network`)."""

from __future__ import annotations

import argparse

from irlsim.workflows.net import build_network

HELP = "build the SUMO network of the oval course (sumo_net/oval.net.xml) and describe it"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", action="store_true", help="rebuild even when the network is up to date")


def run(args: argparse.Namespace) -> int:
    build_network(force=args.force)
    return 0
