"""``irlsim scenario list | show NAME|PATH``: the shipped scenarios, and what irlsim derives from one
(route, lanes, stops, exits, mission, traffic) with a picture."""

from __future__ import annotations

import argparse
from pathlib import Path

from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_file
from irlsim.road import load_road
from irlsim.road.scenario import load_scenario, shipped_scenarios

HELP = "list the shipped scenarios, or show what irlsim derives from one (and draw it)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=("list", "show"), help="list the shipped ones, or show one")
    parser.add_argument("scenario", nargs="?", default=None, help="a shipped name or a scenario.toml path")
    parser.add_argument("--out", type=Path, default=None, help="draw it into this PNG (default: none)")


def run(args: argparse.Namespace) -> int:
    if args.action == "list":
        for name in shipped_scenarios():
            print(f"{name:12s} {load_scenario(name, build=False).description}")
        return 0
    if args.scenario is None:
        raise IrlsimError("scenario show needs a scenario: irlsim scenario show NAME|PATH")
    if args.out is not None:
        check_output_file(args.out, "--out", "scenario.png")
    scn = load_scenario(args.scenario)
    road = load_road(scenario=args.scenario)
    print(f"scenario {scn.name}: {scn.path}")
    print(f"  network: {scn.net_file}")
    for key, value in describe(road).items():
        print(f"  {key}: {value}")
    if args.out is not None:
        from irlsim.viz.road_map import draw_scenario  # lazy: matplotlib

        print(f"picture: {draw_scenario(road, args.out, f'{scn.name}: {scn.description}')}")
    return 0


def describe(road: object) -> dict[str, object]:
    """What irlsim derived: the road's own summary and the route's edges."""
    out = dict(road.describe())  # type: ignore[attr-defined]
    out["edges"] = " ".join(road.edges)  # type: ignore[attr-defined]
    if not road.closed:  # type: ignore[attr-defined]
        out["route_length_m"] = round(road.route_end_s - road.route_begin_s, 1)  # type: ignore[attr-defined]
    return out
