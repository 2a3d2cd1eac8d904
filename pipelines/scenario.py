"""``irlsim scenario list | show NAME|PATH``: the shipped scenarios, and what irlsim derives from one
(route, lanes, stops, exits, mission, traffic) with a picture."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_file
from irlsim.road import Road, load_road
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

        title = f"{scn.name}: {scn.description}" if scn.description else scn.name
        print(f"picture: {draw_scenario(road, args.out, title)}")
    return 0


def describe(road: Road) -> dict[str, object]:
    """What irlsim derived: the road's own summary, the route's edges, its lanes stretch by stretch, the
    speed limits and where the traffic comes from."""
    out = dict(road.describe())
    out["edges"] = " ".join(road.edges)
    hi_s = road.lap_length if road.closed else road.route_end_s
    if not road.closed:
        out["route_length_m"] = round(road.route_end_s - road.route_begin_s, 1)
    s = np.arange(road.route_begin_s, hi_s, 1.0)
    lo, hi = road.lane_bounds(s)
    change = np.flatnonzero((np.diff(lo) != 0) | (np.diff(hi) != 0)) + 1
    starts = np.concatenate([[0], change])
    out["lanes_per_stretch"] = ", ".join(
        f"{s[a]:.0f}-{s[b - 1] if b < len(s) else hi_s:.0f} m: lanes {lo[a]}..{hi[a]}"
        for a, b in zip(starts, [*change, len(s)], strict=True)
    )
    out["speed_limit_kmh"] = round(3.6 * road.speed_limit_over(road.route_begin_s, hi_s), 1)
    if road.max_speed_limit > road.speed_limit_over(road.route_begin_s, hi_s):
        out["speed_limit_kmh"] = f"{out['speed_limit_kmh']} .. {3.6 * road.max_speed_limit:.1f}"
    out["traffic"] = (
        f"its own SUMO demand ({', '.join(p.name for p in road.demand)}), warm-up {road.warmup:.0f} s"
        if road.demand
        else "irlsim's spawner (the config's scenario.n_vehicles kept around the ego)"
    )
    return out
