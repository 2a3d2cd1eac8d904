"""``irlsim drive``: closed-loop driving in SUMO with the expert and learned rewards, side by side.

The arguments become a :class:`irlsim.workflows.drive.DriveRun`; :func:`irlsim.workflows.drive.drive_models`
drives every model on the same seeds and writes ``<out>/drive.json``, ``<out>/drive.md`` and the pictures
(its module docstring). Exits 1 when an episode failed twice.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from irlsim import devices
from irlsim.config import MAX_SEED, float_in, int_in
from irlsim.errors import IrlsimError
from irlsim.planner.choice import CHOICES
from irlsim.planner.expert import FOLLOW_HEADWAY
from irlsim.workflows.drive import DriveRun, drive_models
from pipelines.collect import add_executor_arguments

HELP = (
    "drive the ego in SUMO with the expert and learned rewards: closed-loop table (JSON, Markdown), pictures"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--runs",
        type=Path,
        default=None,
        help="the runs folder 'irlsim train --out' wrote (models in stage1/, stage2/)",
    )
    p.add_argument(
        "--model",
        default="expert",
        help="comma-separated: expert (hand-tuned theta + model-based selection), expert-theta (that theta "
        "alone, argmax V), demonstrator (the --config's SUMO driver or recorded ego, to compare styles "
        "with), LIRL, 1DCNN, Bi1DCNN, PACNN, PACNN+S, PTACNN, PTACNN+S or checkpoint paths (default: expert)",
    )
    p.add_argument("--episodes", type=int_in(1), default=1, help="episodes per model (default: 1)")
    p.add_argument("--laps", type=int_in(1), default=1, help="laps per episode (default: 1)")
    p.add_argument(
        "--seed", type=int_in(0, MAX_SEED), default=100, help="episode i uses seed S + i (default: 100)"
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        help="the collect TOML the models were trained with (planner and scenario; default: built-in)",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a field of --config, as the collection did, e.g. --set planner.n_policies=500 "
        "(repeatable)",
    )
    p.add_argument(
        "--reactive",
        action="store_true",
        help="on a recording (a --config with [demonstrator] kind = 'recording'): SUMO drives the other "
        "vehicles from their first recorded pose on (default: they replay their recorded motion)",
    )
    p.add_argument(
        "--safety",
        action="store_true",
        help="learned models drop policies labelled collision / off-road / exit (model-based check)",
    )
    add_choice_arguments(p)
    p.add_argument(
        "--out", type=Path, default=None, help="output folder (default: <runs>/drive, or runs/drive)"
    )
    p.add_argument(
        "--frames",
        type=int_in(0),
        default=40,
        help="animation frames of the first episode of each model (0 = no pictures; default: 40)",
    )
    p.add_argument(
        "--max-cycles",
        type=int_in(0),
        default=0,
        help="stop each episode after this many planning cycles (0 = laps, collision, exit or time-out)",
    )
    p.add_argument(
        "--threads", type=int_in(1, 1024), default=1, help="torch CPU threads of the reward inference"
    )
    p.add_argument(
        "--workers",
        type=int_in(1, 256),
        default=1,
        help="episodes driven in parallel processes, one libsumo each (default: 1, in this process, "
        "without a time limit unless --episode-timeout is given); drive.json is the same for any count",
    )
    add_executor_arguments(p)
    devices.add_arguments(p, "reward inference")
    p.add_argument(
        "--scenario",
        default=None,
        help="the road: a shipped scenario (irlsim scenario list) or a scenario.toml path (default: the "
        "config's [scenario] name, the oval)",
    )


def add_choice_arguments(p: argparse.ArgumentParser) -> None:
    """--choice, --lane-change-bias, --commit, --full-stop, --keep-distance and --in-lane: how a learned
    reward picks its policy (irlsim.planner.choice, irlsim.planner.expert.ThetaDriver)."""
    p.add_argument(
        "--choice",
        choices=CHOICES,
        default="argmax",
        help="how a learned model picks its policy: 'argmax' of its reward (the paper's; default), "
        "'expected': the maneuver and policy its maximum-entropy distribution expects, or 'maneuver': "
        "that maneuver's most likely policy",
    )
    p.add_argument(
        "--lane-change-bias",
        type=float_in(1.0),
        default=1.0,
        help="with --choice expected or maneuver: a lane change's probability mass is multiplied by "
        "this (>= 1) before the maneuver is chosen (calibrated on a reward's training data by "
        "irlsim.reward.choice.lane_change_bias; default: 1)",
    )
    p.add_argument(
        "--commit",
        action="store_true",
        help="a learned model finishes the maneuver it chose: while the ego heads to another lane it "
        "picks among the policies that end there (unless each is a predicted collision), and once it chose "
        "to come to a stand it does not run an active stop line (default: every cycle chooses afresh, the "
        "paper's)",
    )
    p.add_argument(
        "--full-stop",
        action="store_true",
        help="a learned model never crosses an active stop line without a full stop, nor exceeds a braking "
        "curve to it, while a policy that keeps to both exists (a rule of the road; default: the reward "
        "alone decides, the paper's)",
    )
    p.add_argument(
        "--keep-distance",
        nargs="?",
        type=float_in(0.0),
        const=FOLLOW_HEADWAY,
        default=0.0,
        metavar="HEADWAY",
        help="a learned model keeps a safe following distance to the vehicle ahead: HEADWAY seconds "
        f"(alone: the expert's check, {FOLLOW_HEADWAY:g} s) plus 2 m, and room to brake to its speed at 3 "
        "m/s^2 (a vehicle braking harder than 1 m/s^2 seen braking on to a stand); where no policy does, it "
        "falls short least (a rule of the road; default: the reward alone decides, the paper's)",
    )
    p.add_argument(
        "--in-lane",
        action="store_true",
        help="with --keep-distance: the rule keeps the lane the reward chooses and picks the speed in it; "
        "a lane change only where no policy in that lane keeps the distance (default: any policy that keeps "
        "it, whatever its lane)",
    )


def request(args: argparse.Namespace) -> DriveRun:
    """The parsed arguments as the library's request (one-line errors for a bad --model list)."""
    specs = [m.strip() for m in args.model.split(",") if m.strip()]
    if not specs:
        raise IrlsimError("--model is empty: name at least one model, e.g. --model expert,PTACNN+S")
    if len(set(specs)) != len(specs):
        raise IrlsimError(f"--model names a model twice: {args.model}")
    return DriveRun(
        tuple(specs),
        args.runs,
        args.episodes,
        args.laps,
        args.seed,
        args.config,
        args.safety,
        args.out,
        args.frames,
        args.max_cycles,
        args.threads,
        args.workers,
        args.executor,
        args.address,
        args.episode_timeout,
        args.device,
        args.precision,
        args.scenario,
        reactive=args.reactive,
        choice=args.choice,
        lane_change_bias=args.lane_change_bias,
        commit=args.commit,
        full_stop=args.full_stop,
        keep_distance=args.keep_distance,
        in_lane=args.in_lane,
        overrides=tuple(args.set or ()),
    )


def run(args: argparse.Namespace) -> int:
    devices.resolve(args.device, args.precision)  # a missing device or precision: one line, before any work
    return 0 if drive_models(request(args)) is not None else 1
