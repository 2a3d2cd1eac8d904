"""A highD recording (Krajewski et al., ITSC 2018: drone tracks of German motorways at 25 Hz) read as an
irlsim recording on a SUMO network of its road.

A recording ``NN`` is three CSV files, ``NN_tracks.csv`` (one row per vehicle and frame),
``NN_tracksMeta.csv`` (one row per vehicle) and ``NN_recordingMeta.csv`` (one row), in the layout of
highD's own tools (github.com/RobertKrajewski/highD-dataset). Their conventions, and what irlsim makes of
them:

- positions are metres in the image's frame (x to the right, y down) and give the upper left corner of
  the vehicle's bounding box; ``width`` is the box's extent along x (the vehicle's length, as vehicles
  drive along x), ``height`` along y (its width). irlsim's network keeps x and turns y over (``y_net =
  -y``), and a row's point is the box's centre (read with ``position = "centre"``);
- ``xVelocity``, ``yVelocity`` [m/s] give the speed and the heading (the direction of motion);
- ``drivingDirection`` is 1 for the upper carriageway (driving to the left, -x) and 2 for the lower (to
  the right, +x); ``upperLaneMarkings`` and ``lowerLaneMarkings`` are the image y of each carriageway's
  lane markings, separated by ``;``;
- ``class`` is ``Car`` or ``Truck``: SUMO's classes ``passenger`` (egos) and ``truck`` (replayed only);
- ``speedLimit`` [m/s], -1 where the motorway has none; ``frameRate`` [Hz].

The road is one straight edge per carriageway, its lanes as wide as the markings are apart on average
(irlsim places a road's lanes at one width), spanning the recording's x range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from irlsim.errors import IrlsimError

FILES = ("tracks", "tracksMeta", "recordingMeta")
TRACK_COLUMNS = ("frame", "id", "x", "y", "width", "height", "xVelocity", "yVelocity")
META_COLUMNS = ("id", "class", "drivingDirection")
RECORDING_COLUMNS = ("frameRate", "speedLimit", "upperLaneMarkings", "lowerLaneMarkings")
#: highD's drivingDirection of each carriageway
DIRECTIONS = {"upper": 1, "lower": 2}
#: highD's classes (lower case) and the SUMO vehicle types the recording names (their vClass)
CLASSES = {"car": "passenger", "truck": "truck"}
#: [m/s] a carriageway without a speed limit gets the advisory speed of German motorways, 130 km/h
ADVISORY_SPEED = 130.0 / 3.6
#: [m/s] the highest speed limit read as one (above: not m/s)
MAX_LIMIT = 200.0 / 3.6
#: [m] the road reaches this far beyond the first and the last recorded box
MARGIN = 10.0
#: [m] the range of a lane's width the markings may give (outside it: not highD's metres)
LANE_WIDTH = (2.0, 6.0)


@dataclass(frozen=True)
class Carriageway:
    """One driving direction's road: a straight edge from ``x_from`` to ``x_to`` (network coordinates)."""

    name: str  # "upper" or "lower"
    y: float  # [m] network y of the edge's middle
    lanes: int
    lane_width: float  # [m]
    x_from: float
    x_to: float


@dataclass(frozen=True)
class HighD:
    """A highD recording as read: its files, its frame rate, its speed limit and, per carriageway, the
    lane markings and the rows of its vehicles (network coordinates, the boxes' centres)."""

    prefix: Path
    frame_rate: float  # [Hz]
    speed_limit: float  # [m/s]; <= 0: none
    markings: dict[str, np.ndarray]  # per carriageway: the markings' image y, ascending
    rows: dict[str, pa.Table]  # per carriageway: id, t, x, y, v, heading, length, width, type
    x_range: tuple[float, float]  # [m] the road's ends: MARGIN beyond the first and the last recorded box

    def carriageway(self, name: str) -> Carriageway:
        m = self.markings[name]
        ends = self.x_range if name == "lower" else self.x_range[::-1]
        return Carriageway(
            name, -float(m[0] + m[-1]) / 2, len(m) - 1, float(m[-1] - m[0]) / (len(m) - 1), *ends
        )


def highd_files(path: str | Path) -> dict[str, Path]:
    """The three files of the recording ``path`` names: ``DIR/NN`` or any of its files; one line when
    one is missing."""
    p = Path(path)
    stem = p.name
    for kind in FILES:
        if stem.endswith(f"_{kind}.csv"):
            stem = stem[: -len(f"_{kind}.csv")]
            break
    files = {kind: p.with_name(f"{stem}_{kind}.csv") for kind in FILES}
    missing = [str(f) for f in files.values() if not f.is_file()]
    if missing:
        raise IrlsimError(
            f"highD recording {path}: {missing[0]} not found: give DIR/NN (or one of its files) where "
            "NN_tracks.csv, NN_tracksMeta.csv and NN_recordingMeta.csv are"
        )
    return files


def read_highd(path: str | Path) -> HighD:
    """Read and convert a highD recording (:func:`highd_files`); every problem is one line naming the
    file before anything is written."""
    files = highd_files(path)
    tracks = _read(files["tracks"], TRACK_COLUMNS)
    meta = _read(files["tracksMeta"], META_COLUMNS)
    rec = _read(files["recordingMeta"], RECORDING_COLUMNS)
    frame_rate = float(_numbers(rec, "frameRate", files["recordingMeta"])[0])
    if not frame_rate > 0:
        raise IrlsimError(f"{files['recordingMeta']}: frameRate {frame_rate:g} is not a rate: give it in Hz")
    speed_limit = float(_numbers(rec, "speedLimit", files["recordingMeta"])[0])
    if speed_limit != -1 and not 0 < speed_limit <= MAX_LIMIT:
        raise IrlsimError(
            f"{files['recordingMeta']}: speedLimit {speed_limit:g} is not highD's (m/s, -1 where there is "
            f"none; {speed_limit:g} m/s is {speed_limit * 3.6:.0f} km/h): give it in m/s"
        )
    markings = {name: _markings(rec, name, files["recordingMeta"]) for name in DIRECTIONS}

    ids = _numbers(meta, "id", files["tracksMeta"]).astype(np.int64)
    classes = np.array([str(c).strip().lower() for c in meta.column("class").to_pylist()], dtype=object)
    unknown = sorted(set(classes) - set(CLASSES))
    if unknown:
        raise IrlsimError(
            f"{files['tracksMeta']}: vehicle class {unknown[0]!r} is not one of highD's "
            f"({', '.join(c.title() for c in CLASSES)}): fix the file"
        )
    direction = _numbers(meta, "drivingDirection", files["tracksMeta"]).astype(np.int64)
    bad = ~np.isin(direction, list(DIRECTIONS.values()))
    if bad.any():
        raise IrlsimError(
            f"{files['tracksMeta']}: vehicle {ids[bad][0]} has drivingDirection {direction[bad][0]}: "
            "highD's are 1 (upper) and 2 (lower)"
        )
    vid = _numbers(tracks, "id", files["tracks"]).astype(np.int64)
    order = np.argsort(ids)
    at = np.searchsorted(ids[order], vid)
    known = (at < len(ids)) & (ids[order][np.minimum(at, len(ids) - 1)] == vid)
    if not known.all():
        raise IrlsimError(
            f"{files['tracks']}: vehicle {vid[~known][0]} is not in {files['tracksMeta'].name}: "
            "give the files of one recording"
        )
    row_meta = order[at]
    cols = {c: _numbers(tracks, c, files["tracks"]) for c in TRACK_COLUMNS[2:]}
    length, width = cols["width"], cols["height"]
    if not ((length > 0).all() and (width > 0).all()):
        raise IrlsimError(f"{files['tracks']}: a box of no size (width or height <= 0): fix the file")
    vx, vy = cols["xVelocity"], -cols["yVelocity"]  # the network's y is the image's turned over
    table = {
        "id": vid.astype(str),
        "t": _numbers(tracks, "frame", files["tracks"]) / frame_rate,
        "x": cols["x"] + length / 2,
        "y": -(cols["y"] + width / 2),
        "v": np.hypot(vx, vy),
        "heading": np.arctan2(vy, vx),
        "length": length,
        "width": width,
        "type": classes[row_meta],
    }
    rows = {
        name: pa.table({k: v[direction[row_meta] == code] for k, v in table.items()})
        for name, code in DIRECTIONS.items()
    }
    prefix = files["tracks"].parent / files["tracks"].name[: -len("_tracks.csv")]
    ends = (float(np.min(table["x"] - length / 2)) - MARGIN, float(np.max(table["x"] + length / 2)) + MARGIN)
    return HighD(prefix, frame_rate, speed_limit, markings, rows, ends)


def write_rows(table: pa.Table, path: Path) -> None:
    """One carriageway's rows as irlsim's columnar format (Parquet), vehicle by vehicle, each in time (the
    order egos are split in is :mod:`irlsim.workflows.highd`'s: by the time they entered)."""
    pq.write_table(table.sort_by([("id", "ascending"), ("t", "ascending")]), path)


def vehicle_types_xml() -> str:
    """The recording's vehicle types: ``car`` and ``truck`` of highD's classes (sizes come per vehicle)."""
    rows = "".join(f'    <vType id="{c}" vClass="{v}"/>\n' for c, v in CLASSES.items())
    return f"<additional>\n{rows}</additional>\n"


def plain_network(roads: list[Carriageway], speed: float) -> tuple[str, str]:
    """netconvert's node and edge files of the carriageways (straight, lanes at one width)."""
    nodes, edges = [], []
    for r in roads:
        for end, x in (("from", r.x_from), ("to", r.x_to)):
            nodes.append(f'    <node id="{r.name}_{end}" x="{x:.3f}" y="{r.y:.3f}" type="dead_end"/>')
        edges.append(
            f'    <edge id="{r.name}" from="{r.name}_from" to="{r.name}_to" numLanes="{r.lanes}" '
            f'speed="{speed:.3f}" spreadType="center" width="{r.lane_width:.3f}"/>'
        )
    return (
        "<nodes>\n" + "\n".join(nodes) + "\n</nodes>\n",
        "<edges>\n" + "\n".join(edges) + "\n</edges>\n",
    )


def road_speed(h: HighD) -> float:
    """[m/s] the carriageways' speed: the recording's limit, else the advisory 130 km/h."""
    return h.speed_limit if h.speed_limit > 0 else ADVISORY_SPEED


def top_speed(h: HighD, name: str) -> float:
    """[m/s] the planner's top speed for a carriageway: the fastest car's speed, rounded up to a whole
    m/s, at least the road's speed (no recorded car is faster than every policy)."""
    t = h.rows[name]
    cars = t.column("type").to_numpy(zero_copy_only=False) == "car"
    v = _column(t, "v")[cars]
    return float(max(math.ceil(float(v.max())) if len(v) else 0.0, math.ceil(road_speed(h))))


# ----------------------------------------------------------------------------------------------- reading


def _read(path: Path, columns: tuple[str, ...]) -> pa.Table:
    try:
        table = pacsv.read_csv(path)
    except (pa.ArrowInvalid, OSError) as e:
        raise IrlsimError(
            f"{path}: not a CSV file highD writes ({str(e).splitlines()[0]}): restore it"
        ) from None
    missing = [c for c in columns if c not in table.column_names]
    if missing:
        raise IrlsimError(
            f"{path}: no column {missing[0]!r} (it has {', '.join(table.column_names[:10])}"
            f"{', ...' if len(table.column_names) > 10 else ''}): give highD's file"
        )
    if table.num_rows == 0:
        raise IrlsimError(f"{path}: no rows: give a recording's file")
    return table


def _column(table: pa.Table, name: str) -> np.ndarray:
    return np.asarray(table.column(name).to_numpy(zero_copy_only=False), dtype=np.float64)


def _numbers(table: pa.Table, name: str, path: Path) -> np.ndarray:
    col = table.column(name)
    if not (pa.types.is_integer(col.type) or pa.types.is_floating(col.type)) or col.null_count:
        raise IrlsimError(f"{path}: column {name!r} is not all numbers: fix the file")
    out = _column(table, name)
    if not np.isfinite(out).all():
        raise IrlsimError(f"{path}: column {name!r} is not all finite numbers: fix the file")
    return out


def _markings(rec: pa.Table, name: str, path: Path) -> np.ndarray:
    key = f"{name}LaneMarkings"
    text = str(rec.column(key)[0].as_py())
    try:
        m = np.array(sorted(float(v) for v in text.split(";") if v.strip()))
    except ValueError:
        m = np.array([])
    widths = np.diff(m)
    if len(m) < 2 or not ((widths >= LANE_WIDTH[0]) & (widths <= LANE_WIDTH[1])).all():
        raise IrlsimError(
            f"{path}: {key} {text!r} are not a carriageway's lane markings (two or more image y in metres, "
            f"separated by ';', {LANE_WIDTH[0]:g}-{LANE_WIDTH[1]:g} m apart): fix the file"
        )
    return m
