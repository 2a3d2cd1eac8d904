"""``irlsim scenario list | show | check | sweep | generate | from-highd | from-sumo``: the shipped
scenarios; what irlsim derives from one (route, lanes, stops, exits, mission, traffic) with a picture;
the acceptance of one (the expert and SUMO's driver on the same seeds:
:mod:`irlsim.workflows.scenarios`); a sweep of random routes over many networks
(:mod:`irlsim.workflows.sweep`); generated networks to sweep; a highD recording's road, tracks and
configs (:mod:`irlsim.workflows.highd`); a SUMO configuration's recording and configs
(:mod:`irlsim.workflows.from_sumo`)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from irlsim.config import MAX_SEED, float_in, int_in
from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_file
from irlsim.road import Road, load_road
from irlsim.road.scenario import load_scenario, shipped_scenarios
from irlsim.workflows import from_sumo
from irlsim.workflows.highd import MIN_DURATION, HighDRun, import_highd
from irlsim.workflows.scenarios import CheckRun, GenerateRun, check_scenario_run, generate_networks
from irlsim.workflows.sweep import SweepRun, sweep_networks

HELP = (
    "list the shipped scenarios, show what irlsim derives from one, check the expert on one, sweep "
    "random routes over many networks, generate networks to sweep, import a highD recording or a SUMO "
    "scenario's traffic"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    _action(sub, "list", "the shipped scenarios")
    p = _action(sub, "show", "what irlsim derives from a scenario, and its picture")
    p.add_argument("scenario", nargs="?", default=None, help="a shipped name or a scenario.toml path")
    p.add_argument("--out", type=Path, default=None, help="draw it into this PNG (default: none)")
    _add_check(sub)
    _add_sweep(sub)
    p = _action(
        sub,
        "generate",
        "generate SUMO networks to sweep (grid, spider, random; 1-4 lanes, 30-130 km/h, signals or priority, "
        "left-turn lanes, sidewalks and bike lanes), the same bytes per seed (docs/guide/sweeps.md)",
    )
    p.add_argument("--count", type=int_in(1), required=True, help="networks to generate")
    p.add_argument(
        "--seed", type=int_in(0, MAX_SEED), default=0, help="network i is drawn from (S, i) (default: 0)"
    )
    p.add_argument("--out", type=Path, required=True, help="output folder (kept networks are not rebuilt)")
    _add_highd(sub)
    _add_from_sumo(sub)


def _add_from_sumo(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = _action(
        sub,
        "from-sumo",
        "a SUMO scenario's traffic made ready to learn from: SUMO runs your .sumocfg on its own and "
        "records it (or give --recording), and its network, vehicle types and signal programs become a "
        "scenario, with a collect config (its cars as egos in turn) and a drive config (the cars no "
        "collected episode used) (docs/guide/demonstrators.md)",
    )
    p.add_argument(
        "config", type=Path,
        help="the SUMO configuration (.sumocfg) of your scenario; sumo_tools/... is inside the SUMO wheel "
        "(its game scenarios: sumo_tools/game/cross.sumocfg)",
    )  # fmt: skip
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument(
        "--recording", type=Path, default=None,
        help="a recording already made with this configuration (SUMO's FCD output .xml[.gz], or a .csv / "
        ".parquet file of tracks); default: SUMO runs it and records",
    )  # fmt: skip
    p.add_argument(
        "--duration", type=float_in(0.0, above=True), default=None,
        help="[s] how long SUMO runs from the configuration's begin (default: to its end; "
        f"{from_sumo.DEFAULT_DURATION:g} s where it has none)",
    )  # fmt: skip
    p.add_argument("--seed", type=int_in(0, MAX_SEED), default=0, help="SUMO's random seed (default: 0)")
    p.add_argument(
        "--min-duration", type=float_in(0.0, above=True), default=from_sumo.MIN_DURATION,
        help="[s] the least time a car drives on its route to be an ego "
        f"(default: {from_sumo.MIN_DURATION:g})",
    )  # fmt: skip


def _add_highd(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = _action(
        sub,
        "from-highd",
        "a highD recording made ready to learn from: its road as a SUMO network, each carriageway a "
        "scenario with its tracks, a collect config (its cars as egos in turn) and a drive config (the "
        "cars no collected episode used) (docs/guide/demonstrators.md)",
    )
    p.add_argument("recording", type=Path, help="DIR/NN of highD's NN_tracks.csv, NN_tracksMeta.csv, "
                   "NN_recordingMeta.csv (or one of them)")  # fmt: skip
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument(
        "--min-duration", type=float_in(0.0, above=True), default=MIN_DURATION,
        help=f"[s] the least time a car drives on its carriageway to be an ego (default: {MIN_DURATION:g})",
    )  # fmt: skip


def _action(sub: argparse._SubParsersAction, name: str, text: str) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    return sub.add_parser(name, help=text.split(" (")[0].split(";")[0], description=text)  # type: ignore[no-any-return]


def _add_check(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = _action(
        sub,
        "check",
        "the expert and SUMO's driver on the same seeds of a scenario: the bar and the table (check.md, "
        "check.json); exits 1 when the expert misses the bar",
    )
    p.add_argument("scenario", help="a shipped name or a scenario.toml path")
    p.add_argument("--episodes", type=int_in(1), default=10, help="episodes per driver (default: 10)")
    p.add_argument(
        "--seed", type=int_in(0, MAX_SEED), default=1000, help="episode i uses seed S + i (default: 1000)"
    )
    p.add_argument(
        "--max-time", type=float_in(0.0, above=True), default=None,
        help="[s] simulated time of an episode at most (default: the scenario's, 600 s)",
    )  # fmt: skip
    p.add_argument("--out", type=Path, default=None, help="output folder (default: runs/check/<scenario>)")


def _add_sweep(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = _action(
        sub,
        "sweep",
        "draw random car routes on a network or a folder of them, load each as a scenario and let the expert "
        "drive the first that load: routes loaded, refused by reason, driven within the safety bounds, "
        "crashes (sweep.md, sweep.json, routes.csv); resumable (docs/guide/sweeps.md)",
    )
    p.add_argument("source", type=Path, help="a SUMO network (.net.xml, .net.xml.gz) or a folder of them")
    p.add_argument("--routes", type=int_in(1), required=True, help="routes drawn per network")
    p.add_argument(
        "--seed", type=int_in(0, MAX_SEED), default=0, help="route k is drawn from (S, k), driven with S + k"
    )
    p.add_argument("--out", type=Path, required=True, help="output folder (a rerun resumes it)")
    p.add_argument(
        "--drive",
        type=int_in(0),
        default=1,
        help="routes driven per network: the first that load (default: 1)",
    )
    p.add_argument(
        "--max-time", type=float_in(0.0, above=True), default=90.0,
        help="[s] simulated time of a driven episode at most (default: 90)",
    )  # fmt: skip
    p.add_argument(
        "--workers", type=int_in(1, 256), default=1, help="processes loading and driving routes (default: 1)"
    )


def run(args: argparse.Namespace) -> int:
    if args.action == "list":
        for name in shipped_scenarios():
            print(f"{name:12s} {load_scenario(name, build=False).description}")
        return 0
    if args.action == "check":
        acc = check_scenario_run(CheckRun(args.scenario, args.out, args.episodes, args.seed, args.max_time))
        return 0 if not acc.failures else 1
    if args.action == "sweep":
        sweep_networks(
            SweepRun(args.source, args.routes, args.out, args.seed, args.drive, args.max_time, args.workers)
        )
        return 0
    if args.action == "generate":
        generate_networks(GenerateRun(args.count, args.out, args.seed))
        return 0
    if args.action == "from-highd":
        import_highd(HighDRun(args.recording, args.out, args.min_duration))
        return 0
    if args.action == "from-sumo":
        run = from_sumo.SumoImport(
            args.config, args.out, args.recording, args.duration, args.seed, args.min_duration
        )
        from_sumo.import_sumo(run)
        return 0
    return show(args)


def show(args: argparse.Namespace) -> int:
    if args.scenario is None:
        raise IrlsimError("scenario show needs a scenario: irlsim scenario show NAME|PATH")
    if args.out is not None:
        check_output_file(args.out, "--out", "scenario.png")
    scn = load_scenario(args.scenario)  # the file read once: its road and its description
    road = load_road(scenario=scn)
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
