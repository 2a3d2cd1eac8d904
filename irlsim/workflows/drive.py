"""Closed-loop driving of several models over many episodes (``irlsim drive``): :func:`drive_models`
with :class:`DriveRun`.

Every model drives the same seeds (episode i uses seed S + i). Episodes run through ``irlsim.executor``
(``workers`` processes, or Ray tasks with executor 'ray'; each episode within the episode time limit);
results are put back in model and episode order, so drive.json is the same for any worker count
(wall-clock figures aside). Writes ``<out>/drive.json`` (every episode and a summary per model) and
``<out>/drive.md`` (the side-by-side table), atomically, and for the first episode of each model the
pictures ``<out>/<model>/cycle_XXXX.png``, ``radar_XXXX.png``, ``temporal_XXXX.png`` and ``episode.gif``.
"""

from __future__ import annotations

import hashlib
import math
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from irlsim import devices
from irlsim.config import MAX_SEED, load_config, parse_overrides
from irlsim.data.collection import CollectConfig
from irlsim.data.demonstrator import RECORDING, resolve_recording
from irlsim.drive.closed_loop import PictureSpec, drive_episode
from irlsim.drive.demonstrated import DEMONSTRATOR, check_demonstrator, resolve_model
from irlsim.drive.metrics import markdown_table, summarize
from irlsim.drive.scorecard import scorecard_table
from irlsim.errors import IrlsimError
from irlsim.executor import Job, check_executor, describe_failures, run_jobs
from irlsim.outputs import check_output_dir
from irlsim.planner.choice import CHOICES
from irlsim.road import load_road
from irlsim.road.scenario import Scenario, Scenarios, recorded_name
from irlsim.rollout.style import pool_styles, style_report
from irlsim.sim.preflight import check_starts
from irlsim.utils import atomic_write_text, owned_output, write_json
from irlsim.workflows.collect import episode_timeout, timeout_advice
from irlsim.workflows.drive_seeds import check_egos_unseen, check_seeds_unseen


@dataclass(frozen=True)
class DriveRun:
    """Closed-loop drives of several models: what ``irlsim drive`` parses its arguments into."""

    models: tuple[str, ...] = ("expert",)
    """what drives: 'expert', 'expert-theta', 'demonstrator' (the config's SUMO driver or recorded ego), model
    names found in ``runs``, or checkpoint paths"""
    runs: Path | None = None
    """the runs folder 'irlsim train --out' wrote"""
    episodes: int = 1
    """episodes per model"""
    laps: int = 1
    """laps per episode"""
    seed: int = 100
    """episode i uses seed ``seed`` + i"""
    config_file: Path | None = None
    """the collect TOML the models were trained with (None: the built-in config)"""
    safety: bool = False
    """learned models drop policies labelled collision / off-road / exit"""
    out: Path | None = None
    """output folder (None: ``<runs>/drive``, or runs/drive)"""
    frames: int = 40
    """animation frames of the first episode of each model (0: no pictures)"""
    max_cycles: int = 0
    """stop each episode after this many cycles (0: laps, collision, exit or time-out)"""
    threads: int = 1
    """torch CPU threads of the reward inference"""
    workers: int = 1
    """episodes driven in parallel processes (1: in this process)"""
    executor: str = "local"
    address: str | None = None
    episode_timeout: float | None = None
    """[s] limit of one episode attempt (None: :func:`irlsim.workflows.collect.episode_timeout`'s default)"""
    device: str = "auto"
    precision: str = "fp32"
    scenario: str | None = None
    """the road to drive (a shipped scenario or a scenario.toml path; None: the collect config's)"""
    reactive: bool = False
    """on a recording (the config's ``[demonstrator] kind = 'recording'``): SUMO drives the other
    vehicles from their first recorded pose on (False: they replay their recorded motion)"""
    choice: str = "argmax"
    """how a learned model's reward picks the policy: 'argmax' (the paper's), 'expected' (the fit's
    expected maneuver and policy) or 'maneuver' (the expected maneuver's most likely policy;
    :mod:`irlsim.planner.choice`)"""
    lane_change_bias: float = 1.0
    """the 'expected'/'maneuver' choices' lane-change bias (:func:`irlsim.reward.choice.lane_change_bias`)"""
    commit: bool = False
    """a learned model finishes the maneuver it chose (:class:`irlsim.planner.expert.ThetaDriver`)"""
    full_stop: bool = False
    """a learned model makes a full stop at every active stop line it can (a rule of the road)"""
    keep_distance: float = 0.0
    """> 0: a learned model keeps a safe following distance to the vehicle ahead, with this time headway
    [s] (a rule of the road; the expert's check: ``irlsim.planner.expert.FOLLOW_HEADWAY``)"""
    in_lane: bool = False
    """with ``keep_distance``: kept in the lane the reward chooses, where a policy there keeps it"""
    overrides: tuple[str, ...] = ()
    """config fields set over the ``config_file``'s, ``KEY=VALUE`` (as ``irlsim collect --set``)"""


@dataclass
class DriveResult:
    """What :func:`drive_models` wrote: the folder, every episode's record and a summary per model."""

    out: Path
    episodes: list[dict[str, Any]] = field(default_factory=list)
    summaries: list[dict[str, Any]] = field(default_factory=list)


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
    reactive: bool = False  # on a recording: SUMO drives the other vehicles
    road: Any = None  # the Scenario of cfg.scenario.name, read once by the command (None: read here)
    how: Any = None  # how a learned reward picks the policy: drive_episode's choice keywords (None: default)


#: per process: models and the road, loaded once by the first episode that needs them
_MODELS: dict[tuple[Any, ...], Any] = {}
_ROAD: dict[str, Any] = {}


def _model_key(spec: str, runs: str | None, n_policies: int, threads: int) -> tuple[Any, ...]:
    return (spec, runs, n_policies, threads, devices.current())


def _drive_job(job: DriveJob) -> dict[str, Any]:  # top level: picklable for worker processes and Ray
    with devices.use(job.device, job.precision):
        return _drive(job)


def _drive(job: DriveJob) -> dict[str, Any]:
    key = _model_key(job.spec, job.runs, job.cfg.planner.n_policies, job.threads)
    if key not in _MODELS:
        planner = job.cfg.planner
        _MODELS[key] = resolve_model(job.spec, job.runs, planner, job.threads)
    name = job.cfg.scenario.name
    if name not in _ROAD:
        _ROAD[name] = load_road(scenario=job.road if job.road is not None else name)
    return drive_episode(
        _MODELS[key],
        _ROAD[name],
        job.cfg,
        job.seed,
        job.laps,
        episode=job.episode,
        safety=job.safety,
        pictures=job.pictures,
        max_cycles=job.max_cycles,
        expert_progress=job.expert_progress,
        reactive=job.reactive,
        **(job.how or {}),
    )


def drive_models(run: DriveRun) -> DriveResult | None:
    """Drive every model of ``run`` over its episodes and write ``drive.json`` / ``drive.md`` (printing
    the tables); returns the episode records and summaries, or None (after one line on stderr) when an
    episode failed twice. Raises :class:`~irlsim.errors.IrlsimError` (one line) before any work for a
    missing device, an unknown model, seeds the models were trained on or an unusable output folder."""
    device = devices.resolve(run.device, run.precision)  # one line, before any work
    with devices.use(device, run.precision):
        return _run(run, str(device))


def _episode_jobs(
    run: DriveRun,
    models: list[Any],
    specs: list[str],
    cfg: Any,
    out: Path,
    runs: str | None,
    device: str,
    road: Scenario | None = None,
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
        for i in range(run.episodes):
            pics = PictureSpec(folder, frames=run.frames) if i == 0 and run.frames > 0 else None
            if job_spec != spec:
                _MODELS[_model_key(job_spec, runs, cfg.planner.n_policies, run.threads)] = model
            job = DriveJob(
                job_spec,
                runs,
                cfg,
                run.seed + i,
                run.laps,
                i,
                run.safety,
                pics,
                run.max_cycles,
                run.threads,
                device,
                run.precision,
                reactive=run.reactive,
                road=road,
                how=_how(run),
            )
            jobs.append(Job(f"{label}/{i}", job))

    return jobs, labels


#: the planner's rules a learned reward may drive under (DriveRun's flags), as drive.md names them
RULE_WORDS = {
    "commit": "maneuvers committed",
    "full_stop": "a full stop at every stop line",
    "keep_distance": "a safe distance to the vehicle ahead ({:g} s headway)",
    "in_lane": "in the lane the reward chooses",
}


def _how(run: DriveRun) -> dict[str, Any]:
    """:func:`drive_episode`'s keywords for how a learned reward picks its policy."""
    return {k: getattr(run, k) for k in ("choice", "lane_change_bias", *RULE_WORDS)}


def _choice_record(run: DriveRun) -> dict[str, Any]:
    """The choice in drive.json's config, left out where it is the default (records unchanged)."""
    rec = {"choice": run.choice, "lane_change_bias": run.lane_change_bias} if run.choice != "argmax" else {}
    return {**rec, **{k: getattr(run, k) for k in RULE_WORDS if getattr(run, k)}}


def _choice_words(run: DriveRun) -> str:
    words = f", choosing the {run.choice} policy (lane-change bias {run.lane_change_bias:g})"
    return (words if run.choice != "argmax" else "") + "".join(
        f", {w.format(getattr(run, k))}" for k, w in RULE_WORDS.items() if getattr(run, k)
    )


def _write_outputs(
    run: DriveRun,
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
    safety = "with" if run.safety else "without"
    own = "; the demonstrator: none, it drives as collected" if DEMONSTRATOR in specs else ""
    md = (
        f"# Closed-loop driving\n\n{run.episodes} episode(s) per model, {run.laps} lap(s) each, seeds "
        f"{run.seed}..{run.seed + run.episodes - 1}; learned models {safety} the model-based safety "
        f"filter{_choice_words(run)}; "
        f"{cfg.planner.n_policies} policies per cycle.\n\n{table}\n"
        "stop compliance: stop lines crossed after a full stop / crossed; checkpoints in lane: passed in the "
        "required lane / passed; RMS jerk of the executed odometry; inference: reward prediction per 0.2 s "
        f"cycle (the expert: its model-based selection{own}).\n\n"
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
                "episodes": run.episodes,
                "laps": run.laps,
                "seed": run.seed,
                "safety": run.safety,
                **_choice_record(run),
                "config_file": str(run.config_file) if run.config_file else None,
                "n_policies": cfg.planner.n_policies,
                "max_cycles": run.max_cycles,
                "device": device,
                "precision": run.precision,
            }
            # the road, unless it is the default (left out of records), and a recording
            | ({"scenario": name} if (name := recorded_name(cfg.scenario.name)) else {})
            | ({"set": list(run.overrides)} if run.overrides else {})
            | _recording_record(cfg, run),
            "summary": summaries,
            "episodes": episodes,
        },
    )
    atomic_write_text(out / "drive.md", md)
    print()
    print(table, end="")
    print()
    print(scores, end="")
    print(style_report(summaries, DEMONSTRATOR if DEMONSTRATOR in specs else None, episodes), end="")
    print(
        f"wrote {out}/drive.json, {out}/drive.md"
        + (
            f"; pictures in {out}/<model>/ (cycle_*.png, radar_*.png, temporal_*.png, episode.gif)"
            if run.frames
            else ""
        )
    )


def _run(run: DriveRun, device: str) -> DriveResult | None:
    specs = list(run.models)
    if not specs:
        raise IrlsimError("--model is empty: name at least one model, e.g. --model expert,PTACNN+S")
    if len({_folder(s) for s in specs}) != len(specs):  # a checkpoint named twice, relative and absolute
        raise IrlsimError(f"--model names a model twice: {','.join(specs)}")
    if run.seed + run.episodes - 1 > MAX_SEED:
        raise IrlsimError(f"--seed {run.seed} + --episodes {run.episodes} passes the largest seed {MAX_SEED}")
    if run.choice not in CHOICES:
        raise IrlsimError(f"--choice {run.choice!r} is not one of {', '.join(CHOICES)}")
    if not (math.isfinite(run.lane_change_bias) and run.lane_change_bias >= 1.0):
        raise IrlsimError(f"--lane-change-bias must be a finite number >= 1, got {run.lane_change_bias}")
    if not (math.isfinite(run.keep_distance) and run.keep_distance >= 0.0):
        raise IrlsimError(f"--keep-distance must be a finite headway >= 0 s, got {run.keep_distance}")
    if run.in_lane and not run.keep_distance > 0.0:
        raise IrlsimError("--in-lane keeps the following distance in the reward's lane: add --keep-distance")
    # the scorecard's progress term compares every model with the expert on the same seed: the expert
    # drives first when --model names it; without it progress is null (left out of the score)
    if "expert" in specs:
        specs = ["expert"] + [s for s in specs if s != "expert"]
    else:
        print("note: --model has no expert, so the scorecard's progress is null (add expert to measure it)")
    check_executor(run.executor, run.workers, run.address)
    over = parse_overrides(list(run.overrides)) | (
        {"scenario.name": str(run.scenario)} if run.scenario is not None else {}
    )
    scenarios = Scenarios()  # the road's file read once: for the config's [defaults] and every episode
    cfg = load_config(CollectConfig, run.config_file, over or None, scenarios=scenarios)
    cfg, sha256 = _recording(cfg, run, scenarios)
    check_starts(cfg.scenario, (cfg.scenario.name,), scenarios)  # a route too short for the ego's start
    out = run.out or ((run.runs / "drive") if run.runs else Path("runs/drive"))
    check_output_dir(out, "--out")  # before driving: the tables are written after every episode
    # resolve every model before driving, so a typo fails in a second, not after the expert's episodes
    if DEMONSTRATOR in specs:
        check_demonstrator(cfg)
    models = [resolve_model(s, run.runs, cfg.planner, run.threads) for s in specs]
    if cfg.demonstrator.kind == RECORDING:  # an episode is its ego; the seed picks no car
        egos = cfg.demonstrator.ego.split(",")[: run.episodes]
        check_egos_unseen(models, cfg.demonstrator.file, sha256, egos)
    else:
        check_seeds_unseen(models, run.seed, run.episodes)
    runs = str(run.runs.resolve()) if run.runs else None
    for model, spec in zip(models, specs, strict=True):  # the episodes in this process reuse them
        _MODELS[_model_key(spec, runs, cfg.planner.n_policies, run.threads)] = model
    with owned_output(out, "drive"):  # one command writes an --out at a time; pictures come first
        return _drive_into(run, models, specs, cfg, out, runs, device, scenarios(cfg.scenario.name))


def _drive_into(
    run: DriveRun,
    models: list[Any],
    specs: list[str],
    cfg: Any,
    out: Path,
    runs: str | None,
    device: str,
    road: Scenario,
) -> DriveResult | None:
    """The episodes, pictures and tables, while this process holds ``<out>/.lock``; ``road``: the
    scenario of every episode, as the command read it."""
    jobs, labels = _episode_jobs(run, models, specs, cfg, out, runs, device, road)
    limit = episode_timeout(run.episode_timeout, run.executor, run.workers, cfg.scenario, run.max_cycles)
    results = _drive_jobs(run, jobs, out, limit)
    if results is None:
        return None
    # in model and episode order, whatever order they finished in: the same JSON for any --workers
    episodes, summaries = [], []
    for label in labels:
        recs, times = [], []
        for i in range(run.episodes):
            rec = dict(results[f"{label}/{i}"])
            # a checkpoint path is its own label: two checkpoints of one model never share a row's name
            rec["drive/model"] = label
            times += rec.pop("_inference_ms")
            rec.pop("_progress")
            recs.append(rec)
        episodes += recs
        summaries.append({**summarize(recs, times), "style": pool_styles(recs)})

    _write_outputs(run, specs, cfg, out, summaries, episodes, device)
    return DriveResult(out, episodes, summaries)


def _recording(cfg: CollectConfig, run: DriveRun, scenarios: Scenarios) -> tuple[CollectConfig, str]:
    """On a recording: its egos, one per episode (read and checked in one line before any work, on the
    road ``scenarios`` has read), and the recording's sha256 ('' on no recording)."""
    if cfg.demonstrator.kind != RECORDING:
        if run.reactive:
            raise IrlsimError("--reactive drives a recording's vehicles: give a --config with a recording")
        return cfg, ""
    scenario = cfg.scenario
    road = load_road(scenario=scenarios(scenario.name))
    resolved, record = resolve_recording(cfg.demonstrator, road, scenario.step, run.episodes)
    return replace(cfg, demonstrator=resolved), str(record["sha256"])


def _recording_record(cfg: CollectConfig, run: DriveRun) -> dict[str, Any]:
    """drive.json's record of a recording: the file, the egos driven and the mode (and how the file was
    read, where not as SUMO's FCD is: its positions' point, its type files)."""
    d = cfg.demonstrator
    if d.kind != RECORDING:
        return {}
    record: dict[str, Any] = {
        "file": d.file,
        "egos": d.ego.split(",")[: run.episodes],
        "reactive": run.reactive,
    }
    record |= d.read_unlike_fcd()
    if d.vehicle_types:
        record["vehicle_types"] = list(d.vehicle_types)
    return {"recording": record}


def _drive_jobs(
    run: DriveRun, jobs: list[Any], out: Path, timeout: float | None = None
) -> dict[str, Any] | None:
    """Run the episode jobs through the executor (``timeout``: its limit per episode attempt): the
    expert's first (their progress curves are the scorecard's reference on each seed), then every other
    model's with the expert's curve of its seed. Returns key -> episode record, or None (after one line
    on stderr) when an episode failed twice."""

    def on_result(job: Any, rec: dict[str, Any]) -> None:
        name, i = job.key.rsplit("/", 1)
        print(f"{name} episode {i} (seed {run.seed + int(i)}): {_line(rec)}", flush=True)

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
            executor=run.executor,
            workers=run.workers,
            address=run.address,
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
