"""``irlsim collect``: drive the expert in SUMO and write a Parquet dataset of policy sets and demonstrations.

Episodes run through ``irlsim.executor`` in ``--workers`` processes (one libsumo each): spawned local
workers, or Ray tasks with ``--executor ray`` (``--address`` joins a cluster whose nodes all write
``--out``). An episode that raises, whose worker dies or that runs past ``--episode-timeout`` is tried
once more; one that fails again is listed under ``"failed"`` in the manifest, the others finish, and the
command exits 1 naming it.
Every file is written under a temporary name
and renamed; an episode is finished once its cycles file exists. Killing the command at any moment leaves
only complete files, and running it again resumes by skipping finished episodes; each of those is checked
first (``check_episode``: footers, schemas, ids), and a truncated or foreign pair is deleted and collected
again. The manifest says ``"complete": false`` until the last episode is on disk.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path
from typing import Any

from irlsim import FEATURE_NAMES
from irlsim.config import MAX_SEED, float_in, int_in, load_config, parse_overrides
from irlsim.data.collection import (
    SPLITS,
    CollectConfig,
    EpisodeJob,
    collect_episode,
    data_config,
    episode_record,
    estimate_dataset_bytes,
    first_difference,
    same_driver,
)
from irlsim.data.layout import (
    check_episode,
    episode_done,
    remove_episode,
    remove_partial,
    write_manifest,
)
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.drive.closed_loop import EXPERT, EXPERT_THETA, load_drive_model
from irlsim.drive.dagger import dagger_driver_factory
from irlsim.errors import IrlsimError
from irlsim.executor import TIMED_OUT, Job, check_executor, describe_failures, run_jobs
from irlsim.outputs import check_output_dir
from irlsim.road.network import build_net
from irlsim.utils import LockBusy, check_non_negative, exclusive_lock, progress

HELP = "drive the expert and record policy sets + demonstrations to a Parquet dataset"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, default=None, help="TOML config (configs/collect/*.toml)")
    p.add_argument("--out", type=Path, required=True, help="dataset folder, e.g. data/default")
    p.add_argument(
        "--workers", type=int_in(1, 256), default=None, help="worker processes (overrides the config)"
    )
    p.add_argument("--seed", type=int_in(0, MAX_SEED), default=None, help="base seed (overrides the config)")
    add_executor_arguments(p)
    p.add_argument(
        "--driver",
        default=None,
        metavar="MODEL|CHECKPOINT",
        help="DAgger: this learned reward drives (a model name found in --runs, or a checkpoint path; "
        "argmax of its reward, as 'irlsim drive' without --safety) and the expert labels every cycle with "
        "its own choice on the same policy set (demo_source 'expert'); default: the expert drives",
    )
    p.add_argument("--runs", type=Path, default=None, help="with --driver MODEL: the runs folder holding it")
    p.add_argument(
        "--round",
        type=int,
        default=None,
        help="with --driver: the DAgger round r >= 1 (default 1); its episode seeds are seed * 1e6 + "
        "300,000 + 30,000 (r - 1) + 10,000 x split index + i, disjoint from every expert dataset's",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a config field, e.g. --set planner.n_policies=500 (repeatable)",
    )


#: the default --episode-timeout: EPISODE_START_S for the worker's start and set-up (imports, SUMO,
#: loading models, drive's pictures) plus EPISODE_SIM_FACTOR x the episode's simulated time limit.
#: Measured on 2 cores: collection runs 13x faster than real time (67 cycles/s of 0.2 s, 2,500
#: policies), the expert's 2-lap drive of default.toml 5.8x (327 s simulated in 56 s, under a load of
#: 4): its default limit, 1,800 s (max_time 600 s), is 32x that; the collection's, 920 s, ~75x
EPISODE_START_S = 600.0
EPISODE_SIM_FACTOR = 2.0


def default_episode_timeout(scenario: Any, max_cycles: int) -> float:
    """Seconds: ``EPISODE_START_S`` + ``EPISODE_SIM_FACTOR`` x the simulated seconds an episode can last
    (``scenario.max_time``, or ``max_cycles`` planning cycles when that is shorter; 0: no cap)."""
    sim_s = scenario.max_time
    if max_cycles > 0:
        sim_s = min(sim_s, max_cycles * scenario.cycle)
    return EPISODE_START_S + EPISODE_SIM_FACTOR * sim_s


def episode_timeout(
    asked: float | None, executor: str, workers: int, scenario: Any, max_cycles: int
) -> float | None:
    """The limit the executor gets: ``--episode-timeout`` when given, else the default; None (no limit)
    for ``--workers 1`` with the local executor and no ``--episode-timeout``, whose episodes run in this
    process (which cannot be stopped safely; with the option they run in one worker process)."""
    if asked is not None:
        return asked
    if executor == "local" and workers == 1:
        return None
    return default_episode_timeout(scenario, max_cycles)


def timeout_advice(failed: dict[str, str]) -> str:
    """What to add to the failure line when an episode ran out of time (it may only be slow)."""
    if any(reason.startswith(TIMED_OUT) for reason in failed.values()):
        return " (an episode that is only slow needs a larger --episode-timeout)"
    return ""


def add_executor_arguments(p: argparse.ArgumentParser) -> None:
    """``--executor``, ``--address`` and ``--episode-timeout`` (collect and drive)."""
    p.add_argument(
        "--executor",
        choices=("local", "ray"),
        default="local",
        help="where episodes run: 'local' spawned worker processes (default) or 'ray' tasks (needs the "
        "ray extra: pip install -e '.[ray]'); the outputs are the same bytes either way",
    )
    p.add_argument(
        "--address",
        default=None,
        help="with --executor ray: 'auto' or host:port joins a running Ray cluster (default: start a "
        "local Ray of --workers CPUs); every node must be able to write --out (a shared folder)",
    )
    p.add_argument(
        "--episode-timeout",
        type=float_in(0, above=True),
        default=None,
        metavar="SECONDS",
        help="wall-clock limit of one episode in a worker process (> 0): a worker that has not returned "
        "by then (stopped, deadlocked) is killed and the episode tried once more, then listed as failed "
        f"(exit 1) like a dead worker's. Default: {EPISODE_START_S:g} s + {EPISODE_SIM_FACTOR:g} x the "
        "episode's simulated time limit (scenario.max_time, or max_cycles x scenario.cycle when shorter: "
        "920 s for configs/collect/default.toml); with Ray counted from the task's submission. The local "
        "executor's --workers 1 runs in this process, which cannot be timed out: there a limit applies "
        "only when given, and then the episodes run in one worker process",
    )


#: held by the running collect for its whole run, so two never write into one dataset folder
LOCK_NAME = ".lock"


def _run_job(job):  # top level: picklable for spawn workers and Ray tasks
    if job.driver is None:
        return collect_episode(job)
    return collect_episode(job, dagger_driver_factory(job.driver, job.config.planner.n_policies))


def driver_identity(spec: str, runs: Path | None, n_policies: int) -> dict[str, Any]:
    """Resolve ``--driver`` (refused in one line when it is no learned model, not found or built for
    another policy count) and say what identifies it in the manifest: model, checkpoint path and sha256,
    and the identity of the dataset it was trained on."""
    if spec in (EXPERT, EXPERT_THETA):
        raise IrlsimError(
            f"--driver {spec}: DAgger needs a trained model (a name in --runs or a checkpoint path); the "
            "expert's own data is 'irlsim collect' without --driver"
        )
    model = load_drive_model(spec, runs, n_policies)
    assert model.checkpoint is not None and model.predictor is not None
    path = model.checkpoint.resolve()
    ck = model.predictor.loaded.checkpoint  # type: ignore[attr-defined]
    return {
        "model": model.name,
        "checkpoint": str(path),
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
        "trained_on": ck.get("dataset"),
    }


def run(args: argparse.Namespace) -> int:

    overrides = parse_overrides(args.set)
    if args.workers is not None:
        if args.workers < 1:
            raise IrlsimError(f"--workers must be >= 1, got {args.workers}")
        overrides["workers"] = args.workers
    if args.seed is not None:
        check_non_negative("seed", args.seed)
        overrides["seed"] = args.seed
    if args.driver is None and (args.round is not None or args.runs is not None):
        raise IrlsimError("--round and --runs belong to a DAgger collection: add --driver MODEL|CHECKPOINT")
    if args.driver is not None:
        if args.round is not None and args.round < 1:
            raise IrlsimError(f"--round must be >= 1 (the DAgger round), got {args.round}")
        overrides["dagger_round"] = args.round if args.round is not None else 1
    cfg = load_config(CollectConfig, args.config, overrides)
    if cfg.dagger_round and args.driver is None:
        raise IrlsimError(
            f"dagger_round = {cfg.dagger_round} needs a learned driver: add --driver MODEL|CHECKPOINT"
        )
    driver = (
        driver_identity(args.driver, args.runs, cfg.planner.n_policies) if args.driver is not None else None
    )
    check_executor(args.executor, cfg.workers, args.address)
    timeout = episode_timeout(args.episode_timeout, args.executor, cfg.workers, cfg.scenario, cfg.max_cycles)
    out: Path = args.out
    # before any work: a folder that takes files, with disk for the dataset (irlsim.outputs)
    check_output_dir(out, "--out", estimate_dataset_bytes(cfg))
    try:
        with exclusive_lock(out / LOCK_NAME):
            return _collect(cfg, out, args.executor, args.address, driver, timeout)
    except LockBusy as busy:
        raise IrlsimError(
            f"another 'irlsim collect' is writing {out} (pid {busy.holder}): wait for it or stop it"
        ) from None


def _check_resumable(
    manifest_path: Path, config: dict[str, Any], driver: dict[str, Any] | None = None
) -> dict[str, Any] | None:
    """Refuse to add to a dataset of another schema version, feature set or data config (one line);
    returns the driver as recorded there (the same by content: its path may differ)."""

    out = manifest_path.parent
    fix = f"choose another --out or delete {out}"
    try:
        old = json.loads(manifest_path.read_text())
    except (OSError, ValueError):
        old = None
    if not isinstance(old, dict) or not isinstance(old.get("config"), dict):
        raise IrlsimError(f"{manifest_path} is corrupt: delete it and re-run the same command")
    version = old.get("schema_version")
    if version != SCHEMA_VERSION:
        raise IrlsimError(
            f"{out} holds a dataset of schema version {version}, this irlsim writes {SCHEMA_VERSION}: {fix}"
        )
    if old.get("feature_names") != list(FEATURE_NAMES):
        raise IrlsimError(f"{out} holds a dataset of other features than this irlsim computes: {fix}")
    diff = first_difference(data_config(old["config"]), config)
    if diff is None and not same_driver(old.get("driver"), driver):
        was, now = (
            d["checkpoint"] + " " + d["sha256"][:12] if d else "the expert"
            for d in (old.get("driver"), driver)
        )
        diff = ("driver", was, now)
    if diff is not None:
        key, was, now = diff
        raise IrlsimError(
            f"{out} was collected with another config ({key} = {was!r} there, {now!r} now): {fix}"
        )
    return old.get("driver")


def _pending_jobs(cfg: Any, out: Path, ckpt: str | None = None) -> tuple[list[Any], dict[str, list[int]]]:
    """The episodes still to collect (executor jobs) and every split's seeds; a finished episode whose
    files fail the check is deleted and collected again."""
    jobs: list[Any] = []
    seeds: dict[str, list[int]] = {}
    vouched = (out / "manifest.json").is_file()  # checked against this config: older files without a record
    for split in SPLITS:
        remove_partial(out, split)
        seeds[split] = [s for _, s in cfg.episodes(split)]
        for episode, seed in cfg.episodes(split):
            if episode_done(out, split, episode):
                # a finished episode is trusted only after a look at its files: a truncated or foreign
                # pair would otherwise be kept, and break the manifest's counts or a later reader
                problem = check_episode(
                    out,
                    split,
                    episode,
                    n_policies=cfg.planner.n_policies,
                    n_control_points=cfg.planner.n_control_points,
                    record=episode_record(seed, cfg),  # a file of another seed or config: collected again
                    unrecorded_ok=vouched,
                )
                if problem is None:
                    continue
                print(f"collect: {problem}: collecting {split} episode {episode} again", file=sys.stderr)
                remove_episode(out, split, episode)
            # an absolute path: a Ray worker runs in a folder of its own
            job = EpisodeJob(str(out.resolve()), split, episode, seed, cfg, ckpt)  # ckpt: DAgger's driver
            jobs.append(Job(f"{split}/{episode}", job))
    return jobs, seeds


def _report_failures(
    cfg: Any,
    out: Path,
    config: dict[str, Any],
    seeds: dict[str, list[int]],
    failed: dict[str, str],
    total: int,
    ident: dict[str, Any] | None = None,
) -> int:
    """Episodes that failed twice: the manifest lists the finished ones and the failed ones and stays
    incomplete (readers refuse it); one line names them; the same command collects just those, as it
    resumes any other incomplete collection. Returns the exit status 1."""
    done = {s: [e for e, _ in cfg.episodes(s) if episode_done(out, s, e)] for s in SPLITS}
    write_manifest(
        out,
        {
            "config": config,
            **(ident or {}),
            "seeds": seeds,
            "splits": done,
            "complete": False,
            "failed": failed,
        },
    )
    print(
        f"irlsim: error: collect: {len(failed)} of {total} episodes failed twice: "
        f"{describe_failures(failed)}; the other episodes are in {out}: re-run the same "
        f"command to collect the failed ones{timeout_advice(failed)}",
        file=sys.stderr,
    )
    return 1


def _collect(
    cfg: Any,
    out: Path,
    executor: str = "local",
    address: str | None = None,
    driver: dict[str, Any] | None = None,
    timeout: float | None = None,
) -> int:
    """The collection itself, run while this process holds ``<out>/.lock``. ``driver``: the learned
    driver's identity (:func:`driver_identity`) for a DAgger collection, recorded in the manifest;
    ``timeout``: the executor's limit per episode attempt (:func:`episode_timeout`)."""

    manifest_path = out / "manifest.json"
    config = data_config(cfg)
    recorded = driver  # as the manifest records it: the first collection's, which the identity hashes
    if manifest_path.is_file():
        recorded = _check_resumable(manifest_path, config, driver)
    build_net()  # once, before the workers start (they only read it)

    jobs, seeds = _pending_jobs(cfg, out, driver["checkpoint"] if driver is not None else None)
    total = sum(len(v) for v in seeds.values())
    where = f"{cfg.workers} worker(s)" + (" as Ray tasks" if executor == "ray" else "")
    where += f", at most {timeout:g} s per episode" if timeout is not None else ", in this process"
    if driver is not None:
        where += f", {driver['model']} drives and the expert labels (DAgger round {cfg.dagger_round})"
    ident = {"driver": recorded} if driver is not None else {}
    print(f"collect: {total} episodes ({total - len(jobs)} already done), {where} -> {out}", flush=True)
    if jobs or not manifest_path.is_file():
        # marked incomplete until the last episode is on disk, so no reader takes a partial dataset for
        # a small one; it lists the config, so a re-run with another config is refused
        write_manifest(
            out,
            {"config": config, **ident, "seeds": seeds, "splits": {s: [] for s in SPLITS}, "complete": False},
        )

    t0 = time.perf_counter()
    cycles = 0
    bar = progress(total=len(jobs), desc="episodes", unit="ep")

    def on_result(job: Any, stats: dict[str, Any]) -> None:
        nonlocal cycles
        cycles += stats["collect/cycles"]
        bar.update(1)
        bar.set_postfix(cycles=cycles, rate=f"{cycles / (time.perf_counter() - t0):.1f}/s")

    def on_retry(job: Any, reason: str) -> None:
        bar.write(f"collect: episode {job.key} failed ({reason}): trying it once more", file=sys.stderr)

    try:
        result = run_jobs(
            _run_job,
            jobs,
            executor=executor,
            workers=cfg.workers,
            address=address,
            on_result=on_result,
            on_retry=on_retry,
            timeout=timeout,
        )
    finally:
        bar.close()
    for split in SPLITS:  # what a killed worker left behind (no job runs now)
        remove_partial(out, split)
    if result.failed:
        return _report_failures(cfg, out, config, seeds, result.failed, total, ident)
    splits = {s: [e for e, _ in cfg.episodes(s)] for s in SPLITS}
    manifest = write_manifest(
        out, {"config": config, **ident, "seeds": seeds, "splits": splits, "complete": True}
    )
    wall = time.perf_counter() - t0
    if jobs:
        print(f"collect: {cycles} cycles in {wall:.1f} s ({cycles / max(wall, 1e-9):.1f} cycles/s in total)")
    print(f"wrote {out}/<split>/episode_*.{{cycles,policies}}.parquet and {manifest}")
    print(f"inspect with: irlsim data info {out}")
    return 0
