"""Demonstrators: who drives while a dataset is collected. A demonstrator is a source of odometry; every
planning cycle the expert's planner samples its policy set at the ego's state, and the demonstration is
the projection of what the demonstrator then drove over the horizon (:class:`irlsim.data.demos.DemoProjector`,
the same rules and distances whoever drives).

- ``expert`` (the default): irlsim's expert (:class:`irlsim.planner.expert.ExpertDriver`). A dataset of
  the expert records no demonstrator: its manifest keeps the bytes of before.
- ``sumo``: SUMO's own car-following and lane-change models drive the ego on the scenario's route
  (:class:`SumoDemonstrator`), with any vType attributes (``params``, or the one vType of
  ``vtype_file``), checked by SUMO before any work (:func:`irlsim.sim.vtype.check_vtype`).
- ``recording``: recorded vehicles (SUMO's FCD output or a columnar file, :mod:`irlsim.data.recording`),
  each an ego in turn while the others replay their recorded motion (:mod:`irlsim.data.recorded`).
"""

from __future__ import annotations

import hashlib
import json
import math
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from irlsim.config import STORED_IF_SET, require
from irlsim.data.recorded import RATE_WINDOW, open_recording, recorded_size
from irlsim.data.recorded import egos as recorded_egos
from irlsim.data.recording_as import (
    COORDINATES,
    EGO_CLASS,
    EGO_SIZES,
    FRONT,
    NETWORK,
    POSITIONS,
    SCENARIO_SIZE,
    ReadAs,
)
from irlsim.errors import IrlsimError
from irlsim.planner.config import PlannerConfig
from irlsim.planner.planner import Planner
from irlsim.planner.policy_set import PolicySet
from irlsim.road import Road, load_road
from irlsim.road.scenario import Scenario
from irlsim.sim.branch import BranchingSimulation
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.drivers import SumoDriver
from irlsim.sim.simulation import Simulation
from irlsim.sim.types import Observation, Trajectory
from irlsim.sim.vehicle_types import type_file
from irlsim.sim.vtype import MODEL_KEYS, check_vtype, read_vtype_file, vtype_attributes

#: SUMO's models of a vType that names none (sumo.dlr.de, "Vehicle Type Parameter Defaults")
SUMO_DEFAULT_MODELS = {"carFollowModel": "Krauss", "laneChangeModel": "LC2013"}
EXPERT = "expert"
SUMO = "sumo"
RECORDING = "recording"
KINDS = (EXPERT, SUMO, RECORDING)
#: the fields of one kind alone: a manifest records only its own kind's (a SUMO demonstrator's config
#: keeps the bytes of before recordings existed)
SUMO_FIELDS = ("car_follow_model", "lane_change_model", "params", "vtype_file", "lane_change_duration")
RECORDING_FIELDS = (
    "file", "ego", "min_duration", "rate_window", "position", "coordinates", "ego_classes", "ego_size",
)  # fmt: skip
#: a SUMO demonstrator's record key: its lane-change model and attributes drove the ego. A record without it
#: was collected by an irlsim that inserted the ego with its own type, so that SUMO kept LC2013 with every
#: lane-change attribute at its default whatever the record says (:data:`irlsim.sim.vtype.PLACED_TYPE`)
LANE_CHANGES_APPLIED = "lane_changes_applied"
#: how :func:`describe` names such a record, and the end of its :func:`identity`
NOT_APPLIED = " (collected with its lane-change attributes not in effect: SUMO's LC2013 defaults drove)"
OLD_IDENTITY = "~lc-defaults"


@dataclass(frozen=True)
class DemonstratorConfig:
    """A collect config's ``[demonstrator]``: who drives (docs/guide/demonstrators.md)."""

    kind: str = EXPERT
    """'expert' (irlsim's expert), 'sumo' (SUMO's driver models) or 'recording' (recorded vehicles)"""
    car_follow_model: str = ""
    """kind 'sumo': SUMO's carFollowModel (Krauss, IDM, EIDM, ACC, CACC, ...; SUMO decides); empty:
    ``vtype_file``'s, else SUMO's default, Krauss"""
    lane_change_model: str = ""
    """kind 'sumo': SUMO's laneChangeModel (LC2013, SL2015, ...); empty: ``vtype_file``'s, else SUMO's
    default, LC2013"""
    params: dict[str, Any] = field(default_factory=dict)
    """kind 'sumo': vType attributes over irlsim's ego type, e.g. {tau = 1.5, accel = 2.0} (SI units as
    SUMO takes them: s, m/s^2, m)"""
    vtype_file: str = ""
    """kind 'sumo': an additional file with one <vType>, whose attributes come first (``params`` and
    the two models then over them); read when the collection starts and recorded as its attributes
    and sha256"""
    lane_change_duration: float = field(default=0.0, metadata={STORED_IF_SET: True})
    """kind 'sumo': [s] how long a lane change takes (SUMO's ``--lanechange.duration``, for every vehicle
    of the demonstrator's episodes): the lateral move spread over this time, as a driver steers; 0:
    SUMO's default, a lane change within one simulation step (a jump of a lane width)"""
    file: str = ""
    """kind 'recording': the recording, SUMO's FCD output (.xml) or a columnar file (.csv, .parquet) on
    the scenario's network (docs/guide/demonstrators.md, "Recordings")"""
    ego: str = ""
    """kind 'recording': the ego vehicles' ids, separated by commas, one per episode in turn (train,
    then validation, then test); empty: every vehicle on a route of the network for ``min_duration``"""
    min_duration: float = 20.0
    """kind 'recording': [s] the least time a vehicle drives on its route to be an ego"""
    rate_window: float = RATE_WINDOW
    """kind 'recording': [s] the window of the local quadratic fit that gives the recorded ego's
    acceleration and lateral rates, the state its policy sets start from (a tracker's position noise
    taken by finite differences starts them metres off); 0: finite differences over one step"""
    position: str = field(default=FRONT, metadata={STORED_IF_SET: True})
    """kind 'recording': the point of a vehicle the recording's x, y give: 'front' (its front bumper's
    centre, SUMO's convention; an FCD file's by definition) or 'centre' (the centre of its box, as most
    public datasets' tracks; needs the columnar format's length column: each row moves half the length
    along the heading)"""
    coordinates: str = field(default=NETWORK, metadata={STORED_IF_SET: True})
    """kind 'recording': what the recording's x, y are: 'network' (the network's coordinates, as SUMO's
    FCD), 'geo' (longitude and latitude in degrees, as ``sumo --fcd-output.geo`` or a GPS track: SUMO
    places them through the network's projection, which a network imported from OpenStreetMap has) or
    'utm' (the network's projection before its netOffset, as ``sumo --fcd-output.utm``)"""
    vehicle_types: tuple[str, ...] = field(default=(), metadata={STORED_IF_SET: True})
    """kind 'recording': the files that define the vehicle types the recording names (FCD's ``type``,
    a ``type`` column; the route or additional files its SUMO run loaded, ``sumo_tools/...`` inside the
    eclipse-sumo wheel): each vehicle's length, width and class are then its type's as SUMO makes it
    (a size column wins), and only vehicles of a car's class are egos; empty: not read (every vehicle
    replays at the replay type's size)"""
    ego_classes: tuple[str, ...] = field(default=(EGO_CLASS,), metadata={STORED_IF_SET: True})
    """kind 'recording': the SUMO vehicle classes whose vehicles may be egos (their types' classes, read
    with ``vehicle_types``), e.g. ["truck"]; default a car's ("passenger")"""
    ego_size: str = field(default=SCENARIO_SIZE, metadata={STORED_IF_SET: True})
    """kind 'recording': the size an ego is planned, driven and checked for collisions at: 'scenario'
    (the scenario's ego size, 4.5 m by 1.8 m, whatever was recorded) or 'recorded' (each ego's own recorded
    length and width: the file's columns or its type's); a class other than a car's needs 'recorded'"""

    def validate(self) -> None:
        require(self.kind in KINDS, f"demonstrator.kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        bad = next((k for k, v in self.params.items() if not isinstance(v, (int, float, str, bool))), None)
        require(bad is None, f"demonstrator.params.{bad} must be a number or a string (a vType attribute)")
        require(
            math.isfinite(self.min_duration) and self.min_duration > 0,
            f"demonstrator.min_duration must be a number > 0 s, got {self.min_duration}",
        )
        require(
            math.isfinite(self.rate_window) and self.rate_window >= 0,
            f"demonstrator.rate_window must be a number >= 0 s, got {self.rate_window}",
        )
        require(
            math.isfinite(self.lane_change_duration) and self.lane_change_duration >= 0,
            f"demonstrator.lane_change_duration must be a number >= 0 s, got {self.lane_change_duration}",
        )
        if self.kind != SUMO:
            require(
                not self.lane_change_duration,
                "demonstrator.lane_change_duration belongs to kind = 'sumo': set it, or drop it",
            )
            require(
                not self.params and not self.vtype_file,
                "demonstrator.params / vtype_file belong to kind = 'sumo': set it, or drop them",
            )
            require(
                self.kind == EXPERT or not (self.car_follow_model or self.lane_change_model),
                "demonstrator car_follow_model / lane_change_model belong to kind = 'sumo': drop them",
            )
        require(
            self.position in POSITIONS,
            f"demonstrator.position must be one of {', '.join(POSITIONS)}, got {self.position!r}",
        )
        require(
            self.coordinates in COORDINATES,
            f"demonstrator.coordinates must be one of {', '.join(COORDINATES)}, got {self.coordinates!r}",
        )
        require(
            self.ego_size in EGO_SIZES,
            f"demonstrator.ego_size must be one of {', '.join(EGO_SIZES)}, got {self.ego_size!r}",
        )
        if self.kind != RECORDING:
            require(
                not self.file
                and not self.ego
                and self.rate_window == RATE_WINDOW
                and self.position == FRONT
                and self.coordinates == NETWORK
                and not self.vehicle_types
                and tuple(self.ego_classes) == (EGO_CLASS,)
                and self.ego_size == SCENARIO_SIZE,
                "demonstrator.file / ego / rate_window / position / coordinates / vehicle_types / "
                "ego_classes / ego_size belong to kind = 'recording': set it, or drop them",
            )
            return
        require(
            bool(self.file), "demonstrator kind = 'recording' needs file = 'an FCD .xml, .csv or .parquet'"
        )
        self._validate_egos()

    def _validate_egos(self) -> None:
        classes = tuple(self.ego_classes)
        require(
            bool(classes) and all(isinstance(c, str) and c for c in classes),
            f"demonstrator.ego_classes must be SUMO vehicle classes, e.g. ['truck'], got {list(classes)}",
        )
        require(
            classes == (EGO_CLASS,) or bool(self.vehicle_types),
            "demonstrator.ego_classes are the recorded types' classes: give demonstrator.vehicle_types",
        )
        other = [c for c in classes if c != EGO_CLASS]
        require(
            not other or self.ego_size != SCENARIO_SIZE,
            f"an ego of class {other[0] if other else ''} would be planned at a car's size: set "
            "demonstrator.ego_size = 'recorded'",
        )

    def read_as(self) -> ReadAs:
        """How a recording demonstrator's file is read."""
        return ReadAs(
            self.position, tuple(self.vehicle_types), self.coordinates, tuple(self.ego_classes), self.ego_size
        )

    def read_unlike_fcd(self) -> dict[str, Any]:
        """What a record (the manifest's, drive.json's) says of how the recording was read where not as
        SUMO's FCD is: its positions' point, its coordinates (the type files each record names its way)."""
        fields: dict[str, tuple[Any, Any]] = {
            "position": (self.position, FRONT),
            "coordinates": (self.coordinates, NETWORK),
            "ego_classes": (list(self.ego_classes), [EGO_CLASS]),
            "ego_size": (self.ego_size, SCENARIO_SIZE),
        }
        return {k: value for k, (value, default) in fields.items() if value != default}

    def attributes(self) -> dict[str, Any]:
        """The vType attributes this demonstrator sets: the file's, then the models, then ``params``."""
        base = {**SUMO_DEFAULT_MODELS, **(read_vtype_file(self.vtype_file) if self.vtype_file else {})}
        models = zip(MODEL_KEYS, (self.car_follow_model, self.lane_change_model), strict=True)
        return {**base, **{k: v for k, v in models if v}, **self.params}


def resolve(
    cfg: DemonstratorConfig,
    scenarios: tuple[Scenario, ...],
    step: float = 0.1,
    episodes: int = 0,
) -> tuple[DemonstratorConfig, dict[str, Any]]:
    """Before any work: the demonstrator with its ``vtype_file`` read into ``params`` (what the workers
    get and the manifest's config records), and its manifest record (kind, models, params, the file's
    path and sha256); SUMO's refusal of the type (on the first network of ``scenarios``, the roads the
    command loaded) as one line (:func:`irlsim.sim.vtype.check_vtype`). A recording (kind 'recording',
    on the one scenario of ``scenarios``, ``episodes`` episodes at the simulation ``step``): see
    :func:`resolve_recording`."""
    cfg.validate()
    if cfg.kind == EXPERT:
        return cfg, {"kind": EXPERT}
    if cfg.kind == RECORDING:
        require(
            len(scenarios) == 1,
            f"a recording is on one scenario's network, this config lists {len(scenarios)}: give [scenario] "
            "name",
        )
        return resolve_recording(cfg, load_road(scenario=scenarios[0]), step, episodes)
    attrs = cfg.attributes()
    with tempfile.TemporaryDirectory(prefix="irlsim-check-") as tmp:
        check_vtype(scenarios[0].net_file, vtype_attributes(attrs, 1.0), Path(tmp))
    params = {k: _canonical(v) for k, v in attrs.items() if k not in MODEL_KEYS}
    out = replace(
        cfg,
        car_follow_model=str(attrs["carFollowModel"]),
        lane_change_model=str(attrs["laneChangeModel"]),
        params=params,
        vtype_file="",
    )
    record: dict[str, Any] = {
        "kind": SUMO,
        "car_follow_model": out.car_follow_model,
        "lane_change_model": out.lane_change_model,
        "params": params,
        LANE_CHANGES_APPLIED: True,
    }
    if cfg.lane_change_duration:
        record["lane_change_duration"] = cfg.lane_change_duration
    if cfg.vtype_file:
        data = Path(cfg.vtype_file).read_bytes()
        record["vtype_file"] = {"path": str(cfg.vtype_file), "sha256": hashlib.sha256(data).hexdigest()}
    return out, record


def resolve_recording(
    cfg: DemonstratorConfig, road: Road, step: float, episodes: int
) -> tuple[DemonstratorConfig, dict[str, Any]]:
    """A recording read and checked on ``road`` (its scenario's, as the command loaded it; one line
    before any work), its egos (``ego``, else every vehicle long enough) written into ``ego``, and the
    manifest record: kind, the file's path and sha256, the egos."""
    rec = open_recording(cfg.file, road, step, cfg.read_as())
    wanted = tuple(v.strip() for v in cfg.ego.split(",") if v.strip())
    refused: dict[str, int] = {}
    ids = recorded_egos(rec, road, wanted, cfg.min_duration, refused, tuple(cfg.ego_classes))
    if cfg.ego_size != SCENARIO_SIZE and ids:
        recorded_size(rec, ids[0])  # one line now, not in an episode, where it has no sizes
    if refused:  # every vehicle was asked: say which were not egos, and why
        why = ", ".join(f"{n} {words}" for words, n in sorted(refused.items(), key=lambda kv: -kv[1]))
        print(f"recording {cfg.file}: {len(ids)} of {len(rec.ids)} vehicles are egos; not: {why}", flush=True)
    if len(ids) < episodes:
        raise IrlsimError(
            f"recording {cfg.file} gives {len(ids)} ego(s) (vehicles on a route of the network for "
            f"min_duration {cfg.min_duration:g} s), the config asks for {episodes} episodes: ask for at most "
            f"{len(ids)} episodes (one per ego), or lower demonstrator.min_duration"
        )
    out = replace(cfg, ego=",".join(ids))
    record: dict[str, Any] = {"kind": RECORDING, "file": cfg.file, "sha256": rec.sha256, "egos": list(ids)}
    record |= cfg.read_unlike_fcd()
    if cfg.vehicle_types:  # each file by content, as the recording
        record["vehicle_types"] = [
            {"path": f, "sha256": hashlib.sha256(type_file(f).read_bytes()).hexdigest()}
            for f in cfg.vehicle_types
        ]
    return out, record


def recorded_ego(cfg: DemonstratorConfig, counts: dict[str, int], split: str, episode: int) -> str:
    """The ego of episode ``episode`` of ``split`` (``counts``: the episodes of each split, in the order
    of the splits): the resolved egos in turn, train, then validation, then test."""
    names = list(counts)
    return cfg.ego.split(",")[sum(counts[s] for s in names[: names.index(split)]) + episode]


def collected_egos(manifest: dict[str, Any]) -> tuple[str, list[str]] | None:
    """The recorded vehicles a dataset's episodes drove as egos, every split (``manifest``: the dataset's),
    with the recording's sha256; None where its demonstrator is no recording. The manifest lists the
    egos the recording gave in the order episodes take them (:func:`recorded_ego`); only the first of
    them, as many as the config's episodes, were collected."""
    record = manifest.get("demonstrator") or {}
    if record.get("kind") != RECORDING:
        return None
    config = manifest.get("config") or {}
    n = sum(int(config.get(f"{split}_episodes") or 0) for split in ("train", "validation", "test"))
    return str(record["sha256"]), [str(v) for v in record["egos"][:n]]


def as_recorded(d: dict[str, Any]) -> dict[str, Any]:
    """A demonstrator's config as a manifest records it: only its own kind's fields."""
    drop = SUMO_FIELDS if d.get("kind") == RECORDING else RECORDING_FIELDS
    return {k: v for k, v in d.items() if k not in drop}


def _canonical(value: Any) -> Any:
    """A vType attribute as recorded: a number (TOML's or a file's text) as a float, other text as it
    is; so ``tau = 1.5`` in the config and ``tau="1.5"`` in a vType file are the same demonstrator."""
    if isinstance(value, bool):
        return value
    try:
        x = float(value)
    except ValueError:
        return value
    return x if math.isfinite(x) else value


def describe(record: dict[str, Any] | None) -> str:
    """One short name of a recorded demonstrator: 'expert', 'sumo IDM/LC2013 {tau=1.5}'."""
    if not record or record.get("kind", EXPERT) == EXPERT:
        return EXPERT
    if record.get("kind") == RECORDING:
        n = len(record.get("egos") or [])
        read = [f"positions at the {record['position']}"] if record.get("position") else []
        read += [f"{record['coordinates']} coordinates"] if record.get("coordinates") else []
        read += [f"types of {len(record['vehicle_types'])} file(s)"] if record.get("vehicle_types") else []
        read += [f"egos of class {', '.join(record['ego_classes'])}"] if record.get("ego_classes") else []
        read += [f"egos at their {record['ego_size']} size"] if record.get("ego_size") else []
        how = "".join(f", {r}" for r in read)
        return f"recording {record.get('file')} (sha256 {str(record.get('sha256'))[:12]}, {n} egos{how})"
    params = shown_params(record)
    text = ",".join(f"{k}={v}" for k, v in sorted(params.items()) if k != "maxSpeed")
    return (
        f"sumo {record.get('car_follow_model')}/{record.get('lane_change_model')}"
        + (f" {{{text}}}" if text else "")
        + ("" if record.get(LANE_CHANGES_APPLIED) else NOT_APPLIED)
    )


def shown_params(record: dict[str, Any]) -> dict[str, Any]:
    """A SUMO demonstrator's attributes as its name shows them: the vType's, and a lane change duration
    other than SUMO's default as ``lanechange.duration`` (SUMO's option)."""
    params = dict(record.get("params") or {})
    if record.get("lane_change_duration"):
        params["lanechange.duration"] = record["lane_change_duration"]
    return params


#: a SUMO demonstrator's identity longer than this is its models and a digest of its attributes
MAX_IDENTITY = 64


def identity(record: dict[str, Any] | None) -> str:
    """The one identity string of a recorded demonstrator (a manifest's ``demonstrator``; None or no
    record: the expert), which ``--demonstrator-select`` takes and breakdowns name: ``expert``,
    ``sumo:IDM/LC2013{accel=2,tau=1.5}`` (attributes sorted; beyond ``MAX_IDENTITY`` characters
    ``sumo:IDM/LC2013#<sha256 prefix of the attributes>``), ``recording:<file's sha256 prefix>``. Every
    episode of a dataset is its manifest's demonstrator."""
    rec = record or {}
    kind = rec.get("kind", EXPERT)
    if kind == EXPERT:
        return EXPERT
    if kind == RECORDING:
        return f"{RECORDING}:{str(rec.get('sha256'))[:12]}"
    models = f"{SUMO}:{rec.get('car_follow_model')}/{rec.get('lane_change_model')}"
    params = shown_params(rec)
    text = models + "{" + ",".join(f"{k}={_short(v)}" for k, v in sorted(params.items())) + "}"
    old = "" if rec.get(LANE_CHANGES_APPLIED) else OLD_IDENTITY  # another driver than the one it names
    if len(text) <= MAX_IDENTITY:
        return text + old
    digest = hashlib.sha256(json.dumps(params, sort_keys=True, default=str).encode()).hexdigest()
    return f"{models}#{digest[:12]}{old}"


def identity_kind(ident: str) -> str:
    """The kind of a demonstrator's identity ('expert', 'sumo', 'recording')."""
    return ident.split(":", 1)[0]


def _short(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


class SumoDemonstrator:
    """SUMO's driver models drive the ego (a :class:`SumoDriver` with the simulation's demonstrator
    type); every cycle the expert's planner samples the policy set at the ego's state, which collection
    records. No policy of the set is executed: ``last_index`` is -1 and the writer records the policy
    closest to what was driven as the executed one."""

    def __init__(self, road: Road, planner: PlannerConfig, scenario: EpisodeConfig):
        self.planner = Planner(road, planner)
        self.sumo = SumoDriver(road, scenario)
        self.last_policy_set: PolicySet | None = None
        self.last_index = -1

    def plan(self, obs: Observation) -> Trajectory:
        self.last_policy_set = self.planner.plan(obs)
        return self.sumo.plan(obs)


def demo_vtype(cfg: DemonstratorConfig, scenario: EpisodeConfig) -> dict[str, str] | None:
    """The vType attributes a worker's :class:`~irlsim.sim.simulation.Simulation` gets (None: the
    expert); ``maxSpeed`` defaults to the scenario's ego target speed."""
    if cfg.kind != SUMO:
        return None
    return vtype_attributes(cfg.attributes(), scenario.ego_target_speed)


def demonstrator_simulation(
    road: Road, scenario: EpisodeConfig, demonstrator: DemonstratorConfig, branching: bool = False
) -> Simulation:
    """An episode's simulation: a SUMO demonstrator's vehicle type and lane change duration (none of
    either for the expert); ``branching``: one that looks ahead with SUMO's driver (DAgger's SUMO
    labeller, :class:`irlsim.sim.branch.BranchingSimulation`)."""
    return (BranchingSimulation if branching else Simulation)(
        road,
        scenario,
        demo_vtype=demo_vtype(demonstrator, scenario),
        lane_change_duration=demonstrator.lane_change_duration,
    )
