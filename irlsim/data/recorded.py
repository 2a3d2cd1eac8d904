"""The recording demonstrator: recorded vehicles as demonstrators, each an ego in turn (log replay).

For an ego vehicle of a recording (:mod:`irlsim.data.recording`): the route it drove (the scenario's
route when every edge it drove lies on it, else a :class:`~irlsim.road.Road` of its edges: its recorded
lanes' edges, or without lanes the route its positions match, :mod:`irlsim.data.matching`),
an episode on a :class:`~irlsim.sim.replay.ReplaySimulation` where the other recorded vehicles replay
their motion (non-reactive) and the ego is placed every step at its recorded pose
(:class:`RecordingDemonstrator`); every cycle the expert's planner samples its policy set at the ego's
state, and the demonstration is the projection of the ego's recorded odometry. A vehicle is an ego when
it stays on its route (within half a lane of the road's edges) for ``min_duration`` from its first point
outside a junction.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.data.recording import Recording, load_recording
from irlsim.data.recording_as import AS_RECORDED, EGO_CLASS, RECORDED_SIZE, ReadAs
from irlsim.errors import IrlsimError
from irlsim.planner.config import PlannerConfig
from irlsim.planner.planner import Planner
from irlsim.planner.policy_set import PolicySet
from irlsim.road import Road
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.replay import ReplaySimulation, Tracks
from irlsim.sim.traffic import LoopEdges, wrap_route
from irlsim.sim.types import EgoState, Observation, Trajectory
from irlsim.sim.vehicle_types import vehicle_types

#: the episode of a recorded ego ends with its recording, never on laps
LAPS = 1_000_000
#: [s] the default window of the recorded ego's rates (:func:`local_rates`; ``demonstrator.rate_window``):
#: chosen on development recordings with tracker-like noise (docs/guide/demonstrators.md, "Recordings")
RATE_WINDOW = 2.0


#: per process: the recordings read, by (file, its mtime, the network, step, how read); the last two kept
_RECORDINGS: dict[tuple[str, float, str, float, ReadAs], Recording] = {}


def open_recording(path: str | Path, road: Road, step: float, read: ReadAs = AS_RECORDED) -> Recording:
    """The recording ``path`` on the network of ``road`` (the scenario's, as the command loaded it),
    read as ``read`` says (its positions' point, its vehicle types asked of SUMO with the road's
    network), checked and resampled to ``step`` (read once per process)."""
    p = Path(path)
    if not p.is_file():
        raise IrlsimError(f"recording {p} not found: give the path of an FCD .xml, a .csv or a .parquet file")
    key = (str(p.resolve()), p.stat().st_mtime, str(Path(road.net_file).resolve()), step, read)
    if key not in _RECORDINGS:
        types = vehicle_types(road.net_file, read.vehicle_types) if read.vehicle_types else None
        _RECORDINGS[key] = load_recording(
            key[0],
            road.net,
            step,
            position=read.position,
            types=types,
            coordinates=read.coordinates,
            net_file=road.net_file,
        )
        while len(_RECORDINGS) > 2:
            del _RECORDINGS[next(iter(_RECORDINGS))]
    return _RECORDINGS[key]


@dataclass(frozen=True)
class EgoTrack:
    """A recorded ego at the step from its first point outside a junction: its route and its states."""

    vid: str
    road: Road
    t0: float  # [s] recording time of the first state
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    v: np.ndarray
    s: np.ndarray  # unwrapped route position [m]
    d: np.ndarray
    step: float  # [s]

    @property
    def duration(self) -> float:
        """[s] from the first state to the last."""
        return (len(self.x) - 1) * self.step


def _without_demand(road: Road) -> Road:
    """The scenario's road without its own SUMO demand: the recording is the traffic."""
    if not road.demand:
        return road
    out = copy.copy(road)
    out.demand, out.warmup = (), 0.0
    return out


def ego_track(
    rec: Recording,
    vid: str,
    scenario_road: Road,
    routes: dict[tuple[str, ...], Road | str] | None = None,
    classes: tuple[str, ...] = (EGO_CLASS,),
) -> EgoTrack | str:
    """Vehicle ``vid`` of ``rec`` as an ego, or why it cannot be one (a phrase). ``routes``: the roads
    of the routes met so far (or why each is none), shared by the vehicles that drove the same edges;
    ``classes``: the SUMO classes of the egos (where the types were read)."""
    k = rec.ids.index(vid)
    why = rec.unrouted[k] if rec.unrouted else ""
    if rec.vclass and rec.vclass[k] not in classes:
        why = (
            f"it is of class {rec.vclass[k]} (its type's), not the ego's ({EGO_CLASS})"
            if classes == (EGO_CLASS,)
            else f"it is of another class, {rec.vclass[k]} (its type's), than the egos' ({'/'.join(classes)})"
        )
    if why:
        return why if why.startswith("it ") else f"it drove no connected route of the network ({why})"
    road = scenario_road
    if rec.edges[k] and not set(rec.edges[k]) <= set(scenario_road.edges):
        own = (routes or {}).get(rec.edges[k])
        if own is None:
            try:
                own = Road(
                    scenario_road.net_file,
                    rec.edges[k],
                    name=scenario_road.name,
                    additional=scenario_road.additional,
                )
            except IrlsimError as e:
                own = f"its recorded edges are no route of the network ({e})"
            if routes is not None:
                routes[rec.edges[k]] = own
        if isinstance(own, str):
            return own
        road = copy.copy(own)
        road.name = f"{scenario_road.name}:{vid}"
    road = _without_demand(road)
    tr = rec.track(vid)
    s_w, d = road.to_frenet(tr["x"], tr["y"])
    s = s_w[0] + np.concatenate([[0.0], np.cumsum(wrap_route(np.diff(s_w), road.lap_length))])
    off = np.flatnonzero(np.abs(d) > road.half_road + 0.5 * road.lane_width)
    if len(off):
        return f"it leaves its route at t = {tr['t'][off[0]]:g} s"
    edges = LoopEdges.from_road(road)
    first = next((i for i, si in enumerate(s) if edges.locate(float(si), road.lap_length)), None)
    if first is None:
        return "it never leaves a junction"
    cut = slice(first, None)
    return EgoTrack(
        vid,
        road,
        float(tr["t"][first]),
        tr["x"][cut],
        tr["y"][cut],
        tr["heading"][cut],
        tr["v"][cut],
        s[cut],
        d[cut],
        rec.step,
    )


#: why a vehicle is no ego, by how the phrase begins (:func:`ego_track`, :func:`egos`) -> a few words
NOT_EGO = (
    ("it is of class", "of another class than a car"),
    ("it is of another class", "of another class than the egos'"),
    ("it drove on lane", "on lanes a car may not use"),
    ("it is recorded", "recorded under min_duration on their route"),
    ("it leaves its route", "leaving their route"),
    ("it never leaves a junction", "within a junction only"),
)


def not_ego(why: str) -> str:
    """The few words :func:`egos` counts a vehicle's reason under (a route of the network for the rest)."""
    return next((words for start, words in NOT_EGO if why.startswith(start)), "on no connected route")


def egos(
    rec: Recording,
    scenario_road: Road,
    wanted: tuple[str, ...],
    min_duration: float,
    refused: dict[str, int] | None = None,
    classes: tuple[str, ...] = (EGO_CLASS,),
    routes: dict[tuple[str, ...], Road | str] | None = None,
) -> list[str]:
    """The ego vehicles of ``rec``: ``wanted`` (each refused in one line unless it can be one), else every
    vehicle that can be one for ``min_duration`` seconds, in the recording's order; ``refused`` counts the
    others by their reason (:func:`not_ego`); ``classes``: the SUMO classes of the egos; ``routes``: the
    roads of the routes met (:func:`ego_track`), kept for the caller where given."""
    unknown = [v for v in wanted if v not in rec.ids]
    if unknown:
        raise IrlsimError(
            f"recording {rec.path} has no vehicle {unknown[0]!r}: name one of {', '.join(rec.ids[:8])}"
            + (", ..." if len(rec.ids) > 8 else "")
        )
    out: list[str] = []
    routes = {} if routes is None else routes
    for vid in wanted or rec.ids:
        et = ego_track(rec, vid, scenario_road, routes, classes)
        why = et if isinstance(et, str) else None
        if why is None and isinstance(et, EgoTrack) and et.duration < min_duration:
            why = (
                f"it is recorded {et.duration:.1f} s on its route, less than min_duration {min_duration:g} s"
            )
        if why is None:
            out.append(vid)
        elif wanted:
            fix = " or lower demonstrator.min_duration" if why.startswith("it is recorded") else ""
            raise IrlsimError(
                f"recording {rec.path}: vehicle {vid} cannot be an ego: {why}: choose another{fix}"
            )
        elif refused is not None:
            refused[not_ego(why)] = refused.get(not_ego(why), 0) + 1
    return out


def recorded_size(rec: Recording, vid: str) -> tuple[float, float]:
    """[m] the recorded length and width of ``vid``; one line where the recording has none."""
    if not {"length", "width"} <= rec.size.keys():
        raise IrlsimError(
            f"recording {rec.path}: demonstrator.ego_size = 'recorded' needs each vehicle's length and "
            "width: give the file length and width columns, or demonstrator.vehicle_types"
        )
    k = rec.ids.index(vid)
    return float(rec.size["length"][k]), float(rec.size["width"][k])


def ego_sized(planner: PlannerConfig, scenario: EpisodeConfig) -> PlannerConfig:
    """``planner`` at the episode's ego size (a recorded ego's own, ``ego_size = 'recorded'``)."""
    return dataclasses.replace(planner, ego_length=scenario.ego_length, ego_width=scenario.ego_width)


def others(rec: Recording, vid: str) -> Tracks:
    """Every recorded vehicle but ``vid``, for the replay."""
    keep = np.array([v != vid for v in rec.ids])
    n = np.diff(rec.start)
    rows = np.repeat(keep, n)
    return Tracks(
        ids=tuple(v for v in rec.ids if v != vid),
        start=np.concatenate([[0], np.cumsum(n[keep])]),
        t0=rec.t0[keep],
        x=rec.x[rows],
        y=rec.y[rows],
        heading=rec.heading[rows],
        v=rec.v[rows],
        step=rec.step,
        edges=tuple(e for e, k in zip(rec.edges, keep, strict=True) if k),
        size={c: col[keep] for c, col in rec.size.items()},
    )


def local_rates(z: np.ndarray, dt: float, window: float) -> tuple[np.ndarray, np.ndarray]:
    """The first and second time derivative of ``z`` (samples ``dt`` [s] apart) at every sample: the slope
    and curvature of a quadratic fitted by least squares to the samples within ``window`` [s] centred on it
    (a Savitzky-Golay filter; the first and last half windows take the fit of the first and last whole
    window), so that a recording's position noise of sigma [m] enters the first derivative as about
    sigma / (dt * sqrt(sum k^2)) instead of finite differences' sigma / (dt * sqrt 2). ``window`` under
    three samples (0: none): finite differences (``np.gradient``, twice for the second)."""
    z = np.asarray(z, dtype=np.float64)
    n = len(z)
    h = min(int(round(window / (2.0 * dt))), (n - 1) // 2)
    if h < 1:
        first = np.gradient(z, dt) if n > 1 else np.zeros_like(z)
        return first, np.gradient(first, dt) if n > 1 else np.zeros_like(z)
    tk = np.arange(-h, h + 1) * dt
    fit = np.linalg.pinv(np.stack([np.ones_like(tk), tk, tk * tk], axis=1))  # [3, 2h + 1]
    c = np.lib.stride_tricks.sliding_window_view(z, 2 * h + 1) @ fit[1:].T  # [n - 2h, 2]: slope, curvature
    first = np.concatenate(
        [c[0, 0] + 2.0 * c[0, 1] * tk[:h], c[:, 0], c[-1, 0] + 2.0 * c[-1, 1] * tk[h + 1 :]]
    )
    second = np.concatenate([np.full(h, 2.0 * c[0, 1]), 2.0 * c[:, 1], np.full(h, 2.0 * c[-1, 1])])
    return first, second


class RecordingDemonstrator:
    """The recorded ego drives: its trajectory each cycle is its recorded states (placed by the
    simulation with moveToXY), and the expert's planner samples the policy set at its state. No policy
    of the set is executed: ``last_index`` is -1 and the writer records the policy closest to what was
    driven as the executed one. The state's rates (acceleration, lateral velocity and acceleration) are
    fitted over ``rate_window`` [s] (:func:`local_rates`): the policy set starts from them, and a
    recording's position noise taken by finite differences would start it metres off."""

    def __init__(
        self, ego: EgoTrack, planner: PlannerConfig, scenario: EpisodeConfig, rate_window: float = RATE_WINDOW
    ):
        self.planner = Planner(ego.road, planner)
        self.last_policy_set: PolicySet | None = None
        self.last_index = -1
        self.n, self.dt = scenario.horizon_steps + 1, scenario.step
        a, _ = local_rates(ego.v, self.dt, rate_window)
        d_dot, d_ddot = local_rates(ego.d, self.dt, rate_window)
        self.states: dict[str, np.ndarray] = {
            "x": ego.x, "y": ego.y, "yaw": ego.yaw, "v": ego.v, "a": a, "s": ego.s, "d": ego.d,
            "d_dot": d_dot, "d_ddot": d_ddot,
        }  # fmt: skip
        self.lane = ego.road.lane_of_d(ego.d)
        self._t_first: float | None = None

    def state(self, k: int) -> EgoState:
        """The ego's recorded state ``k`` (its time: the recording's)."""
        values = {name: float(a[k]) for name, a in self.states.items()}
        return EgoState(t=0.0, lane=int(self.lane[k]), **values)

    def plan(self, obs: Observation) -> Trajectory:
        self.last_policy_set = self.planner.plan(obs)
        t = obs.ego.t
        if self._t_first is None:
            self._t_first = t
        k = int(round((t - self._t_first) / self.dt))
        idx = np.minimum(k + np.arange(self.n), len(self.lane) - 1)  # held at the recording's end
        arrays: dict[str, Any] = {name: a[idx].astype(np.float64) for name, a in self.states.items()}
        return Trajectory(t0=t, dt=self.dt, lane=self.lane[idx].astype(np.int8), **arrays)


def recorded_episode(
    file: str,
    road: Road,
    scenario: EpisodeConfig,
    planner: PlannerConfig,
    vid: str,
    reactive: bool = False,
    rate_window: float = RATE_WINDOW,
    end_on_collision: bool = True,
    read: ReadAs = AS_RECORDED,
) -> tuple[RecordingDemonstrator, Road, EpisodeConfig, ReplaySimulation]:
    """The demonstrator, road, episode settings and replay simulation of ego ``vid`` of recording
    ``file`` on ``road`` (the road of ``scenario``, as the command loaded it: nothing is read again): the
    ego starts at its recorded state and the episode ends with its recording; ``reactive``: SUMO drives
    the others from their first recorded pose on; ``rate_window``: :class:`RecordingDemonstrator`'s;
    ``end_on_collision`` False where the recorded ego drives as recorded (a collection, ``drive --model
    demonstrator``): the recording goes on where the recorded boxes of the ego and another overlap (as
    noisy positions make them), counted as a collision; ``read``: how the file is read
    (:func:`open_recording`)."""
    rec = open_recording(file, road, scenario.step, read)
    et = ego_track(rec, vid, road, classes=read.ego_classes)
    if isinstance(et, str):
        raise IrlsimError(f"recording {rec.path}: vehicle {vid} cannot be an ego: {et}")
    road = et.road
    lane0 = int(road.lane_of_d(np.array([et.d[0]]))[0])
    if read.ego_size == RECORDED_SIZE:  # planned, checked for collisions and sized in SUMO at its own size
        size = recorded_size(rec, vid)
        scenario = dataclasses.replace(scenario, ego_length=size[0], ego_width=size[1])
        planner = ego_sized(planner, scenario)
    scn = dataclasses.replace(
        scenario,
        ego_start_random=False,
        ego_start_s=float(et.s[0] % road.lap_length),
        ego_start_lane=max(lane0, 0),
        ego_start_speed=float(et.v[0]),
        max_time=max(et.duration, scenario.step),
        laps=LAPS,
        end_on_collision=scenario.end_on_collision and end_on_collision,
    )
    driver = RecordingDemonstrator(et, planner, scn, rate_window)
    start = driver.state(0)
    sim = ReplaySimulation(road, scn, others(rec, vid), et.t0, start=start, reactive=reactive)
    if not end_on_collision:  # the recorded ego drives as recorded
        sim.replayed_rows = rec.interval
    return driver, road, scn, sim
