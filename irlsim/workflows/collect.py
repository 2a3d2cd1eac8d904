"""Collecting a dataset (``irlsim collect``): :func:`collect_dataset` with its typed :class:`CollectRun`.

The expert (or, for DAgger, a learned driver labelled by the expert or SUMO's driver) drives SUMO episodes
through ``irlsim.executor`` in ``workers`` processes (one libsumo each): spawned local workers, or Ray tasks
(``executor='ray'``; ``address`` joins a cluster whose nodes all write ``out``). An episode that raises,
whose worker dies or that runs past the episode time limit is tried once more; one that fails again is
listed under ``"failed"`` in the manifest, the others finish, and the result names it.
Every file is written under a temporary name and renamed; an episode is finished once its cycles file
exists. Killing the collection at any moment leaves only complete files, and running it again resumes by
skipping finished episodes; each of those is checked first (``check_episode``: footers, schemas, ids),
and a truncated or foreign pair is deleted and collected again. The manifest says ``"complete": false``
until the last episode is on disk. Seeds: :meth:`irlsim.data.collection.CollectConfig.episodes`.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

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
from irlsim.data.demonstrator import EXPERT as EXPERT_DEMONSTRATOR
from irlsim.data.demonstrator import describe
from irlsim.data.demonstrator import resolve as resolve_demonstrator
from irlsim.data.layout import (
    check_episode,
    episode_done,
    manifest_feature_names,
    remove_episode,
    remove_partial,
    write_manifest,
)
from irlsim.data.prune import prune_caches
from irlsim.data.reader import open_dataset
from irlsim.data.schema import SCHEMA_VERSION
from irlsim.drive.dagger import dagger_driver_factory
from irlsim.errors import IrlsimError
from irlsim.executor import TIMED_OUT, check_executor, describe_failures, run_jobs
from irlsim.executor import Job as ExecutorJob
from irlsim.outputs import check_output_dir
from irlsim.planner.config import PlannerConfig
from irlsim.reward import EXPERT, EXPERT_THETA, check_features, load_reward
from irlsim.road.scenario import Scenarios, recorded_name
from irlsim.sim.preflight import check_starts
from irlsim.utils import LockBusy, exclusive_lock, progress


@dataclass(frozen=True)
class CollectRun:
    """One collection: what ``irlsim collect`` parses its arguments into."""

    config: CollectConfig
    """the collect config (episode counts, seeds, planner, scenario, ``workers``, ``dagger_round``)"""
    out: Path
    """the dataset folder"""
    executor: str = "local"
    """'local' (spawned worker processes) or 'ray'"""
    address: str | None = None
    """with executor 'ray': 'auto' or host:port of a running cluster (None: a local Ray)"""
    episode_timeout: float | None = None
    """[s] limit of one episode attempt (None: :func:`episode_timeout`'s default)"""
    driver: str | None = None
    """DAgger: the learned driver (a model name in ``runs`` or a checkpoint path); None: the expert"""
    runs: Path | None = None
    """with ``driver`` a model name: the runs folder holding it"""
    scenarios: Scenarios = field(default_factory=Scenarios, compare=False)
    """the command's roads, each scenario file read once (the one its config was loaded with, when
    given: ``load_config(..., scenarios=)``) and handed to every episode"""


@dataclass
class CollectResult:
    """What a collection left: the dataset folder and the episodes that failed twice (key -> reason)."""

    out: Path
    failed: dict[str, str] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.failed


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


#: held by the running collect for its whole run, so two never write into one dataset folder
LOCK_NAME = ".lock"


def _run_job(job):  # top level: picklable for spawn workers and Ray tasks
    if job.driver is None:
        return collect_episode(job)
    return collect_episode(job, dagger_driver_factory(job.driver, job.config.planner.n_policies))


def driver_identity(spec: str, runs: Path | None, planner: PlannerConfig) -> dict[str, Any]:
    """Resolve ``--driver`` (refused in one line when it is no learned model, not found or built for
    another policy count or feature set than ``planner``'s) and say what identifies it in the manifest:
    model, checkpoint path and sha256, and the identity of the dataset it was trained on."""
    if spec in (EXPERT, EXPERT_THETA):
        raise IrlsimError(
            f"--driver {spec}: DAgger needs a trained model (a name in --runs or a checkpoint path); the "
            "expert's own data is 'irlsim collect' without --driver"
        )
    model = load_reward(spec, runs, n_policies=planner.n_policies)
    check_features(model, planner.feature_names)
    assert model.checkpoint is not None and model.trained is not None
    path = model.checkpoint.resolve()
    ck = model.trained
    return {
        "model": model.name,
        "checkpoint": str(path),
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
        "trained_on": ck.get("dataset"),
    }


def collect_dataset(run: CollectRun) -> CollectResult:
    """Collect (or resume) the dataset of ``run`` into ``run.out``; see the module docstring. Raises
    :class:`~irlsim.errors.IrlsimError` (one line) before any work for a config the folder was not
    collected with, a busy folder, a missing driver or an unusable output folder."""
    cfg, scenarios = run.config, run.scenarios
    cfg.check_roads(scenarios)
    # SUMO's refusal of a demonstrator's vehicle type: one line, before any work (nothing written)
    demo_record = None
    if cfg.demonstrator.kind != EXPERT_DEMONSTRATOR:
        n = cfg.train_episodes + cfg.validation_episodes + cfg.test_episodes
        roads, step = tuple(scenarios(name) for name in cfg.scenario_names), cfg.scenario.step
        demonstrator, demo_record = resolve_demonstrator(cfg.demonstrator, roads, step, n)
        cfg = replace(cfg, demonstrator=demonstrator)
    # a route too short for the ego's start: refused here; each road's network built, before any worker
    check_starts(cfg.scenario, cfg.scenario_names, scenarios)
    if cfg.dagger_round and run.driver is None:
        raise IrlsimError(
            f"dagger_round = {cfg.dagger_round} needs a learned driver: add --driver MODEL|CHECKPOINT"
        )
    driver = driver_identity(run.driver, run.runs, cfg.planner) if run.driver is not None else None
    check_executor(run.executor, cfg.workers, run.address)
    timeout = episode_timeout(run.episode_timeout, run.executor, cfg.workers, cfg.scenario, cfg.max_cycles)
    out = run.out
    # before any work: a folder that takes files, with disk for the dataset (irlsim.outputs)
    check_output_dir(out, "--out", estimate_dataset_bytes(cfg))
    try:
        with exclusive_lock(out / LOCK_NAME):
            failed = _collect(cfg, out, scenarios, run.executor, run.address, driver, timeout, demo_record)
    except LockBusy as busy:
        raise IrlsimError(
            f"another 'irlsim collect' is writing {out} (pid {busy.holder}): wait for it or stop it"
        ) from None
    return CollectResult(out, failed)


def scenario_records(cfg: CollectConfig, scenarios: Scenarios | None = None) -> dict[str, Any]:
    """The manifest's record of the roads (refused in one line, before any work, for a scenario that
    does not load): ``scenarios`` {name: sha256 of its scenario file and network} for a dataset over
    several scenarios or one named, and ``episode_scenarios`` {split: {episode: name}} for several;
    nothing for the default road alone, which records leave out (``recorded_name``). ``scenarios``: the
    command's (None: read here)."""
    if not cfg.scenarios and recorded_name(cfg.scenario.name) is None:
        return {}
    scenarios = scenarios or Scenarios()
    # each road by its identity (a shipped name, or name@digest): no path, one road however spelled
    ident = {n: scenarios.identity(n) for n in cfg.scenario_names}
    out: dict[str, Any] = {"scenarios": {ident[n]: scenarios(n).digest() for n in cfg.scenario_names}}
    if cfg.scenarios:
        out["episode_scenarios"] = {
            s: {str(e): ident[n] for (e, _), n in zip(cfg.episodes(s), cfg.episode_scenarios(s), strict=True)}
            for s in SPLITS
        }
    return out


def _scenario_problem(old: dict[str, Any], roads: dict[str, Any]) -> str | None:
    """Why a dataset recorded over other scenarios (or roads changed since) cannot be resumed, or None."""
    was, now = old.get("scenarios"), roads.get("scenarios")
    if not isinstance(was, dict) or now is None:  # older manifests record no roads: the config decides
        return None
    if list(was) != list(now):
        return f"was collected over the scenarios {', '.join(was)}, this config lists {', '.join(now)}"
    changed = [n for n in now if was[n] != now[n]]
    if changed:
        return f"was collected on another version of scenario {changed[0]} (its scenario file or network)"
    return None


def _check_resumable(
    manifest_path: Path,
    config: dict[str, Any],
    driver: dict[str, Any] | None = None,
    roads: dict[str, Any] | None = None,
    demonstrator: dict[str, Any] | None = None,
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
    if old.get("feature_names") != list(manifest_feature_names({"config": config})):
        raise IrlsimError(f"{out} holds a dataset of other features than this irlsim computes: {fix}")
    was, now = describe(old.get("demonstrator")), describe(demonstrator)
    if was != now:  # its vType attributes in full: the config's difference below
        raise IrlsimError(f"{out} was collected with demonstrator {was}, this config has {now}: {fix}")
    problem = _scenario_problem(old, roads or {})
    if problem is None and config.get("scenarios") != old["config"].get("scenarios"):
        problem = "was collected with another [[scenarios]] list (names or episodes per split)"
    if problem is not None:
        raise IrlsimError(f"{out} {problem}: {fix}")
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


def _pending_jobs(
    cfg: Any, out: Path, ckpt: str | None = None, scenarios: Scenarios | None = None
) -> tuple[list[Any], dict[str, list[int]]]:
    """The episodes still to collect (executor jobs) and every split's seeds; a finished episode whose
    files fail the check is deleted and collected again. Every job carries the command's ``scenarios``."""
    scenarios = scenarios or Scenarios()
    jobs: list[Any] = []
    seeds: dict[str, list[int]] = {}
    vouched = (out / "manifest.json").is_file()  # checked against this config: older files without a record
    for split in SPLITS:
        remove_partial(out, split)
        seeds[split] = [s for _, s in cfg.episodes(split)]
        # a dataset over several scenarios: each episode's own road (None: [scenario] name)
        roads = cfg.episode_scenarios(split) if cfg.scenarios else [None] * len(seeds[split])
        for (episode, seed), road in zip(cfg.episodes(split), roads, strict=True):
            if episode_done(out, split, episode):
                # a finished episode is trusted only after a look at its files: a truncated or foreign
                # pair would otherwise be kept, and break the manifest's counts or a later reader
                problem = check_episode(
                    out,
                    split,
                    episode,
                    n_policies=cfg.planner.n_policies,
                    n_control_points=cfg.planner.n_control_points,
                    record=episode_record(
                        seed, cfg, road, scenarios
                    ),  # another seed or config: collected again
                    unrecorded_ok=vouched,
                )
                if problem is None:
                    continue
                print(f"collect: {problem}: collecting {split} episode {episode} again", file=sys.stderr)
                remove_episode(out, split, episode)
            # an absolute path: a Ray worker runs in a folder of its own
            job = EpisodeJob(
                str(out.resolve()), split, episode, seed, cfg, ckpt, road, scenarios
            )  # ckpt: DAgger's
            jobs.append(ExecutorJob(f"{split}/{episode}", job))
    return jobs, seeds


def _report_failures(
    cfg: Any,
    out: Path,
    config: dict[str, Any],
    seeds: dict[str, list[int]],
    failed: dict[str, str],
    total: int,
    ident: dict[str, Any] | None = None,
) -> None:
    """Episodes that failed twice: the manifest lists the finished ones and the failed ones and stays
    incomplete (readers refuse it); one line names them; the same command collects just those, as it
    resumes any other incomplete collection."""
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


def _complete(cfg: Any, out: Path, record: dict[str, Any], collected: bool) -> Path:
    """Write the complete manifest (``record`` with every split's episodes) and return its path. When
    episodes were ``collected`` (an episode collected again has new files), the caches built from the
    files before are obsolete: removed now, one line each (:func:`irlsim.data.prune.prune_caches`)."""
    splits = {s: [e for e, _ in cfg.episodes(s)] for s in SPLITS}
    manifest = write_manifest(out, {**record, "splits": splits, "complete": True})
    if collected:
        prune_caches(open_dataset(out))
    return manifest


def _demo_record(demonstrator: dict[str, Any] | None) -> dict[str, Any]:
    """The manifest's ``demonstrator`` entry: a SUMO demonstrator's record, nothing for the expert."""
    return {"demonstrator": demonstrator} if demonstrator else {}


def _dagger_words(driver: dict[str, Any], demonstrator: dict[str, Any] | None, r: int) -> str:
    """Who drives and who labels a DAgger collection, as its first line says: the expert labels, or a SUMO
    driver (by name)."""
    who = describe(demonstrator) if demonstrator else "the expert"
    return f", {driver['model']} drives and {who} labels (DAgger round {r})"


def _collect(
    cfg: Any,
    out: Path,
    scenarios: Scenarios,
    executor: str = "local",
    address: str | None = None,
    driver: dict[str, Any] | None = None,
    timeout: float | None = None,
    demonstrator: dict[str, Any] | None = None,
) -> dict[str, str]:
    """The collection itself, run while this process holds ``<out>/.lock``. ``driver``: the learned
    driver's identity (:func:`driver_identity`) for a DAgger collection, recorded in the manifest;
    ``timeout``: the executor's limit per episode attempt; ``demonstrator``: a SUMO demonstrator's record
    (None: the expert); ``scenarios``: the command's roads. Returns the episodes that failed twice (key ->
    reason; empty when complete)."""
    manifest_path = out / "manifest.json"
    config = data_config(cfg, scenarios)
    roads = scenario_records(cfg, scenarios)  # a scenario that does not load: one line, before any work
    recorded = driver  # as the manifest records it: the first collection's, which the identity hashes
    if manifest_path.is_file():
        recorded = _check_resumable(manifest_path, config, driver, roads, demonstrator)
        if "scenarios" not in json.loads(manifest_path.read_text()):
            roads = {}  # one road, collected before manifests recorded it: the manifest keeps its bytes

    jobs, seeds = _pending_jobs(cfg, out, driver["checkpoint"] if driver is not None else None, scenarios)
    total = sum(len(v) for v in seeds.values())
    where = f"{cfg.workers} worker(s)" + (" as Ray tasks" if executor == "ray" else "")
    where += f", at most {timeout:g} s per episode" if timeout is not None else ", in this process"
    if driver is not None:
        where += _dagger_words(driver, demonstrator, cfg.dagger_round)
    elif demonstrator:
        where += f", demonstrator {describe(demonstrator)}"
    ident = {**({"driver": recorded} if driver is not None else {}), **_demo_record(demonstrator), **roads}
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
        _report_failures(cfg, out, config, seeds, result.failed, total, ident)
        return dict(result.failed)
    manifest = _complete(cfg, out, {"config": config, **ident, "seeds": seeds}, bool(jobs))
    wall = time.perf_counter() - t0
    if jobs:
        print(f"collect: {cycles} cycles in {wall:.1f} s ({cycles / max(wall, 1e-9):.1f} cycles/s in total)")
    print(f"wrote {out}/<split>/episode_*.{{cycles,policies}}.parquet and {manifest}")
    print(f"inspect with: irlsim data info {out}")
    return {}
