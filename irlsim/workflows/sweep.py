"""Many routes on many networks (``irlsim scenario sweep``): :func:`sweep_networks` with :class:`SweepRun`.

For a SUMO network (``.net.xml`` or ``.net.xml.gz``) or a folder of them (searched recursively):

1. **draw**: ``routes`` car routes per network (:func:`irlsim.road.draw.draw_routes`, seeded), each
   written as a scenario file ``<out>/scenarios/<network>/route_<k>.toml`` that names the network by its
   path and the route by its edges; a network without an edge for cars is listed and skipped;
2. **load**: every route as ``irlsim scenario show`` loads it (:func:`irlsim.road.load_road`): loaded,
   refused (a one-line :class:`~irlsim.errors.IrlsimError`, sorted into the reasons of
   :mod:`irlsim.road.refusals`) or crashed (any other exception: a defect of the road layer, recorded
   with its first line and where it was raised);
3. **drive**: the expert drives one episode (seed ``seed + k`` for route ``k``, at most ``max_time``
   simulated seconds) on the first ``drive`` routes of each network that loaded, in worker processes
   (:func:`irlsim.executor.run_jobs`, each episode within a time limit); the safety bounds are no
   collision, no exit, no red light crossed and a full stop at every stop sign.

Each route's record is written atomically to ``<out>/records/<network>/<k>.json`` as it finishes, so an
interrupted sweep resumes where it stopped, and a finished one reruns as a no-op. The tables
(``sweep.md``, ``sweep.json``, ``routes.csv``: :mod:`irlsim.workflows.sweep_report`) are made from the
records alone and hold no wall-clock figure: the same command gives the same bytes.
"""

from __future__ import annotations

import gzip
import json
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from irlsim.config import MAX_SEED
from irlsim.errors import IrlsimError
from irlsim.executor import Job, run_jobs
from irlsim.outputs import check_output_dir
from irlsim.road import load_road
from irlsim.road.draw import MIN_ROUTE_LENGTH, car_edges, draw_routes, read_network
from irlsim.road.refusals import refusal_reason
from irlsim.road.scenario import Scenarios, load_scenario
from irlsim.rollout.drivers import make_driver
from irlsim.rollout.runner import EpisodeRunner
from irlsim.sim.collision import collision_line
from irlsim.sim.config import scenario_config
from irlsim.sim.simulation import Simulation
from irlsim.sim.start import check_start
from irlsim.utils import atomic_write_text, owned_output, progress, seed_everything, write_json
from irlsim.workflows.sweep_report import write_report

NET_SUFFIXES = (".net.xml", ".net.xml.gz")
#: [s] wall-clock limit of one driven episode per simulated second, and its fixed part (start-up)
DRIVE_TIMEOUT_PER_SIM_S = 5.0
DRIVE_TIMEOUT_BASE_S = 120.0
#: the simulator's counts (``sim/<key>``) the safety bounds read, and how a broken bound is named
SAFETY_COUNTS = {
    "collisions": "collision",
    "exits": "exit",
    "red_crossings": "red light",
    "yield_violations": "right of way",
    "stop_lines_passed": "",
    "stop_lines_compliant": "",
}


@dataclass(frozen=True)
class SweepRun:
    """A sweep: what ``irlsim scenario sweep`` parses its arguments into."""

    source: Path
    """a SUMO network (.net.xml, .net.xml.gz) or a folder of them (searched recursively)"""
    routes: int
    """routes drawn per network"""
    out: Path
    """output folder (scenario files, records, tables)"""
    seed: int = 0
    """route k of a network is drawn from (seed, k) and driven with seed + k"""
    drive: int = 1
    """the expert drives the first this many routes that load, per network (0: none)"""
    max_time: float = 90.0
    """[s] simulated time of one driven episode at most"""
    workers: int = 1
    """processes that load and drive routes in parallel"""
    min_length: float = MIN_ROUTE_LENGTH
    """[m] a drawn route is at least this long"""

    def identity(self) -> dict[str, Any]:
        """What a resumed sweep must share with the one that began the folder (the workers may differ)."""
        return {
            "source": str(self.source.resolve()),
            "routes": self.routes,
            "seed": self.seed,
            "drive": self.drive,
            "max_time": self.max_time,
            "min_length": self.min_length,
        }


@dataclass(frozen=True)
class RouteTask:
    """One route of one network, for a worker: its scenario file and episode seed."""

    network: str
    index: int
    scenario: str  # absolute path of the scenario.toml
    seed: int
    max_time: float


def find_networks(source: Path, exclude: Path | None = None) -> list[tuple[str, Path]]:
    """(name, path) of every network of ``source``, by name; a name is the path below the folder without
    its suffix, '/' written '__'; nothing under ``exclude`` (the sweep's own output, where unpacked
    copies of .gz networks lie). One line, before any work, when there is none or one is not a network."""
    if not source.exists():
        raise IrlsimError(
            f"{source} does not exist: give a SUMO network (.net.xml, .net.xml.gz) or a folder of them"
        )
    if source.is_file():
        if not source.name.endswith(NET_SUFFIXES):
            raise IrlsimError(
                f"{source} is not a SUMO network: give a .net.xml or .net.xml.gz file, or a folder"
            )
        files = [source]
        names = [_strip_suffix(source.name)]
    else:
        skip = exclude.resolve() if exclude is not None else None
        files = sorted(
            p
            for p in source.rglob("*")
            if p.is_file()
            and p.name.endswith(NET_SUFFIXES)
            and not (skip and p.resolve().is_relative_to(skip))
        )
        if not files:
            raise IrlsimError(
                f"{source} holds no SUMO network (*.net.xml, *.net.xml.gz): choose another folder"
            )
        names = [_strip_suffix(p.relative_to(source).as_posix()).replace("/", "__") for p in files]
    for path in files:
        _check_network_head(path)
    return sorted(zip(names, files, strict=True))


def _strip_suffix(name: str) -> str:
    for suffix in NET_SUFFIXES[::-1]:
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def _check_network_head(path: Path) -> None:
    """A file whose beginning holds no ``<net`` element is not a SUMO network: one line."""
    try:
        opener: Any = gzip.open if path.name.endswith(".gz") else open
        with opener(path, "rb") as f:
            head = f.read(65536)
    except (OSError, EOFError) as e:
        raise IrlsimError(f"{path} cannot be read as a SUMO network ({e}): remove it or fix it") from None
    if b"<net " not in head and b"<net>" not in head:
        raise IrlsimError(f"{path} is not a SUMO network (no <net> element): remove it or give another file")


def check_request(run: SweepRun) -> list[tuple[str, Path]]:
    """Every one-line refusal of a sweep, before any work; returns the networks."""
    if run.routes < 1:
        raise IrlsimError(f"--routes must be >= 1, got {run.routes}")
    if run.drive < 0 or run.drive > run.routes:
        raise IrlsimError(f"--drive must be in 0..--routes ({run.routes}), got {run.drive}")
    if not 0 <= run.seed <= MAX_SEED - run.routes:
        raise IrlsimError(f"--seed must be in 0..{MAX_SEED - run.routes}, got {run.seed}")
    if not run.max_time > 0:
        raise IrlsimError(f"--max-time must be > 0 s, got {run.max_time}")
    if run.workers < 1:
        raise IrlsimError(f"--workers must be >= 1, got {run.workers}")
    networks = find_networks(run.source, exclude=run.out)
    check_output_dir(run.out, "--out")
    asked = run.identity()
    request = run.out / "request.json"
    if request.is_file():
        done = json.loads(request.read_text())
        diff = [k for k in asked if done.get(k) != asked[k]]
        if diff:
            was = ", ".join(f"{k}={done.get(k)}" for k in diff)
            raise IrlsimError(
                f"--out {run.out} holds a sweep with other {', '.join(diff)} ({was}): rerun it with the same "
                "arguments or choose another --out"
            )
    return networks


def sweep_networks(run: SweepRun) -> dict[str, Any]:
    """Draw, load and drive (module docstring); writes the tables, prints the summary table and where
    it wrote; returns the summary (``sweep.json``'s content)."""
    networks = check_request(run)
    run.out.mkdir(parents=True, exist_ok=True)
    with owned_output(run.out, "scenario sweep"):
        write_json(run.out / "request.json", run.identity())
        tasks = _draw(run, networks)
        _load(run, tasks)
        _drive(run, tasks)
        summary = write_report(run.out, [name for name, _ in networks], run.identity())
    return summary


# ------------------------------------------------------------------------------------------ draw


def _record_path(out: Path, network: str, index: int) -> Path:
    return out / "records" / network / f"{index:04d}.json"


def _read_record(out: Path, network: str, index: int) -> dict[str, Any] | None:
    p = _record_path(out, network, index)
    return json.loads(p.read_text()) if p.is_file() else None


def _draw(run: SweepRun, networks: list[tuple[str, Path]]) -> list[RouteTask]:
    """Every network's routes drawn and written as scenario files (skipped where done); the routes that
    remain to load or drive, as tasks."""
    tasks: list[RouteTask] = []
    for name, path in progress(networks, desc="draw routes", unit="network"):
        marker = run.out / "records" / name / "network.json"
        if not marker.is_file():
            _draw_network(run, name, path, marker)
        info = json.loads(marker.read_text())
        for k in info["drawn"]:
            scn = run.out / "scenarios" / name / f"route_{k:04d}.toml"
            tasks.append(RouteTask(name, k, str(scn.resolve()), run.seed + k, run.max_time))
    return tasks


def _draw_network(run: SweepRun, name: str, path: Path, marker: Path) -> None:
    try:
        net = read_network(path)
    except IrlsimError as e:  # a network sumolib cannot read: every route refused with its line
        for k in range(run.routes):
            _write_record(run.out, _base_record(name, k, run.seed + k, (), 0.0, "", "refused", str(e)))
        write_json(marker, {"network": str(path.resolve()), "drawn": [], "car_lanes": True})
        return
    cars = bool(car_edges(net))
    routes = draw_routes(net, run.routes, run.seed, run.min_length) if cars else []
    drawn = []
    for r in routes:
        scn = run.out / "scenarios" / name / f"route_{r.index:04d}.toml"
        if r.refusal:
            rec = _base_record(name, r.index, run.seed + r.index, (), 0.0, "", "refused", r.refusal)
            _write_record(run.out, rec)
            continue
        atomic_write_text(scn, scenario_text(name, r.index, path, r.edges, r.length))
        drawn.append(r.index)
    write_json(marker, {"network": str(path.resolve()), "drawn": drawn, "car_lanes": cars})


def scenario_text(network: str, index: int, net_file: Path, edges: tuple[str, ...], length: float) -> str:
    """The scenario file of a drawn route: the network by its absolute path, the route by its edges."""
    quoted = ", ".join(json.dumps(e) for e in edges)
    return (
        f'name = "{network}-route{index:04d}"\n'
        f'description = "route {index} drawn on {network} by irlsim scenario sweep ({length:.0f} m)"\n\n'
        f"[network]\nfile = {json.dumps(str(net_file.resolve()))}\n\n"
        f"[route]\nedges = [{quoted}]\n"
    )


def _base_record(
    network: str,
    index: int,
    seed: int,
    edges: tuple[str, ...],
    length: float,
    scenario: str,
    load: str,
    message: str = "",
) -> dict[str, Any]:
    return {
        "network": network,
        "route": index,
        "seed": seed,
        "edges": " ".join(edges),
        "length_m": length,
        "scenario": scenario,
        "load": load,  # loaded, refused or crash
        "reason": refusal_reason(message) if load == "refused" else ("crash" if load == "crash" else ""),
        "message": message,
        "driven": False,
        "outcome": "",  # ok, failed, refused or crash once driven
        "failure": "",
    }


def _write_record(out: Path, rec: dict[str, Any]) -> None:
    write_json(_record_path(out, rec["network"], rec["route"]), rec)


# ------------------------------------------------------------------------------------------ load


def crash_line(e: BaseException) -> str:
    """An unexpected exception as one line: its type, its message's first line and where it was raised
    (the innermost frame in irlsim, else the innermost one)."""
    first = (str(e).strip().splitlines() or [""])[0]
    frames = traceback.extract_tb(e.__traceback__)
    ours = [f for f in frames if "/irlsim/" in f.filename]
    if not frames:
        return f"{type(e).__name__}: {first}"
    where = (ours or frames)[-1]
    name = "irlsim/" + where.filename.split("/irlsim/")[-1] if ours else where.filename
    return f"{type(e).__name__}: {first} (at {name}:{where.lineno})"


def _load_route(task: RouteTask) -> dict[str, Any]:  # top level: picklable for worker processes
    """Load one route's road as ``irlsim scenario show`` does, and check that it leaves the ego a start
    as every command that drives does before any work: loaded, refused or crash (never raises)."""
    edges: tuple[str, ...] = ()
    try:  # the route's scenario file read once: its road and its [defaults]
        scn = load_scenario(task.scenario, build=False)
        edges = scn.edges
        road = load_road(scenario=scn)
        check_start(road, scenario_config(task.scenario, Scenarios(scn)))
    except IrlsimError as e:
        return _base_record(task.network, task.index, task.seed, edges, 0.0, task.scenario, "refused", str(e))
    except Exception as e:  # a defect of the road layer: recorded, never a refusal
        return _base_record(
            task.network, task.index, task.seed, edges, 0.0, task.scenario, "crash", crash_line(e)
        )
    length = (
        round(float(road.route_end_s - road.route_begin_s), 1)
        if not road.closed
        else round(road.lap_length, 1)
    )
    return _base_record(task.network, task.index, task.seed, edges, length, task.scenario, "loaded")


def _load(run: SweepRun, tasks: list[RouteTask]) -> None:
    todo = [t for t in tasks if _read_record(run.out, t.network, t.index) is None]
    if not todo:
        return
    bar = progress(total=len(todo), desc="load routes", unit="route")

    def done(job: Job, rec: Any) -> None:
        _write_record(run.out, rec)
        bar.update(1)

    jobs = [Job(f"{t.network}/{t.index}", t) for t in todo]
    res = run_jobs(_load_route, jobs, workers=run.workers, on_result=done)
    for key, reason in sorted(res.failed.items()):  # a worker that died while loading: a crash
        t = next(j.arg for j in jobs if j.key == key)
        _write_record(run.out, _base_record(t.network, t.index, t.seed, (), 0.0, t.scenario, "crash", reason))
        bar.update(1)
    bar.close()


# ------------------------------------------------------------------------------------------ drive


def _drive_route(task: RouteTask) -> dict[str, Any]:  # top level: picklable for worker processes
    """The expert's episode on one route: its outcome against the safety bounds (never raises)."""
    try:
        scn = load_scenario(task.scenario)  # the route's scenario file read once
        road = load_road(scenario=scn)
        cfg = scenario_config(task.scenario, Scenarios(scn), max_time=task.max_time)
        seed_everything(task.seed)
        with Simulation(road, cfg) as sim:
            result = EpisodeRunner(sim).run(make_driver("expert", road, cfg), task.seed)
            first = sim.first_collision
    except IrlsimError as e:
        return {"outcome": "refused", "failure": str(e)}
    except Exception as e:  # a defect of the road or the simulation
        return {"outcome": "crash", "failure": crash_line(e)}
    st = result.stats
    count = {k: int(st.get(f"sim/{k}") or 0) for k in SAFETY_COUNTS}
    failing = ("collisions", "exits", "red_crossings", "yield_violations")
    broken = [SAFETY_COUNTS[k] for k in failing if count[k] > 0]
    if count["stop_lines_compliant"] < count["stop_lines_passed"]:
        broken.append(f"stops {count['stop_lines_compliant']}/{count['stop_lines_passed']}")
    return {
        "outcome": "failed" if broken else "ok",
        "failure": ", ".join(broken),
        "end_reason": result.end_reason,
        "time_s": st.get("sim/time_s"),
        "distance_m": st.get("sim/distance_m"),
        "mean_speed_kmh": st.get("sim/mean_speed_kmh"),
        "checkpoints": f"{st.get('sim/checkpoints_in_lane', 0)}/{st.get('sim/checkpoints_passed', 0)}",
        # what the first collision was (kind, where, the other vehicle, speeds): the reason looked for
        "collision": collision_line(first) if first else "",
    }


def _drive(run: SweepRun, tasks: list[RouteTask]) -> None:
    todo = []
    by_network: dict[str, int] = {}
    for t in tasks:
        rec = _read_record(run.out, t.network, t.index)
        if rec is None or rec["load"] != "loaded" or by_network.get(t.network, 0) >= run.drive:
            continue
        by_network[t.network] = by_network.get(t.network, 0) + 1
        if not rec["driven"]:
            todo.append((t, rec))
    if not todo:
        return
    bar = progress(total=len(todo), desc="drive routes", unit="episode")
    records = {f"{t.network}/{t.index}": rec for t, rec in todo}

    def done(job: Job, outcome: Any) -> None:
        _write_record(run.out, {**records[job.key], "driven": True, **outcome})
        bar.update(1)

    jobs = [Job(f"{t.network}/{t.index}", t) for t, _ in todo]
    timeout = DRIVE_TIMEOUT_BASE_S + DRIVE_TIMEOUT_PER_SIM_S * run.max_time
    res = run_jobs(_drive_route, jobs, workers=run.workers, on_result=done, timeout=timeout)
    for key, reason in sorted(res.failed.items()):  # a worker that died or hung: a crash
        done(Job(key, None), {"outcome": "crash", "failure": reason})
    bar.close()
