"""Collecting demonstrations: drive the expert in SUMO and record every planning cycle's policy set.

One episode runs in one process (one libsumo per process). Each cycle the expert samples its policy set,
executes its chosen policy for one planning cycle; the odometry of what it actually drove is projected
onto each cycle's policy set once the horizon has been driven (``DemoProjector``), and the episode is
written as a pair of Parquet files (``EpisodeWriter``). The episode's content depends only on its seed.

DAgger (``irlsim collect --driver``): a learned reward drives instead, and every cycle's demonstration is
the expert's own selection in the same policy set at the learner's state (``demo_source`` 'expert'); the
driver is made above this layer (``irlsim.drive.dagger``) and handed in as a factory.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from irlsim.config import MAX_SEED, require, require_memory, to_dict
from irlsim.data.demonstrator import (
    EXPERT,
    RECORDING,
    SUMO,
    DemonstratorConfig,
    SumoDemonstrator,
    as_recorded,
    demonstrator_simulation,
    recorded_ego,
)
from irlsim.data.demos import DemoConfig as DemoConfig  # re-exported: a field of CollectConfig
from irlsim.data.demos import DemoProjector
from irlsim.data.recorded import recorded_episode
from irlsim.data.recorder import CycleRecorder
from irlsim.data.recorder import LabelledDriver as LabelledDriver  # re-exported: DAgger's drivers
from irlsim.data.roads import ScenarioEpisodes as ScenarioEpisodes  # re-exported: of CollectConfig
from irlsim.data.roads import by_identity
from irlsim.data.schema import DEMO_EXPERT, DEMO_ODOMETRY, stats_name
from irlsim.data.writer import EpisodeWriter
from irlsim.planner.config import PLANNER_BYTES_PER_POLICY, PlannerConfig
from irlsim.planner.expert import ExpertDriver
from irlsim.road import Road, load_road
from irlsim.road.scenario import Scenarios, recorded_name
from irlsim.rollout import EpisodeRunner, Observer, ObserverBase
from irlsim.rollout.style import StyleObserver
from irlsim.sim.config import EpisodeConfig, defaults_source, with_scenario_defaults
from irlsim.sim.simulation import Simulation
from irlsim.sim.types import Observation
from irlsim.utils import MISSING as MISSING  # re-exported: the manifest checks' names
from irlsim.utils import first_difference as first_difference
from irlsim.utils import seed_everything, write_json

SPLITS = ("train", "validation", "test")
#: episode seeds: seed * SEED_STRIDE + SPLIT_OFFSET[split] + i, so splits never share a seed
SEED_STRIDE = 1_000_000
SPLIT_OFFSET = {"train": 0, "validation": 100_000, "test": 200_000}
#: DAgger rounds (``dagger_round`` r >= 1) take seeds from the part of each base seed's stride the
#: expert's splits never use: seed * SEED_STRIDE + DAGGER_OFFSET + (r - 1) * DAGGER_ROUND_STRIDE
#: + split index * DAGGER_SPLIT_STRIDE + i; so a round's seeds are disjoint from every odometry dataset's
#: (any base seed) and from every other round's
DAGGER_OFFSET = 300_000
DAGGER_SPLIT_STRIDE = 10_000
DAGGER_ROUND_STRIDE = len(SPLITS) * DAGGER_SPLIT_STRIDE
MAX_DAGGER_ROUND = (SEED_STRIDE - DAGGER_OFFSET) // DAGGER_ROUND_STRIDE


#: the top-level episode counts when a config leaves them out
_DEFAULT_COUNTS = {"train": 4, "validation": 1, "test": 1}


@dataclass(frozen=True)
class CollectConfig:
    """``irlsim collect``: which episodes to drive and how. Nested tables: [scenario], [planner], [demo]."""

    seed: int = 0
    """base seed; episode i of a split uses seed * 1e6 + split offset (train 0, validation 1e5,
    test 2e5) + i"""
    workers: int = 2
    """worker processes, one libsumo simulation each (1 = in this process)"""
    train_episodes: int = 4
    """episodes of the train split (training shuffles their cycles)"""
    validation_episodes: int = 1
    """episodes of the validation split (sequential playback)"""
    test_episodes: int = 1
    """episodes of the test split (sequential playback)"""
    max_cycles: int = 0
    """stop an episode after this many planning cycles (0 = until laps, collision, exit or time-out)"""
    dagger_round: int = 0
    """0: the expert drives, its projected odometry is the demonstration; r >= 1: DAgger round r
    (``irlsim collect --driver``): a learned reward drives, the expert labels, and the episode seeds move
    to round r's window (see ``episodes``)"""
    scenario: EpisodeConfig = field(default_factory=EpisodeConfig)
    """traffic, clocks and episode limits (irlsim.sim.config.EpisodeConfig)"""
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    """policy sampling and features (irlsim.planner.config.PlannerConfig)"""
    demo: DemoConfig = field(default_factory=DemoConfig)
    """demonstration projection"""
    demonstrator: DemonstratorConfig = field(default_factory=DemonstratorConfig)
    """who drives (irlsim.data.demonstrator): the expert (default) or SUMO's driver models"""
    scenarios: tuple[ScenarioEpisodes, ...] = ()
    """a dataset over several scenarios: ``[[scenarios]]`` tables ``{name, train_episodes,
    validation_episodes, test_episodes}``; each split's episodes are numbered over the list in order (the
    first entry's first), so the seed rule of ``episodes`` keeps them disjoint; the top-level counts are
    then their sums (leave them out). Empty: the one scenario ``[scenario] name``"""

    def __post_init__(self) -> None:
        counts = {s: getattr(self, f"{s}_episodes") for s in SPLITS}
        if self.scenarios and counts == _DEFAULT_COUNTS:  # left out: the sums over [[scenarios]]
            for s in SPLITS:
                object.__setattr__(
                    self, f"{s}_episodes", sum(getattr(e, f"{s}_episodes") for e in self.scenarios)
                )

    @classmethod
    def with_defaults(cls, data: dict[str, Any], scenarios: Scenarios | None = None) -> dict[str, Any]:
        """The TOML data with its scenario file's ``[defaults]`` beneath its ``[scenario]`` table (see
        :func:`irlsim.sim.config.with_scenario_defaults`); a dataset over several scenarios as it is."""
        table = data.get("scenario")
        if not isinstance(table, dict) or data.get("scenarios"):
            return data
        return {**data, "scenario": with_scenario_defaults(table, scenarios)}

    @classmethod
    def defaults_source(cls, data: dict[str, Any]) -> str | None:
        """The scenario file whose ``[defaults]`` ``with_defaults`` used (``load_config`` names it)."""
        table = data.get("scenario")
        return defaults_source(table) if isinstance(table, dict) and not data.get("scenarios") else None

    def validate(self) -> None:
        require(self.seed >= 0, f"seed must be >= 0, got {self.seed}")
        self._validate_scenarios()
        for s in SPLITS:
            n = getattr(self, f"{s}_episodes")
            require(0 <= n < 100_000, f"{s}_episodes must be in 0..99999, got {n}")
        require(
            0 <= self.dagger_round <= MAX_DAGGER_ROUND,
            f"dagger_round must be in 0..{MAX_DAGGER_ROUND}, got {self.dagger_round}",
        )
        if self.dagger_round:
            for s in SPLITS:
                n = getattr(self, f"{s}_episodes")
                require(
                    n <= DAGGER_SPLIT_STRIDE,
                    f"{s}_episodes must be <= {DAGGER_SPLIT_STRIDE} in a DAgger round, got {n}",
                )
        # episode seeds are seed * 1e6 + split offset + i and go to SUMO, which takes at most MAX_SEED: the
        # derivation is kept (it decides the bytes of every existing dataset), the base seed is bounded
        last = max(
            (seed - self.seed * SEED_STRIDE for s in SPLITS for _, seed in self.episodes(s)[-1:]), default=0
        )
        max_base = (MAX_SEED - last) // SEED_STRIDE
        require(
            self.seed <= max_base,
            f"seed must be in 0..{max_base} (episode seeds are seed * {SEED_STRIDE:,} + split offset + "
            f"episode and SUMO takes at most {MAX_SEED}), got {self.seed}",
        )
        require(self.workers >= 1, f"workers must be >= 1, got {self.workers}")
        require(self.train_episodes >= 1, "train_episodes must be >= 1")
        require(self.max_cycles >= 0, f"max_cycles must be >= 0, got {self.max_cycles}")
        require(abs(self.planner.dt - self.scenario.step) < 1e-9, "planner.dt must equal scenario.step")
        require(
            abs(self.planner.cycle - self.scenario.cycle) < 1e-9, "planner.cycle must equal scenario.cycle"
        )
        require(
            abs(self.planner.horizon - self.scenario.horizon) < 1e-9,
            "planner.horizon must equal scenario.horizon",
        )
        self.demo.validate()
        self.demonstrator.validate()
        require(
            not self.dagger_round or self.demonstrator.kind != RECORDING,
            "DAgger rounds label with the expert or a SUMO driver; a recording cannot label states its "
            "vehicles never drove: set [demonstrator] kind = 'expert' or 'sumo'",
        )
        require_memory(
            f"planner.n_policies={self.planner.n_policies} with {self.workers} workers",
            self.workers * self.planner.n_policies * PLANNER_BYTES_PER_POLICY,
            "use fewer policies per cycle or fewer --workers",
        )

    def _validate_scenarios(self) -> None:
        if not self.scenarios:
            return
        names = [e.name for e in self.scenarios]
        require(
            all(names), "every [[scenarios]] entry needs a name: a shipped scenario or a scenario.toml path"
        )
        dup = next((n for i, n in enumerate(names) if n in names[:i]), None)
        require(dup is None, f"[[scenarios]] lists '{dup}' twice: give each scenario one entry")
        for e in self.scenarios:
            for s in SPLITS:
                n = getattr(e, f"{s}_episodes")
                require(
                    0 <= n < 100_000, f"[[scenarios]] '{e.name}': {s}_episodes must be in 0..99999, got {n}"
                )
        for s in SPLITS:
            total = sum(getattr(e, f"{s}_episodes") for e in self.scenarios)
            n = getattr(self, f"{s}_episodes")
            require(
                n == total,
                f"{s}_episodes = {n} but [[scenarios]] give {total}: leave the top-level episode counts out "
                "when [[scenarios]] lists the episodes",
            )

    def check_roads(self, scenarios: Scenarios | None = None) -> None:
        """Collection only (drive and the environment take one road of such a config with ``--scenario``):
        ``[scenario] name`` and ``[[scenarios]]`` may not both name the road, nor two entries one road
        spelled two ways (by :func:`~irlsim.road.scenario.scenario_identity`; ``scenarios``: the
        command's, None: read here)."""
        identity = (scenarios or Scenarios()).identity
        require(
            not self.scenarios or recorded_name(self.scenario.name) is None,  # [scenario] names none
            f"[scenario] name = '{self.scenario.name}' and [[scenarios]] both name the road: list every "
            "scenario in [[scenarios]] (and drop --scenario)",
        )
        seen: dict[str, str] = {}
        for name in self.scenario_names:
            road = identity(name)
            require(
                road not in seen,
                f"[[scenarios]] lists one road twice, as '{seen.get(road)}' and '{name}' (both {road}): give "
                "each scenario one entry",
            )
            seen[road] = name

    @property
    def scenario_names(self) -> tuple[str, ...]:
        """The scenarios of the dataset, in order: the ``[[scenarios]]`` names, else ``[scenario] name``."""
        return tuple(e.name for e in self.scenarios) or (self.scenario.name,)

    def episode_scenarios(self, split: str) -> list[str]:
        """The scenario of every episode of ``split``, in the order of ``episodes``."""
        if not self.scenarios:
            return [self.scenario.name] * getattr(self, f"{split}_episodes")
        return [e.name for e in self.scenarios for _ in range(getattr(e, f"{split}_episodes"))]

    def episodes(self, split: str) -> list[tuple[int, int]]:
        """(episode id, seed) of every episode of ``split``: seed * 1e6 + split offset + i for the
        expert's data; seed * 1e6 + 300,000 + (round - 1) * 30,000 + split index * 10,000 + i for DAgger
        round ``dagger_round`` (offsets 300,000 and up, which the expert's splits never reach)."""
        n = getattr(self, f"{split}_episodes")
        if self.dagger_round:
            off = (
                DAGGER_OFFSET
                + (self.dagger_round - 1) * DAGGER_ROUND_STRIDE
                + SPLITS.index(split) * DAGGER_SPLIT_STRIDE
            )
        else:
            off = SPLIT_OFFSET[split]
        return [(i, self.seed * SEED_STRIDE + off + i) for i in range(n)]


#: CollectConfig fields that do not change a byte of the data (workers=1 and workers=2 write the same
#: files): left out of the manifest's config, so a run may be resumed with another value
DATA_NEUTRAL_FIELDS: tuple[str, ...] = ("workers",)


#: [bytes] one policy row on disk, an upper estimate (the tiny dataset: 1.8 MB for 24,000 rows, ~75 B)
DISK_BYTES_PER_POLICY_ROW = 128


def estimate_dataset_bytes(cfg: CollectConfig) -> int:
    """Disk a collection will write at most (Parquet), for the free-space check before it starts."""
    cycles = cfg.max_cycles or int(cfg.scenario.max_time / cfg.scenario.cycle)
    episodes = cfg.train_episodes + cfg.validation_episodes + cfg.test_episodes
    return episodes * cycles * cfg.planner.n_policies * DISK_BYTES_PER_POLICY_ROW


def data_config(cfg: CollectConfig | dict[str, Any], scenarios: Scenarios | None = None) -> dict[str, Any]:
    """The config as recorded in a dataset's manifest: every field that shapes the data, as plain JSON
    types. Accepts a ``CollectConfig`` or an already recorded dict (older manifests kept ``workers``).
    ``scenarios``: the command's, which has read the config's roads (None: read here)."""
    d = cfg if isinstance(cfg, dict) else by_identity(to_dict(cfg), scenarios)
    scn = d.get("scenario")
    if isinstance(scn, dict) and "name" in scn and recorded_name(scn["name"]) is None:
        # the default road is left out: its datasets keep the bytes (and identity) of before scenarios
        d = {**d, "scenario": {k: v for k, v in scn.items() if k != "name"}}
    # dagger_round 0, no [[scenarios]] and the expert as demonstrator are left out: a manifest keeps its
    # bytes (and identity) of before
    return {
        k: as_recorded(v) if k == "demonstrator" else v
        for k, v in d.items()
        if k not in DATA_NEUTRAL_FIELDS
        and (k, v) not in (("dagger_round", 0), ("scenarios", []))
        and not (k == "demonstrator" and (v or {}).get("kind", EXPERT) == EXPERT)
    }


def config_hash(cfg: CollectConfig | dict[str, Any], scenarios: Scenarios | None = None) -> str:
    """sha256 of the data config (:func:`data_config`, canonical JSON): what every episode file records
    beside its seed, so a resumed collection recognises a file collected with another config."""
    text = json.dumps(data_config(cfg, scenarios), sort_keys=True, separators=(",", ":"), default=str)
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


def episode_record(
    seed: int,
    cfg: CollectConfig | dict[str, Any],
    scenario: str | None = None,
    scenarios: Scenarios | None = None,
) -> dict[str, Any]:
    """What an episode's files record of their collection (EpisodeWriter ``record``): seed, config hash,
    and in a dataset over several scenarios (``scenario`` given) the episode's scenario. ``scenarios``:
    the command's, which has read the roads (None: read here)."""
    scenarios = scenarios or Scenarios()
    out: dict[str, Any] = {"seed": int(seed), "config": config_hash(cfg, scenarios)}
    if scenario is not None:
        out["scenario"] = scenarios.identity(scenario)
    return out


def same_driver(old: dict[str, Any] | None, new: dict[str, Any] | None) -> bool:
    """Whether two recorded DAgger drivers (manifest ``driver``: model, checkpoint path, sha256, the
    dataset it was trained on) are the same by content: model and checkpoint sha256, never the path, so a
    copied or moved DAgger folder resumes its collection."""
    if old is None or new is None:
        return old is new
    return (old.get("model"), old.get("sha256")) == (new.get("model"), new.get("sha256"))


@dataclass(frozen=True)
class EpisodeJob:
    dataset: str
    split: str
    episode: int
    seed: int
    config: CollectConfig
    driver: str | None = None
    """None: the expert drives (odometry demonstrations); a checkpoint path: that learned reward drives
    and the expert labels every cycle (DAgger, ``irlsim collect --driver``)"""
    scenario: str | None = None
    """the episode's scenario in a dataset over several (``[[scenarios]]``); None: ``[scenario] name``"""
    scenarios: Scenarios | None = None
    """the command's roads, read (and their networks built) once before the jobs: a worker process
    receives them instead of reading the scenario files again (None: read in the episode)"""


#: makes the driver of a DAgger episode: (road, collect config) -> a LabelledDriver
DriverFactory = Callable[[Road, CollectConfig], LabelledDriver]


def _episode_driver(
    job: EpisodeJob, road: Road, scenario: EpisodeConfig, make_driver: DriverFactory | None
) -> tuple[Any, Road, EpisodeConfig, Simulation | None]:
    """Who drives an episode: (driver, road, scenario, the replay simulation of a recording or None)."""
    cfg, demonstrator = job.config, job.config.demonstrator
    if make_driver is not None:
        return make_driver(road, cfg), road, scenario, None
    if demonstrator.kind == EXPERT:
        return ExpertDriver(road, cfg.planner), road, scenario, None
    if demonstrator.kind == RECORDING:  # the ego's own route and start; the others replay
        counts = {s: getattr(cfg, f"{s}_episodes") for s in SPLITS}
        ego = recorded_ego(demonstrator, counts, job.split, job.episode)
        window = demonstrator.rate_window  # the recorded ego drives on as recorded through an overlap
        return recorded_episode(
            demonstrator.file,
            road,
            scenario,
            cfg.planner,
            ego,
            rate_window=window,
            end_on_collision=False,
            read=demonstrator.read_as(),
        )
    return SumoDemonstrator(road, cfg.planner, scenario), road, scenario, None


def demo_projector(road: Road, cfg: CollectConfig) -> DemoProjector:
    """The odometry projection of a collection with ``cfg`` on ``road`` (its planner's horizon and step,
    the config's ``[demo]`` metric and limit)."""
    return DemoProjector(
        lap_length=road.lap_length,
        horizon=cfg.planner.horizon,
        dt=cfg.planner.dt,
        alpha=cfg.demo.alpha,
        w_yaw=cfg.demo.w_yaw,
        max_demo_distance=cfg.demo.max_distance,
    )


def collect_episode(
    job: EpisodeJob, make_driver: DriverFactory | None = None, observers: Sequence[Observer] = ()
) -> dict[str, Any]:
    """Drive one episode and write its two Parquet files (and its driving figures as JSON).

    ``make_driver`` None: the expert drives and its projected odometry is the demonstration
    (``demo_source`` 'odometry'); otherwise the driver it makes (a :class:`LabelledDriver`: a learned
    reward driving) drives and the expert's selections are the demonstrations (``demo_source``
    'expert'), or with a SUMO demonstrator SUMO's driver's look ahead from each cycle's state, projected
    (``demo_source`` 'odometry'; ``collect/expert_agreement`` is then the agreement with SUMO's label).
    ``observers``: extra observers after the recorder (tests).

    Returns the episode's figures (namespaced keys ``sim/...``, ``collect/...``). ``collect/wall_s`` and
    ``collect/cycles_per_s`` cover the whole episode end to end: set-up (road, SUMO start, reset),
    driving, demonstrations, and writing and renaming its files; ``collect/setup_s`` is the set-up part.
    """
    t_start = time.perf_counter()
    cfg = job.config
    seed_everything(job.seed)
    scenario = cfg.scenario if job.scenario is None else replace(cfg.scenario, name=job.scenario)
    scenarios = job.scenarios or Scenarios()
    road = load_road(scenario=scenarios(scenario.name))
    demonstrator = cfg.demonstrator
    driver, road, scenario, replay = _episode_driver(job, road, scenario, make_driver)
    labeller = driver if make_driver is not None else None
    projector = demo_projector(road, cfg)
    out = Path(job.dataset)
    setup = 0.0

    class _SetupClock(ObserverBase):
        def on_reset(self, sim: Simulation, obs: Observation) -> None:
            nonlocal setup
            setup = time.perf_counter() - t_start

    # DAgger with a SUMO demonstrator: SUMO's driver labels from a look ahead (its odometry, projected)
    look_ahead = labeller is not None and demonstrator.kind == SUMO
    source = DEMO_EXPERT if labeller is not None and not look_ahead else DEMO_ODOMETRY
    with replay or demonstrator_simulation(road, scenario, demonstrator, branching=look_ahead) as sim:
        if look_ahead:
            driver.look_ahead_by = sim.look_ahead  # type: ignore[attr-defined]
            driver.lane_offset_by = sim.look_ahead_offset  # type: ignore[attr-defined]
        record = episode_record(job.seed, cfg, job.scenario, scenarios)
        n_features = len(cfg.planner.feature_names)
        with EpisodeWriter(
            out, job.split, job.episode, demo_source=source, record=record, n_features=n_features
        ) as writer:
            recorder, style = CycleRecorder(writer, projector, labeller), StyleObserver()
            runner = EpisodeRunner(
                sim, observers=[_SetupClock(), recorder, style, *observers], max_cycles=cfg.max_cycles
            )
            result = runner.run(driver, job.seed)
    n_cycles = result.cycles
    stats = {**result.stats, **style.summary()}  # the demonstrator's style (irlsim.rollout.style)
    # the writer has closed (both files written and renamed) and SUMO has stopped: the clock covers them
    wall = time.perf_counter() - t_start
    stats.update(
        {
            "collect/split": job.split,
            "collect/episode": job.episode,
            "collect/seed": job.seed,
            **({"collect/scenario": scenarios.identity(job.scenario)} if job.scenario is not None else {}),
            "collect/cycles": n_cycles,
            "collect/setup_s": round(setup, 3),
            "collect/wall_s": round(wall, 3),
            "collect/cycles_per_s": round(n_cycles / max(wall, 1e-9), 2),
            "collect/demo_source": source,
        }
    )
    if labeller is not None:  # how often the learned driver already chose what the expert would
        stats["collect/expert_agreement"] = round(recorder.agree / max(n_cycles, 1), 4)
    # informational, written after the episode's files (which alone make the episode complete): an
    # episode killed just before this line is complete and lacks only its figures
    write_json(out / job.split / stats_name(job.episode), stats)
    return stats
