"""``irlsim collect``: drive the expert in SUMO and write a Parquet dataset of policy sets and demonstrations.

Episodes run in ``--workers`` processes (one libsumo each). Every file is written under a temporary name
and renamed; an episode is finished once its cycles file exists. Killing the command at any moment leaves
only complete files, and running it again resumes by skipping finished episodes; each of those is checked
first (``check_episode``: footers, schemas, ids), and a truncated or foreign pair is deleted and collected
again. The manifest says ``"complete": false`` until the last episode is on disk.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from irlsim import FEATURE_NAMES
from irlsim.config import MAX_SEED, int_in, load_config, parse_overrides
from irlsim.data.collection import (
    SPLITS,
    CollectConfig,
    EpisodeJob,
    collect_episode,
    data_config,
    estimate_dataset_bytes,
    first_difference,
)
from irlsim.data.layout import (
    check_episode,
    episode_done,
    remove_episode,
    remove_partial,
    write_manifest,
)
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_dir
from irlsim.road.network import build_net
from irlsim.utils import LockBusy, check_non_negative, exclusive_lock, progress, spawn_pool

HELP = "drive the expert and record policy sets + demonstrations to a Parquet dataset"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", type=Path, default=None, help="TOML config (configs/collect/*.toml)")
    p.add_argument("--out", type=Path, required=True, help="dataset folder, e.g. data/default")
    p.add_argument(
        "--workers", type=int_in(1, 256), default=None, help="worker processes (overrides the config)"
    )
    p.add_argument("--seed", type=int_in(0, MAX_SEED), default=None, help="base seed (overrides the config)")
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a config field, e.g. --set planner.n_policies=500 (repeatable)",
    )


#: held by the running collect for its whole run, so two never write into one dataset folder
LOCK_NAME = ".lock"


def _run_job(job):  # top level: picklable for spawn workers

    return collect_episode(job)


def run(args: argparse.Namespace) -> int:

    overrides = parse_overrides(args.set)
    if args.workers is not None:
        if args.workers < 1:
            raise IrlsimError(f"--workers must be >= 1, got {args.workers}")
        overrides["workers"] = args.workers
    if args.seed is not None:
        check_non_negative("seed", args.seed)
        overrides["seed"] = args.seed
    cfg = load_config(CollectConfig, args.config, overrides)
    out: Path = args.out
    # before any work: a folder that takes files, with disk for the dataset (irlsim.outputs)
    check_output_dir(out, "--out", estimate_dataset_bytes(cfg))
    try:
        with exclusive_lock(out / LOCK_NAME):
            return _collect(cfg, out)
    except LockBusy as busy:
        raise IrlsimError(
            f"another 'irlsim collect' is writing {out} (pid {busy.holder}): wait for it or stop it"
        ) from None


def _check_resumable(manifest_path: Path, config: dict[str, Any]) -> None:
    """Refuse to add to a dataset of another schema version, feature set or data config (one line)."""

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
    if diff is not None:
        key, was, now = diff
        raise IrlsimError(
            f"{out} was collected with another config ({key} = {was!r} there, {now!r} now): {fix}"
        )


def _collect(cfg: Any, out: Path) -> int:
    """The collection itself, run while this process holds ``<out>/.lock``."""

    manifest_path = out / "manifest.json"
    config = data_config(cfg)
    if manifest_path.is_file():
        _check_resumable(manifest_path, config)
    build_net()  # once, before the workers start (they only read it)

    jobs, seeds = [], {}
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
                )
                if problem is None:
                    continue
                print(f"collect: {problem}: collecting {split} episode {episode} again", file=sys.stderr)
                remove_episode(out, split, episode)
            jobs.append(EpisodeJob(str(out), split, episode, seed, cfg))
    total = sum(len(v) for v in seeds.values())
    print(f"collect: {total} episodes ({total - len(jobs)} already done), {cfg.workers} worker(s) -> {out}")
    if jobs or not manifest_path.is_file():
        # marked incomplete until the last episode is on disk, so no reader takes a partial dataset for
        # a small one; it lists the config, so a re-run with another config is refused
        write_manifest(
            out,
            {"config": config, "seeds": seeds, "splits": {s: [] for s in SPLITS}, "complete": False},
        )

    t0 = time.perf_counter()
    cycles = 0
    bar = progress(total=len(jobs), desc="episodes", unit="ep")
    results: Iterator[Any]
    if cfg.workers == 1 or len(jobs) <= 1:
        results = map(_run_job, jobs)
        pool = None
    else:
        pool = spawn_pool(min(cfg.workers, len(jobs)))
        results = pool.imap_unordered(_run_job, jobs)
    try:
        for stats in results:
            cycles += stats["collect/cycles"]
            bar.update(1)
            bar.set_postfix(cycles=cycles, rate=f"{cycles / (time.perf_counter() - t0):.1f}/s")
    finally:
        bar.close()
        if pool is not None:
            pool.terminate()
            pool.join()
    splits = {s: [e for e, _ in cfg.episodes(s)] for s in SPLITS}
    manifest = write_manifest(out, {"config": config, "seeds": seeds, "splits": splits, "complete": True})
    wall = time.perf_counter() - t0
    if jobs:
        print(f"collect: {cycles} cycles in {wall:.1f} s ({cycles / max(wall, 1e-9):.1f} cycles/s in total)")
    print(f"wrote {out}/<split>/episode_*.{{cycles,policies}}.parquet and {manifest}")
    print(f"inspect with: irlsim data info {out}")
    return 0
