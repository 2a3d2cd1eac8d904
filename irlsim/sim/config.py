"""Episode settings (``EpisodeConfig``, a config's ``[scenario]`` table): the road it runs on, traffic,
clocks, ego start and episode limits. SI units inside."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from irlsim.config import from_dict, require
from irlsim.errors import IrlsimError
from irlsim.road.scenario import DEFAULT_SCENARIO, Scenarios, load_scenario, scenario_path

MAX_VEHICLES = 15  # the scenario's cap on background vehicles (docs/design/scenario.md)


@dataclass(frozen=True)
class EpisodeConfig:
    """One SUMO episode: the scenario (road and route) it runs on, its traffic, clocks and ego start.

    The ``[scenario]`` table of a config (the table keeps its name: configs and their hashes are
    unchanged). Load from TOML with ``irlsim.config.load_config(EpisodeConfig, path)`` (unknown keys are
    errors). A scenario itself (the road, its route, its ``[defaults]`` of these settings) is
    :class:`irlsim.road.scenario.Scenario`.
    """

    name: str = DEFAULT_SCENARIO
    """the scenario: a shipped name (``irlsim scenario list``) or the path of a scenario.toml"""
    n_vehicles: int = 15
    """number of background vehicles kept around the ego, 0..15"""
    spawn_distance: float = 200.0
    """[m] background vehicles enter about this far ahead of the ego (recycled ones, and those that could
    not be placed at reset); at reset they are spread between ``recycle_behind`` behind the ego and
    spawn_distance + spawn_jitter ahead, as the spawn / recycle cycle leaves them"""
    spawn_jitter: float = 40.0
    """[m] entering vehicles appear at spawn_distance +- spawn_jitter ahead of the ego"""
    spawn_clearance: float = 25.0
    """[m] no vehicle is inserted closer than this (route frame, any lane) to the ego's front bumper"""
    insert_gap: float = 25.0
    """[m] minimum front-to-front distance to any background vehicle in the same lane at insertion"""
    insert_spacing: float = 40.0
    """[m] minimum front-to-front distance to any background vehicle in ANY lane at insertion, so no
    vehicle enters beside another one (side-by-side 'walls' at near-equal speeds would block all lanes
    for tens of seconds); a spot that breaks it is re-drawn, a vehicle that finds none enters later"""
    stop_line_keep_out: float = 40.0
    """[m] no insertion within this distance before a stop line (a vehicle must be able to stop there)"""
    bg_speed_min: float = 25.0 / 3.6
    """[m/s] lowest constant speed of a background vehicle"""
    bg_speed_max: float = 35.0 / 3.6
    """[m/s] highest constant speed of a background vehicle"""
    recycle_behind: float = 600.0
    """[m] a background vehicle further than this behind the ego is removed and re-inserted ahead (the
    span recycle_behind + spawn_distance over 15 vehicles sets the traffic density: ~55 m apart)"""
    bg_stuck_time: float = 10.0
    """[s] a background vehicle standing still (v < stop_speed) longer than this, other than in a
    stop-line queue, counts once in ``sim/bg_stuck``"""
    bg_stuck_queue: float = 60.0
    """[m] standing with the front bumper at most this far before a stop line is queueing, not stuck"""
    step: float = 0.1
    """[s] SUMO simulation step"""
    cycle: float = 0.2
    """[s] planning cycle: the driver plans every cycle / step simulation steps"""
    horizon: float = 5.0
    """[s] planning horizon of the drivers' trajectories"""
    ego_target_speed: float = 70.0 / 3.6
    """[m/s] the ego's desired speed where the road is free"""
    ego_start_random: bool = True
    """draw the ego's start at reset from the episode seed, so episodes of different seeds (train,
    validation, test) do not begin alike: s uniform over the loop edges outside the zones set by the
    two clearances below, lane uniform in {0, 1, 2}, speed uniform in [ego_start_speed_min,
    ego_start_speed_max]; drawn from ``numpy.random.default_rng([seed, 1])``, a stream apart from the
    traffic's, so the same seed gives the same start. false: the fixed ego_start_s / _lane / _speed"""
    ego_start_clearance: float = 150.0
    """[m] a random start lies at least this far along the loop, ahead or behind, from every stop line
    and from where every exit leaves lane 0, so the first seconds need no emergency stop"""
    ego_start_checkpoint_clearance: float = 100.0
    """[m] a random start lies no closer than this before a checkpoint (room to reach its lane)"""
    ego_start_speed_min: float = 5.0
    """[m/s] lowest speed of a random start"""
    ego_start_speed_max: float = 15.0
    """[m/s] highest speed of a random start"""
    ego_start_s: float = 10.0
    """[m] route-frame position of the ego's front bumper at reset when ego_start_random is false
    (0 = start of edge A_S1)"""
    ego_start_lane: int = 1
    """the ego's lane at reset when ego_start_random is false (0 the rightmost, the oval's outer lane;
    a lane the road lacks there: the nearest it has)"""
    ego_start_speed: float = 10.0
    """[m/s] the ego's speed at reset when ego_start_random is false"""
    ego_length: float = 4.5
    """[m] ego box length for the project's collision check (vtype 'ego' in sumo_net/vtypes.add.xml)"""
    ego_width: float = 1.8
    """[m] ego box width"""
    laps: int = 2
    """the episode ends after this many laps of the ego (unwrapped route progress / lap length)"""
    max_time: float = 600.0
    """[s] the episode ends (time-out) after this much simulated time"""
    stop_speed: float = 0.1
    """[m/s] below this the ego (or a background vehicle) counts as stopped"""
    stop_zone: float = 15.0
    """[m] a stop counts for a stop line when the front bumper is at most this far before the line"""
    exit_margin: float = 0.0
    """[m] the ego has taken an exit when, in an exit's ramp zone, d < -(road half width + exit_margin)"""
    end_on_collision: bool = True
    """end the episode at the first ego collision"""

    def validate(self) -> None:
        require(
            0 <= self.n_vehicles <= MAX_VEHICLES,
            f"n_vehicles must be in 0..{MAX_VEHICLES}, got {self.n_vehicles}",
        )
        require(self.spawn_distance > 0, f"spawn_distance must be > 0 m, got {self.spawn_distance}")
        require(0 <= self.spawn_jitter < self.spawn_distance, "spawn_jitter must be in [0, spawn_distance)")
        require(
            self.insert_gap > 0 and self.spawn_clearance > 0, "insert_gap and spawn_clearance must be > 0 m"
        )
        require(self.insert_spacing >= 0, f"insert_spacing must be >= 0 m, got {self.insert_spacing}")
        require(
            0 < self.bg_speed_min <= self.bg_speed_max <= 27.0,
            f"need 0 < bg_speed_min <= bg_speed_max <= 27 m/s, got {self.bg_speed_min}, {self.bg_speed_max}",
        )
        require(self.recycle_behind > 0, f"recycle_behind must be > 0 m, got {self.recycle_behind}")
        require(
            self.bg_stuck_time > 0 and self.bg_stuck_queue >= 0,
            "need bg_stuck_time > 0 s and bg_stuck_queue >= 0 m",
        )
        require(self.step > 0, f"step must be > 0 s, got {self.step}")
        n = self.cycle / self.step
        require(abs(n - round(n)) < 1e-9 and round(n) >= 1, "cycle must be a positive multiple of step")
        require(self.horizon >= self.cycle, "horizon must be >= cycle")
        require(0 < self.ego_target_speed <= 27.78, "ego_target_speed must be in (0, 27.78] m/s")
        require(
            isinstance(self.ego_start_lane, int) and self.ego_start_lane >= 0,
            f"ego_start_lane must be a lane index >= 0 (0 the rightmost), got {self.ego_start_lane}",
        )
        require(self.ego_start_speed >= 0, "ego_start_speed must be >= 0 m/s")
        require(
            self.ego_start_clearance >= 0 and self.ego_start_checkpoint_clearance >= 0,
            "ego_start_clearance and ego_start_checkpoint_clearance must be >= 0 m",
        )
        require(
            0 <= self.ego_start_speed_min <= self.ego_start_speed_max <= 27.78,
            "need 0 <= ego_start_speed_min <= ego_start_speed_max <= 27.78 m/s, got "
            f"{self.ego_start_speed_min}, {self.ego_start_speed_max}",
        )
        require(self.ego_length > 0 and self.ego_width > 0, "ego_length and ego_width must be > 0 m")
        require(self.laps >= 1, f"laps must be >= 1, got {self.laps}")
        require(self.max_time > 0, f"max_time must be > 0 s, got {self.max_time}")
        require(self.stop_speed > 0 and self.stop_zone > 0, "stop_speed and stop_zone must be > 0")

    def __post_init__(self) -> None:
        self.validate()

    @classmethod
    def with_defaults(cls, data: dict[str, Any], scenarios: Scenarios | None = None) -> dict[str, Any]:
        """The data with its scenario file's ``[defaults]`` beneath it (``load_config``'s hook)."""
        return with_scenario_defaults(data, scenarios)

    @classmethod
    def defaults_source(cls, data: dict[str, Any]) -> str | None:
        """Where ``with_defaults`` took values from (``load_config`` names it for a bad one)."""
        return defaults_source(data)

    @property
    def steps_per_cycle(self) -> int:
        return int(round(self.cycle / self.step))

    @property
    def horizon_steps(self) -> int:
        """T - 1: the number of steps a driver's trajectory covers."""
        return int(round(self.horizon / self.step))


#: the old name of :class:`EpisodeConfig` (deprecated: it said "scenario", which is the road's file);
#: kept so that code importing it still runs
ScenarioConfig = EpisodeConfig


def with_scenario_defaults(table: dict[str, Any], scenarios: Scenarios | None = None) -> dict[str, Any]:
    """A ``[scenario]`` table with the named scenario file's ``[defaults]`` beneath it (the table's own
    keys win); a table without a name gets the default scenario's. ``scenarios``: the command's, which
    reads the file once for the config and the road (None: read here)."""
    name = table.get("name", DEFAULT_SCENARIO)
    if not isinstance(name, str):  # not a name: its own line when the config is built
        return table
    scn = scenarios(name, build=False) if scenarios is not None else load_scenario(name, build=False)
    defaults = scn.defaults
    unknown = sorted(set(defaults) - {f for f in EpisodeConfig.__dataclass_fields__} - {"name"})
    if unknown or "name" in defaults:
        bad = unknown[0] if unknown else "name"
        raise IrlsimError(
            f"scenario {name}: [defaults] has '{bad}', which is not an episode setting (irlsim.sim.config."
            "EpisodeConfig): fix the scenario file"
        )
    return {**defaults, **table}


def defaults_source(table: dict[str, Any]) -> str | None:
    """The scenario file whose ``[defaults]`` :func:`with_scenario_defaults` puts beneath ``table``, as an
    error line names it (None: none, or a name that is no scenario: that has its own line)."""
    name = table.get("name", DEFAULT_SCENARIO)
    if not isinstance(name, str):
        return None
    try:
        return f"scenario {scenario_path(name)} [defaults]"
    except IrlsimError:
        return None


def scenario_config(name: str, scenarios: Scenarios | None = None, **overrides: Any) -> EpisodeConfig:
    """The episode settings for scenario ``name``: its file's ``[defaults]``, then ``overrides``; a bad
    value of the ``[defaults]`` is one line naming the scenario file. ``scenarios``: the command's (the
    file read once), None: read here."""
    table = {**overrides, "name": name}
    try:
        return from_dict(EpisodeConfig, with_scenario_defaults(table, scenarios))
    except IrlsimError as e:
        source = defaults_source(table)
        if source is None or not str(e).startswith("config: "):
            raise
        try:
            from_dict(EpisodeConfig, table)
        except IrlsimError:
            raise e from None  # not the defaults' value
        raise IrlsimError(f"config: {source}: {str(e).removeprefix('config: ')}") from None
