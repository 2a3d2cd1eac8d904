"""``irlsim drive``: closed-loop driving in SUMO with the expert and learned rewards, side by side.

Every model drives the same seeds (episode i uses seed S + i). Episodes run through ``irlsim.executor``
(``--workers N`` processes, or Ray tasks with ``--executor ray``; each episode within
``--episode-timeout``); results are put back in model and episode order, so drive.json is the same for
any worker count (wall-clock figures aside).
Writes ``<out>/drive.json`` (every episode
and a summary per model) and ``<out>/drive.md`` (the side-by-side table), atomically, and for the first
episode of each model the pictures ``<out>/<model>/cycle_XXXX.png``, ``radar_XXXX.png``,
``temporal_XXXX.png`` and ``episode.gif``.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from irlsim import devices
from irlsim.config import MAX_SEED, int_in, load_config
from irlsim.data.collection import CollectConfig
from irlsim.drive.closed_loop import PictureSpec, drive_episode, load_drive_model
from irlsim.drive.metrics import markdown_table, summarize
from irlsim.drive.scorecard import scorecard_table
from irlsim.errors import IrlsimError
from irlsim.executor import Job, check_executor, describe_failures, run_jobs
from irlsim.outputs import check_output_dir
from irlsim.road import load_road
from irlsim.utils import atomic_write_text, owned_output, write_json
from pipelines.collect import add_executor_arguments, episode_timeout, timeout_advice

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
    p.add_argument(
        "--workers",
        type=int_in(1, 256),
        default=1,
        help="episodes driven in parallel processes, one libsumo each (default: 1, in this process, "
        "without a time limit unless --episode-timeout is given); drive.json is the same for any count",
    )
    add_executor_arguments(p)
    devices.add_arguments(p, "reward inference")


@dataclass(frozen=True)
class DriveJob:
    """One closed-loop episode of one model: what a worker process needs to drive it."""

    spec: str  # a model name or an absolute checkpoint path
    runs: str | None  # absolute
    cfg: Any  # CollectConfig
    seed: int
    laps: int
    episode: int
    safety: bool
    pictures: Any  # PictureSpec | None (absolute folder)
    max_cycles: int
    threads: int
    device: str = "cpu"
    precision: str = "fp32"
    expert_progress: Any = None  # the expert's (t, s) on the same seed, for the scorecard


#: per process: models and the road, loaded once by the first episode that needs them
_MODELS: dict[tuple[Any, ...], Any] = {}
_ROAD: list[Any] = []


def _model_key(spec: str, runs: str | None, n_policies: int, threads: int) -> tuple[Any, ...]:
    return (spec, runs, n_policies, threads, devices.current())


def _drive_job(job: DriveJob) -> dict[str, Any]:  # top level: picklable for worker processes and Ray
    with devices.use(job.device, job.precision):
        return _drive(job)


def _drive(job: DriveJob) -> dict[str, Any]:
    key = _model_key(job.spec, job.runs, job.cfg.planner.n_policies, job.threads)
    if key not in _MODELS:
        _MODELS[key] = load_drive_model(job.spec, job.runs, job.cfg.planner.n_policies, job.threads)
    if not _ROAD:
        _ROAD.append(load_road())
    return drive_episode(
        _MODELS[key],
        _ROAD[0],
        job.cfg,
        job.seed,
        job.laps,
        episode=job.episode,
        safety=job.safety,
        pictures=job.pictures,
        max_cycles=job.max_cycles,
        expert_progress=job.expert_progress,
    )


# size-ok: checks, the episode pool and the tables of one command (the executor of issue 14 takes the pool)
def run(args: argparse.Namespace) -> int:
    device = devices.resolve_device(args.device)  # a missing device is one line, before any work
    with devices.use(device, args.precision):
        return _run(args, str(device))


def _episode_jobs(
    args: argparse.Namespace,
    models: list[Any],
    specs: list[str],
    cfg: Any,
    out: Path,
    runs: str | None,
    device: str,
) -> tuple[list[Any], list[str]]:
    """One executor job per (model, episode), and each model's label in the job keys (``label/i``)."""
    jobs: list[Any] = []
    labels: list[str] = []
    for model, spec in zip(models, specs, strict=True):
        folder = (out / _folder(model.name if not model.checkpoint or spec == model.name else spec)).resolve()
        label = model.name if spec == model.name else spec
        labels.append(label)
        # a checkpoint path is made absolute: a Ray worker runs in a folder of its own
        job_spec = spec if (model.checkpoint is None or spec == model.name) else str(Path(spec).resolve())
        for i in range(args.episodes):
            pics = PictureSpec(folder, frames=args.frames) if i == 0 and args.frames > 0 else None
            if job_spec != spec:
                _MODELS[_model_key(job_spec, runs, cfg.planner.n_policies, args.threads)] = model
            job = DriveJob(
                job_spec,
                runs,
                cfg,
                args.seed + i,
                args.laps,
                i,
                args.safety,
                pics,
                args.max_cycles,
                args.threads,
                device,
                args.precision,
            )
            jobs.append(Job(f"{label}/{i}", job))

    return jobs, labels


def _write_outputs(
    args: argparse.Namespace,
    specs: list[str],
    cfg: Any,
    out: Path,
    summaries: list[dict[str, Any]],
    episodes: list[dict[str, Any]],
    device: str,
) -> None:
    """drive.json and drive.md (atomically), and the table on stdout."""
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
                "device": device,
                "precision": args.precision,
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


def _run(args: argparse.Namespace, device: str) -> int:

    specs = [m.strip() for m in args.model.split(",") if m.strip()]
    if not specs:
        raise IrlsimError("--model is empty: name at least one model, e.g. --model expert,PTACNN+S")
    if len({_folder(s) for s in specs}) != len(specs):  # a checkpoint named twice, relative and absolute
        raise IrlsimError(f"--model names a model twice: {args.model}")
    if args.seed + args.episodes - 1 > MAX_SEED:
        raise IrlsimError(
            f"--seed {args.seed} + --episodes {args.episodes} passes the largest seed {MAX_SEED}"
        )
    # the scorecard's progress term compares every model with the expert on the same seed: the expert
    # drives first when --model names it; without it progress is null (left out of the score)
    if "expert" in specs:
        specs = ["expert"] + [s for s in specs if s != "expert"]
    else:
        print("note: --model has no expert, so the scorecard's progress is null (add expert to measure it)")
    check_executor(args.executor, args.workers, args.address)
    cfg = load_config(CollectConfig, args.config)
    out = args.out or ((args.runs / "drive") if args.runs else Path("runs/drive"))
    check_output_dir(out, "--out")  # before driving: the tables are written after every episode
    # resolve every model before driving, so a typo fails in a second, not after the expert's episodes
    models = [load_drive_model(s, args.runs, cfg.planner.n_policies, args.threads) for s in specs]
    _check_seeds_unseen(models, args.seed, args.episodes)
    runs = str(args.runs.resolve()) if args.runs else None
    for model, spec in zip(models, specs, strict=True):  # the episodes in this process reuse them
        _MODELS[_model_key(spec, runs, cfg.planner.n_policies, args.threads)] = model

    with owned_output(out, "drive"):  # one command writes an --out at a time; pictures come first
        return _drive_into(args, models, specs, cfg, out, runs, device)


def _drive_into(
    args: argparse.Namespace, models: list[Any], specs: list[str], cfg: Any, out: Path, runs: Any, device: str
) -> int:
    """The episodes, pictures and tables, while this process holds ``<out>/.lock``."""
    jobs, labels = _episode_jobs(args, models, specs, cfg, out, runs, device)
    limit = episode_timeout(args.episode_timeout, args.executor, args.workers, cfg.scenario, args.max_cycles)
    results = _drive_jobs(args, jobs, out, limit)
    if results is None:
        return 1
    # in model and episode order, whatever order they finished in: the same JSON for any --workers
    episodes, summaries = [], []
    for label in labels:
        recs, times = [], []
        for i in range(args.episodes):
            rec = dict(results[f"{label}/{i}"])
            # a checkpoint path is its own label: two checkpoints of one model never share a row's name
            rec["drive/model"] = label
            times += rec.pop("_inference_ms")
            rec.pop("_progress")
            recs.append(rec)
        episodes += recs
        summaries.append(summarize(recs, times))

    _write_outputs(args, specs, cfg, out, summaries, episodes, device)
    return 0


def _check_seeds_unseen(models: list[Any], seed: int, episodes: int) -> None:
    """Refuse (one line) episode seeds seed..seed+episodes-1 that are seeds of the dataset a learned model
    was trained on (any split: train, validation or test), read from its checkpoint's ``dataset_seeds``.
    Checkpoints without them (trained on an in-memory dataset) are not checked."""
    asked = set(range(seed, seed + episodes))
    for model in models:
        loaded = getattr(model.predictor, "loaded", None)
        trained = set(loaded.checkpoint.get("dataset_seeds") or ()) if loaded is not None else set()
        if (
            loaded is not None
            and loaded.checkpoint.get("dataset")
            and loaded.checkpoint.get("dataset_seeds") is None
        ):
            print(
                f"note: {model.name} records no training seeds (trained before they were recorded): "
                "its seeds are not checked; retrain it to have them refused",
                file=sys.stderr,
            )
        overlap = sorted(asked & trained)
        if overlap:
            shown = ", ".join(map(str, sorted(trained)[:8])) + (", ..." if len(trained) > 8 else "")
            raise IrlsimError(
                f"--seed {seed} --episodes {episodes}: episode seed(s) {', '.join(map(str, overlap[:5]))} "
                f"are seeds of the data {model.name} was trained on ({shown}): evaluate on unseen seeds, "
                "choose another --seed"
            )


def _drive_jobs(
    args: argparse.Namespace, jobs: list[Any], out: Path, timeout: float | None = None
) -> dict[str, Any] | None:
    """Run the episode jobs through the executor (``timeout``: its limit per episode attempt): the
    expert's first (their progress curves are the scorecard's reference on each seed), then every other
    model's with the expert's curve of its seed. Returns key -> episode record, or None (after one line
    on stderr) when an episode failed twice."""

    def on_result(job: Any, rec: dict[str, Any]) -> None:
        name, i = job.key.rsplit("/", 1)
        print(f"{name} episode {i} (seed {args.seed + int(i)}): {_line(rec)}", flush=True)

    def on_retry(job: Any, reason: str) -> None:
        print(f"drive: episode {job.key} failed ({reason}): trying it once more", file=sys.stderr, flush=True)

    expert = [j for j in jobs if j.key.rsplit("/", 1)[0] == "expert"]
    phases = [expert, [j for j in jobs if j not in expert]]
    results: dict[str, Any] = {}
    for phase in phases:
        if not phase:
            continue
        if phase is phases[1] and expert:
            progress = {results[j.key]["drive/seed"]: results[j.key]["_progress"] for j in expert}
            phase = [Job(j.key, replace(j.arg, expert_progress=progress.get(j.arg.seed))) for j in phase]
        result = run_jobs(
            _drive_job,
            phase,
            executor=args.executor,
            workers=args.workers,
            address=args.address,
            on_result=on_result,
            on_retry=on_retry,
            timeout=timeout,
        )
        if result.failed:
            print(
                f"irlsim: error: drive: {len(result.failed)} of {len(jobs)} episodes failed twice: "
                f"{describe_failures(result.failed)}; nothing written to {out}/drive.json"
                f"{timeout_advice(result.failed)}",
                file=sys.stderr,
            )
            return None
        results.update(result.results)
    return results


def _folder(name: str) -> str:
    """A model's picture folder: its registry name, or a checkpoint path as one folder name: its parts
    joined by '_' for reading and the first 10 hex digits of the sha256 of its resolved path (e.g.
    runs_a_stage1_PACNN+S_checkpoint.pt-3f0c9a1b2d), so two checkpoints (x_y/checkpoint.pt and
    x/y/checkpoint.pt), or a checkpoint and the registry model of that name, never share a folder, and
    one file named two ways (relative, absolute) draws into one."""
    p = Path(name)
    if p.suffix != ".pt" and "/" not in name:
        return name
    readable = "_".join(part for part in p.parts if part not in ("/", "..", ".")) or p.name
    return f"{readable}-{hashlib.sha256(str(p.resolve()).encode()).hexdigest()[:10]}"


def _line(rec: dict) -> str:
    sc = f"{rec['drive/stop_lines_compliant']}/{rec['drive/stop_lines_passed']}"
    cp = f"{rec['drive/checkpoints_in_lane']}/{rec['drive/checkpoints_passed']}"
    return (
        f"{rec['drive/end_reason']}, laps {rec['drive/laps']}, collisions {rec['drive/collisions']}, "
        f"exits {rec['drive/exits']}, stops {sc}, checkpoints {cp}, {rec['drive/mean_speed_kmh']:.1f} km/h"
    )
