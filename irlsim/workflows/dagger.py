"""DAgger rounds (``irlsim dagger``): :func:`run_dagger` with :class:`DaggerRun` and :class:`DaggerConfig`.

N rounds of (drive -> label -> aggregate -> retrain) on top of a trained model. Round r (1..N), into
``out/round_<r>/``:

1. **drive + label**: :func:`irlsim.workflows.collect.collect_dataset` with the learned driver of the
   previous round (round 1: the one in ``runs``, trained on ``data``) into ``out/round_<r>/data``; the
   expert labels every cycle (``demo_source`` 'expert'); seeds in round r's window, disjoint from
   ``data``'s;
2. **aggregate**: the folders stay as they are: training reads ``data`` and every round's data folder so
   far (:mod:`irlsim.data.aggregate`: their splits concatenated into a memory-mapped cache in ``data``'s
   ``.cache``);
3. **retrain** from scratch, or with ``fine_tune`` from the previous round's stage-1 reward (the one that
   drove this round; ``Stage1Config.init_from``): :func:`irlsim.workflows.train.train_models`, stage 1
   (and stage 2 for a temporal driver or ``stage2_models``, always from scratch on the new base) into
   ``out/round_<r>/runs``.

Each step resumes like the command it equals (printed before it runs, and recorded in the round's
``round.json`` as that command line); a round is finished once ``out/round_<r>/round.json`` exists and
is then skipped. The steps are library calls (:func:`round_plan`), the command lines only their record.

DAgger lives here, not in :mod:`irlsim.drive.dagger` (the learner-drives-expert-labels driver), because a
round composes collection and training workflows, which sit above the driving library.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim.config import MAX_SEED, load_config, require
from irlsim.data.collection import CollectConfig
from irlsim.data.demonstrator import EXPERT
from irlsim.errors import IrlsimError
from irlsim.models.registry import MODEL_NAMES, STAGE2_BASE
from irlsim.train.config import Stage1Config, Stage2Config
from irlsim.train.layout import find_checkpoint, stage_dir
from irlsim.utils import write_json
from irlsim.workflows.collect import CollectRun, collect_dataset
from irlsim.workflows.dagger_record import (
    check_driver_and_data,
    check_round_splits,
    round_finished,
    round_inputs,
    round_outputs,
)
from irlsim.workflows.steps import exit_status
from irlsim.workflows.train import TrainRun, train_models

#: written last in a round's folder: the round is finished (skipped when DAgger runs again)
ROUND_DONE = "round.json"


@dataclass(frozen=True)
class DaggerConfig:
    """``irlsim dagger`` (``configs/dagger/*.toml``)."""

    rounds: int = 2
    """DAgger rounds"""
    model: str = "PACNN+S"
    """the learned driver of every round (a stage-2 model also retrains its stage-1 base)"""
    episodes: int | list[int] = 4
    """learner-driven, labelled train episodes per round (the expert labels, or the collect config's SUMO
    demonstrator by a look ahead): one count for every round, or a list
    with one count per round (``[6, 20]``; ``--rounds 1`` with it runs round 1 only)"""
    validation_episodes: int = 0
    """learner-driven validation episodes per round (0: model choices stay on --data's validation split)"""
    workers: int = 2
    """collection worker processes"""
    collect_config: str = "configs/collect/default.toml"
    """the collect config of --data (its planner, scenario and base seed; episode counts are replaced)"""
    stage1_config: str = "configs/train/stage1.toml"
    """stage-1 training config (only the driver's stage-1 model is trained)"""
    stage2_config: str = "configs/train/stage2.toml"
    """stage-2 training config (used when ``model`` is a stage-2 model)"""
    stage2_models: list[str] = dataclasses.field(default_factory=list)
    """stage-2 models trained on each round's aggregate beside the driver, on its stage-1 base
    (``["PTACNN+S"]`` next to a PACNN+S driver); they do not drive"""
    epochs: list[int] = dataclasses.field(default_factory=list)
    """stage-1 epochs of each round's retraining, one per round (empty: the stage-1 config's ``epochs``
    in every round)"""
    stage2_epochs: int = 0
    """stage-2 epochs of every round's stage-2 training (0: the stage-2 config's ``epochs``)"""
    fine_tune: bool = False
    """each round's stage-1 retraining starts from the previous round's stage-1 reward (round 1: the one
    in ``--runs``) instead of random weights, so ``epochs`` can be few; False: from scratch"""
    stage2_every_round: bool = True
    """False: ``stage2_models`` train in the last round only. The next round's driver is the stage-1
    model, so an earlier round's stage-2 models serve only that round's own evaluation (a stage-2 driver
    is trained in every round all the same); the last round's models are the same bytes either way"""
    overlap: bool = False
    """collect round r + 1's learner episodes in a worker process while round r trains its stage-2 models
    (the learner, a stage-1 model, is trained by then): the same bytes as one step after the other, in
    less time where the cores are not all busy with one step. Needs a stage-1 driver and stage2_models"""
    scenario: str = ""
    """the road the learner drives in every round (a shipped scenario or a scenario.toml path; empty: the
    collect config's). DAgger on a road the reward was not trained on makes its data in-domain"""
    seed: int | None = None
    """training seed of every round's retraining, stage 1 and 2 (None: the stage configs' ``seed``); the
    learner's episodes keep the collect config's seeds, so two training seeds drive the same scenarios"""

    def validate(self) -> None:
        require(1 <= self.rounds <= 23, f"rounds must be in 1..23, got {self.rounds}")
        require(
            self.model in MODEL_NAMES, f"model must be one of {', '.join(MODEL_NAMES)}, got {self.model!r}"
        )
        counts = self.episodes if isinstance(self.episodes, list) else [self.episodes]
        if isinstance(self.episodes, list):
            require(
                len(self.episodes) >= self.rounds,
                f"episodes has {len(self.episodes)} entries for {self.rounds} round(s): give one count per "
                "round, or a single number for every round",
            )
        for n in counts:
            require(1 <= n <= 10_000, f"episodes must be in 1..10000, got {n}")
        if self.epochs:
            require(
                len(self.epochs) >= self.rounds,
                f"epochs has {len(self.epochs)} entries for {self.rounds} round(s): give one per round, or "
                "leave it empty to use the stage-1 config's epochs",
            )
        for n in self.epochs:
            require(1 <= n <= 100_000, f"epochs must be in 1..100000, got {n}")
        require(
            0 <= self.stage2_epochs <= 100_000,
            f"stage2_epochs must be in 0..100000 (0: the stage-2 config's), got {self.stage2_epochs}",
        )
        on_base = [k for k, v in STAGE2_BASE.items() if v == self.stage1_model]
        for m in self.stage2_models:
            require(
                m in on_base,
                f"stage2_models entry {m!r} must be a stage-2 model on the driver's stage-1 base "
                f"{self.stage1_model} ({', '.join(on_base) or 'none'})",
            )
        if self.seed is not None:
            require(0 <= self.seed <= MAX_SEED, f"seed must be in 0..{MAX_SEED}, got {self.seed}")
        require(
            0 <= self.validation_episodes <= 10_000,
            f"validation_episodes must be in 0..10000, got {self.validation_episodes}",
        )
        require(self.workers >= 1, f"workers must be >= 1, got {self.workers}")
        require(
            not self.overlap or (self.model not in STAGE2_BASE and bool(self.stage2_models)),
            "overlap needs a stage-1 driver (model) and stage2_models: the next round's episodes are "
            "collected while this round trains its stage-2 models",
        )
        require(
            not self.overlap or self.stage2_every_round,
            "overlap needs stage2_every_round = true: the next round's episodes are collected while this "
            "round trains its stage-2 models",
        )

    @property
    def stage1_model(self) -> str:
        return STAGE2_BASE.get(self.model, self.model)

    @property
    def trained_stage2(self) -> list[str]:
        """The stage-2 models each round trains: the driver if it is one, then ``stage2_models``."""
        first = [self.model] if self.model in STAGE2_BASE else []
        return first + [m for m in self.stage2_models if m not in first]

    def round_stage2(self, r: int) -> list[str]:
        """The stage-2 models round ``r`` trains: :attr:`trained_stage2`, or only a stage-2 driver in a
        round before the last when ``stage2_every_round`` is off."""
        every = self.trained_stage2
        return every if self.stage2_every_round or r >= self.rounds else [m for m in every if m == self.model]

    def round_episodes(self, r: int) -> int:
        """Learner-driven train episodes of round ``r`` (1-based)."""
        return self.episodes[r - 1] if isinstance(self.episodes, list) else self.episodes

    def round_train_overrides(self, r: int, stage: int) -> dict[str, Any]:
        """Round ``r``'s stage-``stage`` config overrides beyond the model names (epochs, seed)."""
        out: dict[str, Any] = {}
        if stage == 1 and self.epochs:
            out["epochs"] = self.epochs[r - 1]
        if stage == 2 and self.stage2_epochs:
            out["epochs"] = self.stage2_epochs
        if self.seed is not None:
            out["seed"] = self.seed
        return out


@dataclass(frozen=True)
class DaggerRun:
    """DAgger on top of a trained model: what ``irlsim dagger`` parses its arguments into."""

    config: DaggerConfig
    data: Path
    """the expert's dataset the ``runs`` model was trained on"""
    runs: Path
    """the runs folder of the model trained on ``data``"""
    out: Path
    """the DAgger folder: ``out/round_<r>/{data,runs}``"""
    more_data: tuple[Path, ...] = ()
    """further expert datasets the ``runs`` model was trained on together with ``data`` (an aggregate,
    in its order: e.g. a reward trained on several roads); the collect config is ``data``'s"""

    @property
    def expert_data(self) -> tuple[Path, ...]:
        """Every expert dataset the ``runs`` model was trained on, in order."""
        return (self.data, *self.more_data)


@dataclass(frozen=True)
class RoundPlan:
    """Round r's steps: the collection, then the trainings; ``commands`` are the same steps as the
    ``irlsim`` command lines a user would type (printed and recorded, never parsed)."""

    collect: CollectRun
    train: tuple[TrainRun, ...]
    commands: tuple[tuple[str, ...], ...]


def round_dir(out: Path, r: int) -> Path:
    return out / f"round_{r}"


def _sets(overrides: dict[str, Any]) -> list[str]:
    """``--set`` arguments that give ``overrides`` (ints and lists of names) on a command line."""
    out = []
    for key, value in overrides.items():
        if isinstance(value, list):
            text = "[" + ", ".join(f"'{v}'" for v in value) + "]"
        else:
            text = f"'{value}'" if isinstance(value, str) else str(value)
        out += ["--set", f"{key}={text}"]
    return out


def round_plan(run: DaggerRun, r: int) -> RoundPlan:
    """The steps of round r: collect (driver from round r - 1), then the training stages."""
    cfg = run.config
    prev_runs = run.runs if r == 1 else round_dir(run.out, r - 1) / "runs"
    here = round_dir(run.out, r)
    data = (*run.expert_data, *(round_dir(run.out, k) / "data" for k in range(1, r + 1)))
    counts = {
        "train_episodes": cfg.round_episodes(r),
        "validation_episodes": cfg.validation_episodes,
        "test_episodes": 0,
    }
    scenario = {"scenario.name": cfg.scenario} if cfg.scenario else {}
    collect_cfg = load_config(
        CollectConfig, cfg.collect_config, {**counts, "workers": cfg.workers, "dagger_round": r, **scenario}
    )
    collect = CollectRun(collect_cfg, here / "data", driver=cfg.model, runs=prev_runs)
    paths = [str(p) for p in data]
    commands = [
        ["collect", "--config", cfg.collect_config, "--out", str(here / "data")]
        + ["--workers", str(cfg.workers), "--driver", cfg.model, "--runs", str(prev_runs)]
        + ["--round", str(r), *_sets(counts)]
        + (["--scenario", cfg.scenario] if cfg.scenario else [])
    ]
    stages: list[tuple[int, str, type, list[str]]] = [
        (1, cfg.stage1_config, Stage1Config, [cfg.stage1_model])
    ]
    if second := cfg.round_stage2(r):
        stages.append((2, cfg.stage2_config, Stage2Config, second))
    train = []
    for stage, path, kind, models in stages:
        overrides = {"models": models, **cfg.round_train_overrides(r, stage)}
        if stage == 1 and cfg.fine_tune:
            start = find_checkpoint(prev_runs, cfg.stage1_model)
            start = start or stage_dir(prev_runs, 1) / cfg.stage1_model / "checkpoint.pt"
            overrides["init_from"] = str(start)
        train.append(TrainRun(load_config(kind, path, overrides), data, here / "runs"))
        commands.append(
            ["train", "--stage", str(stage), "--config", path, "--data", *paths, "--out", str(here / "runs")]
            + _sets(overrides)
        )
    return RoundPlan(collect, tuple(train), tuple(tuple(c) for c in commands))


def round_commands(run: DaggerRun, r: int) -> list[list[str]]:
    """Round r's steps as ``irlsim`` command lines (without the leading 'irlsim')."""
    return [list(c) for c in round_plan(run, r).commands]


def run_dagger(run: DaggerRun) -> int:
    """Run (or resume) every round of ``run``. Returns 0, or the exit status of the round's step that
    failed (after its one-line error and a line naming the round and step, as ``irlsim`` prints them;
    running again resumes). Raises :class:`~irlsim.errors.IrlsimError` (one line) before any work for a
    missing config file or driver checkpoint, or an ``out`` that is a file."""
    cfg = run.config
    for name in ("collect_config", "stage1_config", "stage2_config"):
        if not Path(getattr(cfg, name)).is_file():
            raise IrlsimError(f"config: {name} {getattr(cfg, name)} not found: pass an existing TOML file")
    if find_checkpoint(run.runs, cfg.model) is None:
        raise IrlsimError(
            f"{cfg.model} has no checkpoint in {run.runs}: train it on {run.data} first ('irlsim train "
            f"--data {run.data} --out {run.runs}'), or set model to a trained one"
        )
    if run.out.exists() and not run.out.is_dir():
        raise IrlsimError(f"--out {run.out} is a file: choose a folder for the DAgger rounds")
    check_driver_and_data(run)  # --runs trained on --data, the collect config the data's: before any work
    for r in range(1, cfg.rounds + 1):
        check_round_splits(run, r)  # an empty validation split is named before the round collects
    kind = load_config(CollectConfig, cfg.collect_config).demonstrator.kind
    labels = "expert-labelled" if kind == EXPERT else f"labelled by the {kind} demonstrator's look ahead"
    for r in range(1, cfg.rounds + 1):
        here = round_dir(run.out, r)
        if round_finished(run, r, here, _driver(run, r)):
            print(f"dagger: round {r} finished before: {here}/data, {here}/runs (skipped)", flush=True)
            continue
        rc = _round(run, r)
        if rc != 0:
            return rc
        print(f"dagger: round {r} wrote {here}/data ({labels}) and {here}/runs ({cfg.model})", flush=True)
    last = round_dir(run.out, cfg.rounds) / "runs"
    final = stage_dir(last, 2 if cfg.model in STAGE2_BASE else 1) / cfg.model
    print(f"dagger: {cfg.rounds} round(s) in {run.out}; the last round's {cfg.model}: {final}")
    return 0


def _driver(run: DaggerRun, r: int) -> Path | None:
    """The checkpoint that drives round r: ``--runs``' model, then each round's retrained one."""
    return find_checkpoint(run.runs if r == 1 else round_dir(run.out, r - 1) / "runs", run.config.model)


def _trained(step: TrainRun) -> bool:
    train_models(step)
    return True


def _round(run: DaggerRun, r: int) -> int:
    """Round r's steps, then its ``round.json``; the exit status of a failed step, else 0."""
    t0 = time.perf_counter()
    here = round_dir(run.out, r)
    plan = round_plan(run, r)
    driver = _driver(run, r)
    if driver is None:
        raise IrlsimError(
            f"dagger: round {r} has no driver {run.config.model} in {plan.collect.runs}: re-run"
        )
    (here / ROUND_DONE).unlink(missing_ok=True)  # not finished until its record is written again
    inputs = round_inputs(run, r, driver)
    steps: list[Callable[[], bool]] = [lambda: collect_dataset(plan.collect).ok]
    steps += [functools.partial(_trained, t) for t in plan.train]
    ahead = None
    spent: dict[str, float] = {}  # where the round's time went, step by step
    for k, (step, cmd) in enumerate(zip(steps, plan.commands, strict=True)):
        if k == 2 and run.config.overlap and r < run.config.rounds:  # stage 1 trained: the next learner
            ahead = _collect_ahead(run, r + 1)
        print(f"\n$ irlsim {' '.join(cmd)}", flush=True)
        t_step = time.perf_counter()
        rc = exit_status(step)
        spent[step_name(cmd)] = round(time.perf_counter() - t_step, 1)
        if rc != 0:
            _join(ahead, r + 1)
            print(f"dagger: round {r} step 'irlsim {cmd[0]}' failed (exit {rc}); re-run to resume")
            return rc
    t_join = time.perf_counter()
    _join(ahead, r + 1)
    if ahead is not None:
        spent[f"waiting for round {r + 1}'s collection"] = round(time.perf_counter() - t_join, 1)
    record: dict[str, Any] = {
        "round": r,
        "model": run.config.model,
        "data": str(here / "data"),
        "runs": str(here / "runs"),
        "driver_runs": str(run.runs if r == 1 else round_dir(run.out, r - 1) / "runs"),
        "trained_on": [
            *map(str, run.expert_data),
            *(str(round_dir(run.out, k) / "data") for k in range(1, r + 1)),
        ],
        "commands": [["irlsim", *c] for c in plan.commands],
        "wall_s": round(time.perf_counter() - t0, 1),
        "steps_s": spent,
        "inputs": inputs,
        "outputs": round_outputs(run, r, here),
    }
    write_json(here / ROUND_DONE, record)
    where = ", ".join(f"{name} {t:.1f} s" for name, t in spent.items())
    print(f"dagger: round {r} took {record['wall_s']:.1f} s ({where})", flush=True)
    return 0


def step_name(cmd: Sequence[str]) -> str:
    """A round step's name in its record: 'collect', 'train stage 1', 'train stage 2'."""
    return f"train stage {cmd[cmd.index('--stage') + 1]}" if cmd[0] == "train" else cmd[0]


def _collect_next(collect: CollectRun) -> None:  # top level: picklable for the spawned process
    raise SystemExit(0 if collect_dataset(collect).ok else 1)


def _collect_ahead(run: DaggerRun, r: int) -> Any:
    """Start round ``r``'s collection (its learner is round r - 1's stage-1 model, trained) in a spawned
    process; round r's collect step then finds the dataset complete, or resumes it."""
    import multiprocessing

    plan = round_plan(run, r)
    print(f"dagger: round {r}'s learner episodes are collected meanwhile into {plan.collect.out}", flush=True)
    proc = multiprocessing.get_context("spawn").Process(target=_collect_next, args=(plan.collect,))
    proc.start()
    return proc


def _join(proc: Any, r: int) -> None:
    """Wait for a collection started by :func:`_collect_ahead`; a failed one is resumed by round r."""
    if proc is None:
        return
    proc.join()
    if proc.exitcode != 0:
        print(
            f"dagger: round {r}'s collection meanwhile ended with exit {proc.exitcode}; round {r} resumes it"
        )
