"""``irlsim drive``: closed-loop driving in SUMO with the expert and learned rewards, side by side.

Every model drives the same seeds (episode i uses seed S + i). Writes ``<out>/drive.json`` (every episode
and a summary per model) and ``<out>/drive.md`` (the side-by-side table), atomically, and for the first
episode of each model the pictures ``<out>/<model>/cycle_XXXX.png``, ``radar_XXXX.png``,
``temporal_XXXX.png`` and ``episode.gif``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from irlsim.config import MAX_SEED, int_in, load_config
from irlsim.data.collection import CollectConfig
from irlsim.drive.closed_loop import PictureSpec, drive_episode, load_drive_model
from irlsim.drive.metrics import markdown_table, summarize
from irlsim.drive.scorecard import scorecard_table
from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_dir
from irlsim.road import load_road
from irlsim.utils import atomic_write_text, write_json

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
        "alone, argmax V), LIRL, 1DCNN, Bi1DCNN, PACNN, PACNN+S, PTACNN, PTACNN+S or checkpoint paths "
        "(default: expert)",
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
        "--safety",
        action="store_true",
        help="learned models drop policies labelled collision / off-road / exit (model-based check)",
    )
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


# size-ok: checks, the episode pool and the tables of one command (the executor of issue 14 takes the pool)
def run(args: argparse.Namespace) -> int:

    for name in ("episodes", "laps"):
        if getattr(args, name) < 1:
            raise IrlsimError(f"--{name} must be >= 1, got {getattr(args, name)}")
    for name in ("seed", "frames", "max_cycles"):
        if getattr(args, name) < 0:
            raise IrlsimError(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    specs = [m.strip() for m in args.model.split(",") if m.strip()]
    if not specs:
        raise IrlsimError("--model is empty: name at least one model, e.g. --model expert,PTACNN+S")
    if len(set(specs)) != len(specs):
        raise IrlsimError(f"--model names a model twice: {args.model}")
    # the scorecard's progress term compares every model with the expert on the same seed: the expert
    # drives first when --model names it; without it progress is null (left out of the score)
    if "expert" in specs:
        specs = ["expert"] + [s for s in specs if s != "expert"]
    else:
        print("note: --model has no expert, so the scorecard's progress is null (add expert to measure it)")
    cfg = load_config(CollectConfig, args.config)
    out = args.out or ((args.runs / "drive") if args.runs else Path("runs/drive"))
    if args.seed + args.episodes - 1 > MAX_SEED:
        raise IrlsimError(
            f"--seed {args.seed} + --episodes {args.episodes} passes the largest seed {MAX_SEED}"
        )
    check_output_dir(out, "--out")  # before driving: the tables are written after every episode
    # resolve every model before driving, so a typo fails in a second, not after the expert's episodes
    models = [load_drive_model(s, args.runs, cfg.planner.n_policies, args.threads) for s in specs]
    road = load_road()

    episodes, summaries = [], []
    expert_runs: dict[int, tuple[list[float], list[float]]] = {}  # seed -> the expert's (t, s)
    for model, spec in zip(models, specs, strict=True):
        folder = out / _folder(model.name if not model.checkpoint or spec == model.name else spec)
        recs, times = [], []
        for i in range(args.episodes):
            pics = PictureSpec(folder, frames=args.frames) if i == 0 and args.frames > 0 else None
            rec = drive_episode(
                model,
                road,
                cfg,
                args.seed + i,
                args.laps,
                episode=i,
                safety=args.safety,
                pictures=pics,
                max_cycles=args.max_cycles,
                expert_progress=expert_runs.get(args.seed + i),
            )
            times += rec.pop("_inference_ms")
            progress = rec.pop("_progress")
            if model.is_expert:
                expert_runs[args.seed + i] = progress
            recs.append(rec)
            print(f"{model.name} episode {i} (seed {args.seed + i}): {_line(rec)}", flush=True)
        episodes += recs
        summaries.append(summarize(recs, times))

    table = markdown_table(summaries)
    scores = scorecard_table(summaries)
    safety = "with" if args.safety else "without"
    md = (
        f"# Closed-loop driving\n\n{args.episodes} episode(s) per model, {args.laps} lap(s) each, seeds "
        f"{args.seed}..{args.seed + args.episodes - 1}; learned models {safety} the model-based safety "
        "filter; "
        f"{cfg.planner.n_policies} policies per cycle.\n\n{table}\n"
        "stop compliance: stop lines crossed after a full stop / crossed; checkpoints in lane: passed in the "
        "required lane / passed; RMS jerk of the executed odometry; inference: reward prediction per 0.2 s "
        "cycle (the expert: its model-based selection).\n\n"
        "## Scorecard (nuPlan-style, means over episodes)\n\n"
        f"{scores}\n"
        "score = 100 x no collision x no exit x stop lines x drivable area x making progress x the weighted "
        "mean of TTC >= 0.95 s (5), progress against the expert on the same seed (5), speed limit (4), "
        "comfort (2) and mission (4); every formula is in the README (section Closed-loop scorecard). "
        "Progress needs the expert's episode on the same seed: without expert in --model it is null ('-') "
        "and the score is the weighted mean of the other terms.\n"
    )
    write_json(
        out / "drive.json",
        {
            "config": {
                "models": specs,
                "episodes": args.episodes,
                "laps": args.laps,
                "seed": args.seed,
                "safety": args.safety,
                "config_file": str(args.config) if args.config else None,
                "n_policies": cfg.planner.n_policies,
                "max_cycles": args.max_cycles,
            },
            "summary": summaries,
            "episodes": episodes,
        },
    )
    atomic_write_text(out / "drive.md", md)
    print()
    print(table, end="")
    print()
    print(scores, end="")
    print(
        f"wrote {out}/drive.json, {out}/drive.md"
        + (
            f"; pictures in {out}/<model>/ (cycle_*.png, radar_*.png, temporal_*.png, episode.gif)"
            if args.frames
            else ""
        )
    )
    return 0


def _folder(name: str) -> str:
    """A model's picture folder: its registry name, or a checkpoint path's parent folder name."""
    p = Path(name)
    return p.parent.name if p.suffix == ".pt" else name


def _line(rec: dict) -> str:
    sc = f"{rec['drive/stop_lines_compliant']}/{rec['drive/stop_lines_passed']}"
    cp = f"{rec['drive/checkpoints_in_lane']}/{rec['drive/checkpoints_passed']}"
    return (
        f"{rec['drive/end_reason']}, laps {rec['drive/laps']}, collisions {rec['drive/collisions']}, "
        f"exits {rec['drive/exits']}, stops {sc}, checkpoints {cp}, {rec['drive/mean_speed_kmh']:.1f} km/h"
    )
