"""``irlsim scenario from-sumo``: a SUMO scenario of the user's own (its ``.sumocfg``) made ready to learn
its drivers from. SUMO runs the configuration on its own (the wheel's ``sumo`` binary, the
configuration's routes, drivers and signals) and records its FCD output, or a recording made with it is
given; irlsim writes a scenario on the configuration's network (with the signal programs it ran with), the
vehicle types of its files, and a collect config (its cars as egos in turn, in the order they entered,
split into train, validation and test episodes) and a drive config (the cars no collected episode used).
"""

from __future__ import annotations

import gzip
import json
import os
import re
import subprocess
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from irlsim.data.recorded import ego_track, egos, open_recording
from irlsim.data.recording import MAX_GAP, Recording
from irlsim.data.recording_as import ReadAs
from irlsim.data.sumocfg import SumoConfig, read_sumocfg, signal_files, vtypes_xml
from irlsim.errors import IrlsimError
from irlsim.road import Road, load_road
from irlsim.road.draw import car_edges, read_network
from irlsim.road.network import strip_header, sumo_binary, sumo_home, tool_error
from irlsim.utils import atomic_write_text, write_json
from irlsim.workflows.imports import MIN_EGOS, ego_configs, staged

#: [s] the least time a car drives on its route to be an ego (irlsim's default for recordings)
MIN_DURATION = 20.0
#: [s] what SUMO records of a configuration without an end
DEFAULT_DURATION = 600.0
#: [s] the step the recording is resampled to (SUMO's, as every collection's)
STEP = 0.1
#: the recording SUMO's run writes into --out
RECORDING = "recording.fcd.xml.gz"
#: the other class whose egos get configs of their own (where there are enough)
TRUCK = "truck"


@dataclass(frozen=True)
class SumoImport:
    """What ``irlsim scenario from-sumo`` parses its arguments into."""

    config: Path
    """the SUMO configuration (.sumocfg)"""
    out: Path
    """output folder: a scenario, the vehicle types, the recording (when SUMO runs) and configs"""
    recording: Path | None = None
    """a recording made with the configuration (FCD .xml[.gz], .csv, .parquet); None: SUMO runs it"""
    duration: float | None = None
    """[s] how long SUMO runs from the configuration's begin (None: to its end, else 600 s)"""
    seed: int = 0
    """SUMO's random seed"""
    min_duration: float = MIN_DURATION
    """[s] the least time a car drives on its route to be an ego"""


def import_sumo(run: SumoImport) -> dict[str, object]:
    """Import ``run.config`` into ``run.out``; returns what was written and the egos. Everything read is
    checked before SUMO runs or anything is written; prints where it wrote."""
    if not run.min_duration > 0:
        raise IrlsimError(f"--min-duration must be > 0 s, got {run.min_duration:g}")
    if run.duration is not None and not run.duration > 0:
        raise IrlsimError(f"--duration must be > 0 s, got {run.duration:g}")
    cfg = read_sumocfg(run.config)
    if run.recording is not None and not run.recording.is_file():
        raise IrlsimError(f"--recording {run.recording} not found: give the FCD (or columnar) file to import")
    types, n_types = vtypes_xml(cfg.routes + cfg.additional)
    with staged(run.out, "from-sumo") as stage:
        atomic_write_text(stage / "vtypes.add.xml", types)
        recording = run.out / RECORDING if run.recording is None else run.recording
        if run.recording is None:
            _record(cfg, stage / RECORDING, run.duration, run.seed)
        written = _write(cfg, stage, run.out, recording, run.min_duration)
        written["vehicle_types"] = n_types
        write_json(stage / "from-sumo.json", written)
    trucks = f" and {written['trucks']} trucks (trucks-collect.toml)" if "trucks-collect" in written else ""
    print(
        f"{cfg.path.name}: {written['vehicles']} vehicles recorded ({written['unfinished']} still driving at "
        f"its end), {written['egos']} cars{trucks} as egos; "
        f"collect with 'irlsim collect --config {written['collect']} "
        f"--out data/{run.out.resolve().name}-demos'"
    )
    print(f"from-sumo: {run.out} (scenario.toml, vtypes.add.xml, collect.toml, drive.toml, from-sumo.json"
          + (f", {RECORDING})" if run.recording is None else ")"))  # fmt: skip
    return written


def _record(cfg: SumoConfig, target: Path, duration: float | None, seed: int) -> None:
    """SUMO runs ``cfg`` on its own and its FCD output is written to ``target`` without SUMO's header
    comment (its time and options), gzipped without a time stamp: the same run, the same bytes."""
    end = cfg.begin + (duration or ((cfg.end - cfg.begin) if cfg.end is not None else DEFAULT_DURATION))
    raw = target.with_suffix("")  # SUMO writes plain XML; irlsim compresses it
    print(f"from-sumo: SUMO runs {cfg.path} from {cfg.begin:g} s to {end:g} s (seed {seed}) ...", flush=True)
    proc = subprocess.run(
        [
            sumo_binary("sumo"),
            "-c",
            str(cfg.path),
            "--fcd-output",
            str(raw),
            "--end",
            f"{end:g}",
            "--seed",
            str(seed),
            "--no-step-log",
            "true",
            "--duration-log.disable",
            "true",
        ],  # fmt: skip
        capture_output=True,
        text=True,
        env={**os.environ, "SUMO_HOME": sumo_home()},
    )
    if proc.returncode != 0 or not raw.is_file():
        raise IrlsimError(
            f"SUMO stopped on {cfg.path}: {tool_error(proc).removeprefix('Error: ')}; fix the configuration "
            f"so that 'sumo -c {cfg.path.name}' runs, or give --recording"
        )
    with raw.open("rb") as src, gzip.GzipFile(target, "wb", mtime=0) as dst:
        lines, batch = split_at_gaps(src), []
        for line in lines:  # the header comment: the first lines, up to its end
            batch.append(line)
            if b"-->" in line or len(batch) > 1000:
                break
        dst.write(strip_header(b"".join(batch)))
        batch = []
        for line in lines:
            batch.append(line)
            if len(batch) >= 10_000:
                dst.write(b"".join(batch))
                batch = []
        dst.write(b"".join(batch))
    raw.unlink()


_TIME = re.compile(rb'<timestep time="([^"]+)"')
_VEHICLE = re.compile(rb'(<vehicle id=")([^"]+)(")')


def split_at_gaps(lines: Iterable[bytes], max_gap: float = MAX_GAP) -> Iterator[bytes]:
    """SUMO's FCD lines with each stretch of a vehicle after a gap of more than ``max_gap`` [s] (SUMO
    teleports a vehicle stuck in a jam: it leaves the FCD and comes back further on) under an id of its
    own, ``<id>#1``, ``<id>#2``, ...: one vehicle per stretch, as a recording takes them."""
    t = 0.0
    last: dict[bytes, tuple[float, int]] = {}
    for line in lines:
        if m := _TIME.search(line):
            t = float(m.group(1))
        elif m := _VEHICLE.search(line):
            vid = m.group(2)
            seen, k = last.get(vid, (t, 0))
            k += t - seen > max_gap + 1e-9
            last[vid] = (t, k)
            if k:
                line = line[: m.end(2)] + b"#%d" % k + line[m.end(2) :]
        yield line


def _write(
    cfg: SumoConfig, stage: Path, out: Path, recording: Path, min_duration: float
) -> dict[str, object]:
    """The scenario and configs into ``stage`` (naming their final place in ``out``), read back: the
    scenario's route is the one the car recorded longest drove; what was written and the egos."""
    read = ReadAs(vehicle_types=(str(stage / "vtypes.add.xml"),))
    at = stage / recording.name if recording == out / RECORDING else recording
    first = _any_road(cfg)
    rec = open_recording(at, first, STEP, read)
    routes: dict[tuple[str, ...], Road | str] = {}
    refused: dict[str, int] = {}
    unfinished = _unfinished(rec)
    found = _enough(cfg, rec, egos(rec, first, (), min_duration, refused, routes=routes), refused, unfinished)
    tracks = [ego_track(rec, v, first, routes) for v in found]
    longest = max((t for t in tracks if not isinstance(t, str)), key=lambda t: t.duration)
    q = json.dumps  # a TOML basic string
    atomic_write_text(stage / "scenario.toml", _scenario_text(cfg, out, out, longest.road.edges, longest.vid))
    staged_scenario = stage / ".scenario.toml"  # its paths relative to where it is read now
    atomic_write_text(staged_scenario, _scenario_text(cfg, out, stage, longest.road.edges, longest.vid))
    road = load_road(scenario=staged_scenario)
    staged_scenario.unlink()
    refused.clear()
    found = _enough(cfg, rec, egos(rec, road, (), min_duration, refused, routes=routes), refused, unfinished)
    trucks = [
        v for v in egos(rec, road, (), min_duration, classes=(TRUCK,), routes=routes) if v not in unfinished
    ]
    entered = {v: float(rec.t0[k]) for k, v in enumerate(rec.ids)}
    common = (
        f'[scenario]\nname = {q(str(out / "scenario.toml"))}\n\n[demonstrator]\nkind = "recording"\n'
        f"file = {q(str(recording))}\nvehicle_types = [{q(str(out / 'vtypes.add.xml'))}]\n"
        f'min_duration = {min_duration:g}\nego_size = "recorded"\n'
    )
    head = f"# SUMO configuration {cfg.path.name} (irlsim scenario from-sumo)"
    written: dict[str, object] = {
        "config": str(cfg.path), "recording": str(recording), "vehicles": len(rec.ids),
        "scenario": str(out / "scenario.toml"), "egos": len(found), "trucks": len(trucks),
        "unfinished": len(unfinished),
    }  # fmt: skip
    for kind, ids in (("cars", found), ("trucks", trucks)):
        if len(ids) < MIN_EGOS:
            continue
        prefix = "" if kind == "cars" else f"{kind}-"
        classes = "" if kind == "cars" else f'ego_classes = ["{TRUCK}"]\n'
        chosen = sorted(ids, key=lambda v: (entered[v], v))  # in the order they entered
        texts, learned, driven = ego_configs(head, kind, chosen, common + classes)
        for what, text in texts.items():
            atomic_write_text(stage / f"{prefix}{what}.toml", text)
        written |= {
            f"{prefix}collect": str(out / f"{prefix}collect.toml"), f"{prefix}collect_egos": learned,
            f"{prefix}drive": str(out / f"{prefix}drive.toml"), f"{prefix}drive_egos": driven,
        }  # fmt: skip
    return written


def _unfinished(rec: Recording) -> set[str]:
    """The vehicles still driving when the recording ends: the end of the route each was recorded on is
    where SUMO stopped, not where it was going (at a crossing, often the stop line of a red light)."""
    ends = rec.t0 + (np.diff(rec.start) - 1) * rec.step
    return {rec.ids[k] for k in np.flatnonzero(ends >= ends.max() - 0.5 * rec.step)}


def _enough(
    cfg: SumoConfig, rec: Recording, found: list[str], refused: dict[str, int], unfinished: set[str]
) -> list[str]:
    """The cars of ``found`` (egos of ``rec``) that finished their drive, where there are enough to collect
    from and drive; else one line with the others counted by reason (``refused``)."""
    done = [v for v in found if v not in unfinished]
    if len(done) >= MIN_EGOS:
        return done
    if len(found) > len(done):
        refused["still driving when the recording ends"] = len(found) - len(done)
    why = ", ".join(f"{n} {words}" for words, n in sorted(refused.items(), key=lambda kv: -kv[1]))
    raise IrlsimError(
        f"{cfg.path.name}: {len(done)} of the recording's {len(rec.ids)} vehicles are cars that drive a "
        f"route of the network long enough (--min-duration) and finish it (not: {why or 'none'}), too few "
        "to collect from and drive: record longer (--duration) or lower --min-duration"
    )


def _any_road(cfg: SumoConfig) -> Road:
    """A road on ``cfg``'s network to read the recording on (its longest edge a car may drive that makes
    a route); one line where the network has none."""
    candidates = sorted(car_edges(read_network(cfg.net)), key=lambda e: (-e.getLength(), e.getID()))
    for edge in candidates[:20]:
        try:
            return Road(cfg.net, (edge.getID(),))
        except IrlsimError:
            continue
    raise IrlsimError(
        f"{cfg.path.name}: network {cfg.net} has no road for cars to record them on: give a configuration "
        "whose network has roads for cars"
    )


def _scenario_text(cfg: SumoConfig, out: Path, base: Path, edges: tuple[str, ...], longest: str) -> str:
    """The scenario of ``cfg`` on the route ``edges``, its files named from ``base`` (where it is read): a
    file inside the SUMO wheel as ``sumo_tools/...``, another relative to ``base``."""
    tools = Path(sumo_home()).resolve() / "tools"

    def name(p: Path) -> str:
        inside = p.is_relative_to(tools)
        return (
            f"sumo_tools/{p.relative_to(tools).as_posix()}" if inside else os.path.relpath(p, base.resolve())
        )

    net = name(cfg.net)
    network = (
        f"sumo_tools = {json.dumps(net.removeprefix('sumo_tools/'))}"
        if net.startswith("sumo_tools/")
        else f"file = {json.dumps(net)}"
    )
    signals = ", ".join(json.dumps(name(f)) for f in signal_files(cfg.additional))
    title = json.dumps(f"SUMO configuration {cfg.path.name}")
    return (
        f"# SUMO configuration {cfg.path.name} (irlsim scenario from-sumo)\n"
        f"name = {json.dumps(out.resolve().name)}\ndescription = {title}\n\n"
        f"[network]\n{network}\nadditional = [{signals}]\n\n"
        f"[route]   # the route of the car recorded longest ({longest})\n"
        f"edges = [{', '.join(map(json.dumps, edges))}]\n"
    )
