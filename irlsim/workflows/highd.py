"""``irlsim scenario from-highd``: a highD recording made ready to learn from. Its road becomes a SUMO
network (netconvert, from the lane markings: :mod:`irlsim.data.highd`), each carriageway a scenario, its
tracks irlsim's columnar format, and each carriageway gets a collect config (its cars as egos in turn,
split into train, validation and test episodes) and a drive config (the cars no collected episode used).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from irlsim.data.highd import (
    CLASSES,
    HighD,
    plain_network,
    read_highd,
    road_speed,
    top_speed,
    vehicle_types_xml,
    write_rows,
)
from irlsim.data.recorded import egos, open_recording
from irlsim.data.recording_as import CENTRE, EGO_CLASS, ReadAs
from irlsim.errors import IrlsimError
from irlsim.road import load_road
from irlsim.road.network import build_net
from irlsim.utils import atomic_write_text, write_json
from irlsim.workflows.imports import MIN_EGOS, ego_configs, staged

#: [s] the least time a car drives on its carriageway to be an ego: a highD road is about 420 m, which a
#: car at 120 km/h crosses in 13 s (irlsim's default, 20 s, would leave only slow cars)
MIN_DURATION = 10.0
#: [s] the step the recording is resampled to (SUMO's, as every collection's)
STEP = 0.1
NETCONVERT_CFG = """<configuration>
    <input>
        <node-files value="highd.nod.xml"/>
        <edge-files value="highd.edg.xml"/>
    </input>
    <processing>
        <offset.disable-normalization value="true"/>
        <no-turnarounds value="true"/>
    </processing>
    <report>
        <no-warnings value="true"/>
    </report>
</configuration>
"""


@dataclass(frozen=True)
class HighDRun:
    """What ``irlsim scenario from-highd`` parses its arguments into."""

    recording: Path
    """DIR/NN of a highD recording, or one of its three files"""
    out: Path
    """output folder: the network, a scenario, a recording and configs per carriageway"""
    min_duration: float = MIN_DURATION
    """[s] the least time a car drives on its carriageway to be an ego"""


def import_highd(run: HighDRun) -> dict[str, dict[str, object]]:
    """Convert ``run.recording`` into ``run.out``; returns per carriageway what was written and its egos.
    Everything read is checked before anything is written; prints where it wrote."""
    if not run.min_duration > 0:
        raise IrlsimError(f"--min-duration must be > 0 s, got {run.min_duration:g}")
    h = read_highd(run.recording)
    with staged(run.out, "from-highd") as stage:
        written = _write(h, stage, run.out, run.min_duration)
    for name, what in written.items():
        egos = f"egos {what['cars']} cars and {what['trucks']} trucks"
        print(
            f"{name} carriageway: {what['vehicles']} vehicles, {egos}; collect with 'irlsim collect "
            f"--config {what['collect']} --out data/{run.out.resolve().name}-{name}'"
        )
    print(f"from-highd: {run.out} (road.net.xml, and per carriageway a scenario, a recording and configs; "
          "highd.json)")  # fmt: skip
    return written


def _write(h: HighD, stage: Path, out: Path, min_duration: float) -> dict[str, dict[str, object]]:
    """Every file of the import into ``stage``, the configs naming their final place in ``out``."""
    roads = [h.carriageway(name) for name in h.rows if h.rows[name].num_rows]
    nodes, edges = plain_network(roads, road_speed(h))
    atomic_write_text(stage / "highd.nod.xml", nodes)
    atomic_write_text(stage / "highd.edg.xml", edges)
    atomic_write_text(stage / "netconvert.cfg", NETCONVERT_CFG)
    build_net(
        "netconvert", ["-c", "netconvert.cfg"], stage / "road.net.xml", subject=str(out / "netconvert.cfg"),
        fix="report it: the importer wrote these files", cwd=stage, force=True,
    )  # fmt: skip
    atomic_write_text(stage / "vtypes.add.xml", vehicle_types_xml())
    written = {r.name: _carriageway(h, r.name, stage, out, min_duration) for r in roads}
    write_json(stage / "highd.json", {"recording": str(h.prefix), "network": "road.net.xml", **written})
    return written


def _carriageway(h: HighD, name: str, stage: Path, out: Path, min_duration: float) -> dict[str, object]:
    """One carriageway's scenario, recording and configs in ``stage`` (the configs name their place in
    ``out``): its cars' (refused in one line when there are too few) and, where there are enough, its
    trucks'; what was written and its egos."""
    recording, scenario = out / f"{name}.parquet", out / f"{name}.toml"
    write_rows(h.rows[name], stage / recording.name)
    atomic_write_text(
        stage / scenario.name,
        f"# The {name} carriageway of highD recording {h.prefix.name} (irlsim scenario from-highd)\n"
        f'name = "{out.resolve().name}-{name}"\n'
        f'description = "highD {h.prefix.name}, the {name} carriageway"\n\n'
        f'[network]\nfile = "road.net.xml"\n\n[route]\nedges = ["{name}"]\n',
    )
    road = load_road(scenario=stage / scenario.name)
    read = ReadAs(CENTRE, (str(stage / "vtypes.add.xml"),))
    rec = open_recording(stage / recording.name, road, STEP, read)
    appears = dict(zip(rec.ids, rec.t0.tolist(), strict=True))
    out_record: dict[str, object] = {
        "vehicles": len(rec.ids), "scenario": str(scenario), "recording": str(recording),
    }  # fmt: skip
    for kind, vclass in CLASSES.items():
        found = egos(rec, road, (), min_duration, classes=(vclass,))
        chosen = sorted(found, key=lambda v: (appears[v], int(v)))  # in the order they entered
        if len(chosen) < MIN_EGOS and kind == "car":
            raise IrlsimError(
                f"highD recording {h.prefix}: the {name} carriageway has {len(chosen)} cars on the road "
                f"for {min_duration:g} s, too few to collect from and drive: lower --min-duration"
            )
        suffix = "" if kind == "car" else f"-{kind}s"
        out_record[f"{kind}s"] = len(chosen)
        if len(chosen) >= MIN_EGOS:
            paths, learned, driven = _configs(h, name, kind, vclass, chosen, stage, out, min_duration, suffix)
            out_record |= {
                f"collect{suffix}": str(paths["collect"]), f"drive{suffix}": str(paths["drive"]),
                f"collect_egos{suffix}": learned, f"drive_egos{suffix}": driven,
            }  # fmt: skip
    return out_record


def _configs(
    h: HighD,
    name: str,
    kind: str,
    vclass: str,
    chosen: list[str],
    stage: Path,
    out: Path,
    min_duration: float,
    suffix: str,
) -> tuple[dict[str, Path], list[str], list[str]]:
    """The collect and drive configs of one class's egos of a carriageway (the first nine in ten, in the
    order they entered, collected; the last tenth driven), each at its recorded size."""
    classes = "" if vclass == EGO_CLASS else f'ego_classes = ["{vclass}"]\n'
    common = (
        f'[scenario]\nname = "{out / f"{name}.toml"}"\n\n[planner]\nv_max = {top_speed(h, name):.1f}\n'
        f"v_target = {road_speed(h):.4f}\n\n"
        f'[demonstrator]\nkind = "recording"\nfile = "{out / f"{name}.parquet"}"\nposition = "centre"\n'
        f'vehicle_types = ["{out / "vtypes.add.xml"}"]\nmin_duration = {min_duration:g}\n'
        f'ego_size = "recorded"\n{classes}'
    )
    head = f"# highD {h.prefix.name}, the {name} carriageway (irlsim scenario from-highd)"
    texts, learned, driven = ego_configs(head, f"{kind}s", chosen, common)
    paths = {}
    for what, text in texts.items():
        paths[what] = out / f"{name}{suffix}-{what}.toml"
        atomic_write_text(stage / paths[what].name, text)
    return paths, learned, driven
