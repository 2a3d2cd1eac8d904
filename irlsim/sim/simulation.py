"""The one owner of the SUMO simulation: start, reset, step, observe, execute a trajectory, close.

libsumo by default (in-process, thousands of steps per second); ``gui=True`` runs sumo-gui through traci
for a user with a display (same API). SUMO is imported and located only in :meth:`Simulation.start`.
libsumo holds one simulation per process: starting a second :class:`Simulation` closes the first.

Clocks: every :meth:`step` advances SUMO by ``cfg.step`` with the ego placed by ``moveToXY`` at the
state it is given, its route in SUMO kept whole (:class:`~irlsim.sim.sumo_ego.EgoRoute`); :meth:`execute`
runs the first ``cycle / step`` states of a driver's trajectory (state j at the j-th step), and the ego's
state becomes the executed trajectory state, so the next plan starts exactly where the last one left off.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.road import Road, load_road, wrap_angle, yaw_to_sumo_angle
from irlsim.road.network import SUMO_NET_DIR, VTYPES_FILE, sumo_binary
from irlsim.sim.bodies import Bodies
from irlsim.sim.collision import first_collision
from irlsim.sim.config import EpisodeConfig
from irlsim.sim.episode import CourseMarks, Episode
from irlsim.sim.inputs import (
    SumoErrorLog,
    additional_files,
    check_inputs,
    refusal,
    reports_sumo_errors,
    start_quietly,
)
from irlsim.sim.intent import JunctionPaths
from irlsim.sim.signals import SignalWatch
from irlsim.sim.start import draw_start, start_scale
from irlsim.sim.sumo_ego import EgoRoute, add_ego, sumo_step, take_over
from irlsim.sim.traffic import BackgroundTraffic, LoopEdges
from irlsim.sim.types import EgoState, Observation, Trajectory, VehicleStates
from irlsim.sim.vtype import DEMO_TYPE, PLACED_TYPE, DemoTypeFile, ego_type_attributes
from irlsim.sim.yielding import YieldWatch

EGO = "ego"
#: [m] the length and width of irlsim's ego type (sumo_net/vtypes.add.xml): an ego of another size (a
#: recorded ego at its own, ``demonstrator.ego_size = 'recorded'``) is resized in SUMO when inserted
EGO_TYPE_SIZE = tuple(float(ego_type_attributes()[k]) for k in ("length", "width"))
MAX_SEED = 2**31 - 1  # SUMO's --seed is a signed 32-bit integer; larger ones make it fail to start
_ACTIVE: Simulation | None = None  # the libsumo simulation of this process


def check_seed(seed: object) -> int:
    """``seed`` as an int; a one-line IrlsimError unless it is an integer in 0..MAX_SEED."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed <= MAX_SEED:
        raise IrlsimError(f"seed must be an integer in 0..{MAX_SEED} (SUMO's --seed), got {seed!r}")
    return int(seed)


class Simulation:
    """SUMO episode on the oval with background traffic and a trajectory-driven ego.

    Typical loop::

        with Simulation(road, cfg) as sim:
            obs = sim.reset(seed)
            while not sim.done:
                sim.execute(driver.plan(obs))
                obs = sim.observe()
            print(sim.stats)
    """

    def __init__(
        self,
        road: Road | None = None,
        cfg: EpisodeConfig | None = None,
        *,
        gui: bool = False,
        net_file: str | Path | None = None,
        vtypes_file: str | Path | None = None,
        demo_vtype: dict[str, str] | None = None,
        lane_change_duration: float = 0.0,
    ):
        self.road = road if road is not None else load_road(net_file)
        self.cfg = cfg if cfg is not None else EpisodeConfig()
        self.gui = gui
        self.vtypes_file = Path(vtypes_file) if vtypes_file else SUMO_NET_DIR / VTYPES_FILE
        self.marks = CourseMarks.from_road(self.road)
        self._edges = LoopEdges.from_road(self.road)
        self._route = EgoRoute(self.road)
        #: the factor on the ego's start clearances this route allows (1 unless it is short); a route too
        #: short for any start is refused here, before SUMO starts
        self.start_scale = start_scale(self.road, self.cfg, self._edges)
        self._api: Any = None
        self.seed: int | None = None
        self.episode: Episode | None = None
        self.traffic: BackgroundTraffic | None = None
        self.ego: EgoState | None = None
        self.vehicles = VehicleStates.empty()
        self.odometry: list[EgoState] = []
        self._ego_by_sumo = False  # SUMO's driver model has taken the ego over (SumoDriver)
        self.demo_type = DemoTypeFile(demo_vtype) if demo_vtype else None  # SumoDriver's type (.vtype)
        self.lane_change_duration = lane_change_duration  # [s] SUMO's --lanechange.duration (0: one step)
        self.errors = SumoErrorLog()  # SUMO's reason where libsumo says only 'Process Error'
        self.signals = SignalWatch(self.road, self.cfg.ego_length, self.cfg.ego_target_speed)  # on its lane
        #: [s] a recorded ego replayed as recorded: its rows' interval (None: the ego is driven); from it
        #: its lights' grace (SignalWatch) and its body's box along its recorded heading (Bodies)
        self.replayed_rows: float | None = None
        self.yields = YieldWatch(self.road, self.cfg)  # right of way at the route's yield points
        self.paths = JunctionPaths(self.road)  # a vehicle's way through a junction into the route
        self._colliding: set[str] = set()
        self.bodies = Bodies()  # the long vehicles' paths: their bodies in the ego's collision check
        self._sumo_pairs: set[tuple[str, str]] = set()
        self._wall = 0.0
        self._sumo_wall = 0.0
        #: called as f(sim) after every bookkept simulation step (the scorecard records its per-step facts)
        self.step_listeners: list[Any] = []

    # ------------------------------------------------------------------ process
    def command(self, seed: int) -> list[str]:
        """The SUMO command line (binary first) for an episode with ``seed``."""
        binary = sumo_binary("sumo-gui" if self.gui else "sumo")
        if not self.vtypes_file.is_file():
            raise IrlsimError(f"vehicle types {self.vtypes_file} not found: restore sumo_net/ from git")
        additional = additional_files(
            self.road, self.vtypes_file, *([self.demo_type.path()] if self.demo_type else [])
        )
        options = {
            "--net-file": str(self.road.net_file),
            "--additional-files": additional,
            **({"--route-files": ",".join(str(p) for p in self.road.demand)} if self.road.demand else {}),
            "--step-length": f"{self.cfg.step}",
            "--seed": str(seed),
            "--begin": "0",
            "--no-step-log": "true",
            "--no-warnings": "true",
            "--collision.action": "warn",
            "--collision.check-junctions": "true",
            "--collision.mingap-factor": "0",
            "--time-to-teleport": "-1",
            **self.errors.option(),
        }
        if self.lane_change_duration:  # [s] lane changes that take time (SUMO's default: one step)
            options["--lanechange.duration"] = f"{self.lane_change_duration:g}"
        cmd = [binary, *(x for kv in options.items() for x in kv)]
        if self.gui:
            cmd += ["--start", "true", "--delay", str(int(self.cfg.step * 1000))]
        return cmd

    def start(self, seed: int = 0) -> None:
        """Start SUMO (no-op when running). Raises a one-line :class:`IrlsimError` on failure."""
        global _ACTIVE
        if self._api is not None:
            return
        if self.gui and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise IrlsimError("--gui needs a display, but DISPLAY is not set: run without --gui (headless)")
        cmd = self.command(check_seed(seed))
        check_inputs(self.vtypes_file, self.road.demand, self.road.additional)  # besides the network
        module = "traci" if self.gui else "libsumo"
        try:
            api: Any = importlib.import_module(module)
        except ImportError:
            raise IrlsimError(f"{module} is not installed: run 'make setup'") from None
        if not self.gui and _ACTIVE is not None and _ACTIVE is not self:
            _ACTIVE.close()  # libsumo: one simulation per process
        why = start_quietly(api, cmd, quiet=not self.gui)
        if why is not None:  # the file SUMO refused, by starting it on each in turn (sim.inputs)
            raise refusal(api, self.road, self.vtypes_file, why) if not self.gui else IrlsimError(why)
        self._api = api
        if not self.gui:
            _ACTIVE = self

    def close(self) -> None:
        """Stop SUMO; safe to call more than once."""
        global _ACTIVE
        api, self._api = self._api, None
        if api is not None:
            try:
                api.close()
            except Exception:  # already gone (closed by another owner or crashed): nothing to release
                pass
        if _ACTIVE is self:
            _ACTIVE = None
        if self.demo_type is not None:
            self.demo_type.cleanup()
        self.errors.remove()

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass

    @property
    def running(self) -> bool:
        return self._api is not None

    # ------------------------------------------------------------------ episode
    @reports_sumo_errors
    def reset(self, seed: int) -> Observation:
        """Start a new episode with ``seed`` (SUMO's --seed and the traffic's numpy Generator)."""
        seed = check_seed(seed)
        if self._api is None:
            self.start(seed)
        else:
            why = start_quietly(self._api, self.command(seed), quiet=not self.gui, load=True)
            if why is not None:
                api, self._api = self._api, None
                raise refusal(api, self.road, self.vtypes_file, why) if not self.gui else IrlsimError(why)
        api, cfg, road = self._api, self.cfg, self.road
        self.seed = seed
        rng = np.random.default_rng(seed)
        route_laps = int(cfg.max_time * 30.0 / road.lap_length) + 3
        self.traffic = BackgroundTraffic(api, road, cfg, rng, route_laps, self._edges)
        self.traffic.add_routes()
        for _ in range(int(round(road.warmup / cfg.step))):  # the scenario's own demand fills the road
            api.simulationStep()
        # the ego: inserted where it starts, then placed exactly by moveToXY
        s0, lane0, v0 = self.ego_start(seed)
        if road.lanes_vary:  # a lane the road lacks there: the nearest one it has
            lo, hi = road.lane_bounds(np.array(s0))
            lane0 = int(np.clip(lane0, lo, hi))
        loc = self._edges.locate(s0, road.lap_length)
        if loc is None:
            raise IrlsimError(f"ego_start_s = {s0} m lies in a junction: choose a position on a loop edge")
        eid, pos = loc
        # and a lane of the very edge it departs from (lane_bounds may hold the next edge's lanes near
        # its end: SUMO refused a departure lane -1 there, a crash of the sweep on a random network)
        i = road.edges.index(eid)
        lane0 = int(np.clip(lane0, road.layout.first[i], road.layout.first[i] + road.layout.count[i] - 1))
        d0 = float(road.lane_center(lane0))
        add_ego(api, EGO, road, eid, pos, lane0, v0, PLACED_TYPE if self.demo_type else "ego")
        if (cfg.ego_length, cfg.ego_width) != EGO_TYPE_SIZE:  # SUMO's drivers see the ego at its size
            api.vehicle.setLength(EGO, cfg.ego_length)
            api.vehicle.setWidth(EGO, cfg.ego_width)
        api.vehicle.setSpeedMode(EGO, 0)
        x, y = road.to_xy(np.array(s0), np.array(d0))
        t = float(api.simulation.getTime())
        start = EgoState(
            t=t,
            x=float(x),
            y=float(y),
            yaw=float(road.heading(np.array(s0))),
            v=v0,
            a=0.0,
            s=s0,
            d=d0,
            d_dot=0.0,
            d_ddot=0.0,
            lane=lane0,
        )
        self.traffic.spawn(s0, VehicleStates.empty(), initial=True)
        self.episode = Episode(
            self.marks,
            cfg.laps,
            cfg.max_time,
            stop_speed=cfg.stop_speed,
            stop_zone=cfg.stop_zone,
            exit_margin=cfg.exit_margin,
            end_on_collision=cfg.end_on_collision,
        )
        self.odometry = []
        self._ego_by_sumo = False
        self.signals = SignalWatch(road, cfg.ego_length, cfg.ego_target_speed, self._red_grace(cfg))
        self._colliding, self._sumo_pairs, self.bodies = set(), set(), Bodies(self.replayed_rows is None)
        #: the episode's first collision (:func:`.collision.first_collision`), None while there is none
        self.first_collision: dict[str, Any] | None = None
        self._wall = self._sumo_wall = 0.0
        self._steps = 0
        self.ego = start
        self._advance(start, bookkeeping=False)  # inserts everyone and places the ego
        if EGO not in api.vehicle.getIDList():
            raise IrlsimError(
                f"SUMO could not insert the ego at s = {s0:.1f} m, lane {lane0} (seed {seed}): choose "
                "another ego_start_s / ego_start_lane, or set ego_start_random"
            )
        self.episode.update(self.ego)
        self.odometry.append(self.ego)
        return self.observe()

    def ego_start(self, seed: int) -> tuple[float, int, float]:
        """The ego's start for an episode with ``seed``: (route position s [m], lane, speed [m/s]); see
        :func:`irlsim.sim.start.draw_start`."""
        occupied = self._read_vehicles() if self.road.demand else None
        return draw_start(self.road, self.cfg, self._edges, seed, occupied, self.start_scale)

    def _sumo_state(self) -> EgoState:
        """SUMO's own driver model drives the ego one step (:func:`irlsim.sim.sumo_ego.sumo_step`)."""
        assert self.ego is not None
        if not self._ego_by_sumo:
            take_over(self._api, EGO, self.cfg.ego_target_speed, DEMO_TYPE if self.demo_type else None)
            self._ego_by_sumo = True
        t1 = time.perf_counter()
        state = sumo_step(self._api, EGO, self.road, self.ego)
        self._sumo_wall += time.perf_counter() - t1
        return state

    def _red_grace(self, cfg: EpisodeConfig) -> float:
        """[s] SignalWatch's grace: a replayed recorded ego's rows' interval less a step (its motion between
        rows is what the light then allowed); 0 for a driven ego."""
        return 0.0 if self.replayed_rows is None else max(self.replayed_rows - cfg.step, 0.0)

    def _advance(self, state: EgoState, bookkeeping: bool = True, placed: bool = False) -> None:
        """Place the ego at ``state`` and advance SUMO one step (``placed``: SUMO has already driven it
        there), read the vehicles, update the books."""
        api = self._api
        t0 = time.perf_counter()
        if not placed:
            api.vehicle.moveToXY(EGO, "", -1, state.x, state.y, yaw_to_sumo_angle(state.yaw), keepRoute=2)
            t1 = time.perf_counter()
            api.simulationStep()
            self._sumo_wall += time.perf_counter() - t1
            if bookkeeping:  # not in reset: libsumo crashes when asked for a still pending ego's edge
                self._route.keep(api, EGO)
        self.ego = state = dataclasses.replace(state, t=float(api.simulation.getTime()))
        self.vehicles = self._read_vehicles(state.s)
        assert self.traffic is not None and self.episode is not None
        self.traffic.after_step(state.t, state.s % self.road.lap_length, self.vehicles)
        new_obb = self._ego_collisions(state)
        new_sumo = self._sumo_collisions()
        teleports = int(api.simulation.getStartingTeleportNumber())
        self.signals.read(api, EGO, state.v, state.s)
        violations = self.yields.read(api, EGO, state.v, state.s) + self.signals.violations
        if bookkeeping:
            self.episode.update(
                state,
                collisions=new_obb,
                sumo_collisions=new_sumo,
                teleports=teleports,
                red=tuple(self.signals.red.tolist()),
                yield_violations=violations,
            )
            self.odometry.append(state)
            self._steps += 1
        self._wall += time.perf_counter() - t0
        if bookkeeping:
            for f in self.step_listeners:
                f(self)

    def _read_vehicles(self, ego_s: float = math.nan) -> VehicleStates:
        """Every vehicle but the ego; on a route that comes back near itself projected by progress (near
        its last or inserted position, else the ego's ``ego_s`` [m]: BackgroundTraffic.hints)."""
        v_api = self._api.vehicle
        ids = tuple(v for v in v_api.getIDList() if v != EGO)
        m = len(ids)
        arr = np.empty((6, m))
        sizes = self.traffic.sizes if self.traffic is not None else {}
        for i, vid in enumerate(ids):
            x, y = v_api.getPosition(vid)
            size = sizes.get(vid)
            if size is None:
                size = sizes[vid] = (v_api.getLength(vid), v_api.getWidth(vid))
            arr[:, i] = (x, y, v_api.getAngle(vid), v_api.getSpeed(vid), size[0], size[1])
        yaw = wrap_angle(np.radians(90.0 - arr[2]))  # SUMO angle (deg, north, clockwise) -> ENU yaw
        near = None
        if not self.road.flat and self.traffic is not None:
            near = self.traffic.hints(ids, ego_s)
        s, d = self.road.to_frenet(arr[0], arr[1], near=near)
        path = self.paths.paths(self._api, ids)
        return VehicleStates(ids, arr[0], arr[1], yaw, arr[3], s, d, arr[4], arr[5], path)

    def _ego_collisions(self, ego: EgoState) -> int:
        """New ego-vehicle overlaps (oriented boxes) this step; one per contiguous overlap per vehicle."""
        veh = self.vehicles
        if veh.count == 0:
            self._colliding = set()
            return 0
        # a long vehicle's body reaches farther from its front (a car's: within 20 m, as ever)
        far = 20.0 + max(self.cfg.ego_length - 5.0, 0.0) + np.maximum(veh.length - 5.0, 0.0)
        near = np.flatnonzero((np.abs(veh.x - ego.x) < far) & (np.abs(veh.y - ego.y) < far))
        hit = self.bodies.hits(ego, self.cfg.ego_length, self.cfg.ego_width, veh, near)
        now = {veh.ids[i] for i in near[hit]}
        if now - self._colliding and self.first_collision is None:
            i, get, road = veh.ids.index(min(now - self._colliding)), self._api.vehicle.getLaneID, self.road
            lanes = (get(EGO), get(veh.ids[i]))
            self.first_collision = first_collision(ego, veh, i, lanes, road.lap_length, road.lane_width)
        new = len(now - self._colliding)
        self._colliding = now
        return new

    def _sumo_collisions(self) -> int:
        """New collisions SUMO reports with the ego (de-duplicated over consecutive steps); background
        vehicles' collisions among themselves go to the traffic figures."""
        pairs = set()
        for c in self._api.simulation.getCollisions():
            pairs.add((c.collider, c.victim))
        new = pairs - self._sumo_pairs
        self._sumo_pairs = pairs
        assert self.traffic is not None
        self.traffic.counts["collisions"] += sum(1 for p in new if EGO not in p)
        return sum(1 for p in new if EGO in p)

    # ------------------------------------------------------------------ driving
    @reports_sumo_errors
    def step(self, state: EgoState | None = None) -> None:
        """Advance one step with the ego placed at ``state`` (None: the ego stands where it is)."""
        self._require_episode()
        assert self.ego is not None
        if state is None:
            state = dataclasses.replace(self.ego, v=0.0, a=0.0, d_dot=0.0, d_ddot=0.0)
        self._advance(state)

    @reports_sumo_errors
    def execute(self, traj: Trajectory, n_steps: int | None = None) -> None:
        """Drive states 1..n_steps of ``traj`` (default: one planning cycle), stopping early when done."""
        self._require_episode()
        assert self.ego is not None
        n = self.cfg.steps_per_cycle if n_steps is None else int(n_steps)
        if len(traj.x) <= n:
            raise ValueError(f"trajectory has {len(traj.x)} states, needs more than {n}")
        if abs(traj.t0 - self.ego.t) > 0.5 * self.cfg.step or abs(traj.dt - self.cfg.step) > 1e-9:
            raise ValueError(
                f"trajectory (t0={traj.t0:.3f} s, dt={traj.dt}) does not start at the ego's time "
                f"{self.ego.t:.3f} s with dt={self.cfg.step}: plan from the latest observation"
            )
        for j in range(1, n + 1):
            self._advance(self._sumo_state() if traj.by_sumo else traj.state(j), placed=traj.by_sumo)
            if self.done:
                break

    def observe(self) -> Observation:
        """The ego's state, the other vehicles (front bumpers, route frame), route target and stop line."""
        self._require_episode()
        assert self.ego is not None and self.episode is not None
        idx, target_s = self.episode.target(self.ego.s)
        stop_s, red = self.episode.stop_s(self.ego.s), False
        lines = [g.s for g, on in zip(self.road.signals, self.signals.binding, strict=True) if on]
        lines += [p.s for p, on in zip(self.road.yield_points, self.yields.binding, strict=True) if on]
        for m in lines:
            line = self.ego.s + self.marks.ahead(self.ego.s, m)
            if line < stop_s:
                stop_s, red = line, True
        return Observation(
            ego=self.ego,
            vehicles=self.vehicles,
            target_checkpoint=idx,
            target_s=target_s,
            stop_s=stop_s,
            lap_length=self.road.lap_length,
            info={
                "lane_required": self.road.required_lane(idx, self.ego.d),
                "laps": self.episode.laps_completed,
            },
            stop_red=red,
        )

    def _require_episode(self) -> None:
        if self._api is None or self.episode is None:
            raise RuntimeError(
                "no episode running: call reset(seed) first (after close(), reset starts SUMO again)"
            )

    # ------------------------------------------------------------------ results
    @property
    def done(self) -> bool:
        return self.episode is not None and self.episode.done

    @property
    def time(self) -> float:
        return 0.0 if self.ego is None else self.ego.t

    @property
    def stats(self) -> dict[str, Any]:
        """Figures of the current episode (``sim/...`` keys, ``end_reason``), timing included.

        The two timing figures (TIMING_KEYS) count the episode's steps per wall-clock second of
        different spans. ``sim/steps_per_s``: time inside the simulator's step, i.e. placing the ego,
        SUMO's step, reading the vehicles (libsumo getters and their route-frame projection), traffic
        upkeep, collision checks and bookkeeping; the driver's planning is NOT included (``irlsim sim``
        reports it as ``sim/plan_ms_mean``). ``sim/sumo_steps_per_s``: time inside libsumo's
        ``simulationStep`` alone, SUMO's own speed (several thousand steps per second with 15 vehicles).
        """
        if self.episode is None or self.traffic is None:
            return {}
        out = self.episode.stats()
        out.update(self.traffic.stats())
        steps = max(self._steps, 1)
        out["sim/steps_per_s"] = round(steps / self._wall, 1) if self._wall > 0 else 0.0
        out["sim/sumo_steps_per_s"] = round(steps / self._sumo_wall, 1) if self._sumo_wall > 0 else 0.0
        out["seed"] = self.seed
        return out

    def odometry_arrays(self) -> dict[str, np.ndarray]:
        """The ego's recorded states (one per step, reset included) as arrays [steps + 1] per field."""
        names = [f.name for f in dataclasses.fields(EgoState)]
        return {n: np.array([getattr(e, n) for e in self.odometry]) for n in names}


#: wall-clock figures, which differ from run to run (see Simulation.stats): left out of determinism checks
TIMING_KEYS = ("sim/steps_per_s", "sim/sumo_steps_per_s")
