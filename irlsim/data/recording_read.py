"""Reading a recording's rows as they are in the file, before any check: SUMO's FCD output (``.xml``, or
``.xml.gz`` as SUMO gzips it; the angle, degrees from north, clockwise, becomes the ENU heading in radians;
or as SUMO writes it in its table formats, ``--fcd-output x.csv`` / ``x.parquet``, recognised by its
column names) and the columnar format (``.csv`` with a header line, comma or semicolon separated, or
``.parquet``, through pyarrow). A file that cannot be read as one is refused in one line naming it; the
checks and the resampling are :mod:`irlsim.data.recording`'s."""

from __future__ import annotations

import gzip
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.errors import IrlsimError
from irlsim.road import wrap_angle

COLUMNS = ("id", "t", "x", "y", "v", "heading")
#: the columns read as text, whatever their values look like
TEXT = ("id", "lane", "type")
#: optional columns: a vehicle's length and width [m], one value per vehicle
SIZES = ("length", "width")
FORMATS = (".xml", ".xml.gz", ".csv", ".parquet")
#: the numeric attributes every FCD <vehicle> needs
FCD_NUMBERS = ("x", "y", "angle", "speed")
#: SUMO's FCD as a table (``--fcd-output x.csv`` / ``x.parquet``): its column names less the prefixes of
#: SUMO's ``--output.column-header`` (tag / auto: ``vehicle_x``; full: ``timestep_vehicle_x``; plain: ``x``)
FCD_TABLE = ("time", "id", "x", "y", "angle", "speed")
FCD_PREFIXES = ("timestep_vehicle_", "timestep_", "vehicle_")


@dataclass(frozen=True)
class Rows:
    """A recording as read: one entry per row, in file order; ``row`` is the row's place in the file (a
    CSV line number, a Parquet row index, the number of an FCD ``<vehicle>`` record)."""

    path: Path
    id: np.ndarray  # [N] str
    t: np.ndarray  # [N] [s]
    x: np.ndarray
    y: np.ndarray
    v: np.ndarray  # [N] [m/s]
    heading: np.ndarray  # [N] [rad] ENU
    lane: np.ndarray | None  # [N] str, SUMO lane ids; None: not recorded
    row: np.ndarray  # [N] int
    fcd: bool  # SUMO's FCD (the heading was converted from degrees by definition)
    #: [N] [m] the optional size columns (``SIZES``) present
    size: dict[str, np.ndarray] = field(default_factory=dict)
    #: the file has no ``heading`` column: ``heading`` is NaN as read, then derived from the positions
    #: (:func:`irlsim.data.recording.headings_from_motion`)
    no_heading: bool = False
    #: [N] str, each row's vehicle type (FCD's ``type``, a columnar file's ``type`` column); None: not
    #: recorded
    vtype: np.ndarray | None = None

    def where(self, i: int) -> str:
        """The file and the place of row ``i`` in it."""
        record = self.fcd and self.path.name.lower().endswith((".xml", ".xml.gz"))
        return f"{self.path}: {'vehicle record' if record else 'row'} {int(self.row[i])}"


def read_rows(path: str | Path) -> Rows:
    """The rows of an FCD XML, CSV or Parquet file; one line naming the file when it cannot be read."""
    p = Path(path)
    if not p.is_file():
        raise IrlsimError(f"recording {p} not found: give the path of an FCD .xml, a .csv or a .parquet file")
    suffix = "".join(p.suffixes[-2:]).lower() if p.suffix.lower() == ".gz" else p.suffix.lower()
    if suffix not in FORMATS:
        raise IrlsimError(
            f"recording {p}: unknown format {suffix!r}: give an FCD .xml (or SUMO's gzipped .xml.gz), "
            "a .csv or a .parquet"
        )
    if suffix in (".xml", ".xml.gz"):
        return _read_fcd(p, gzipped=suffix == ".xml.gz")
    return _read_columns(p, suffix)


def _no_attribute(p: Path, record: int, name: str) -> IrlsimError:
    return IrlsimError(
        f"recording {p}: vehicle record {record} has no {name!r} attribute: record the FCD output with x, y, "
        "angle and speed (a --fcd-output.attributes list that names others leaves them out)"
    )


def _read_fcd(p: Path, gzipped: bool = False) -> Rows:
    """SUMO's FCD output (``gzipped``: as SUMO writes a ``.xml.gz``), streamed (xml.etree.iterparse); the
    angle (deg, north, clockwise) -> ENU rad. A <vehicle> without x, y, angle or speed (SUMO's
    ``--fcd-output.attributes`` naming others) is refused naming the attribute."""
    cols: dict[str, list[Any]] = {k: [] for k in ("id", "x", "y", "angle", "speed", "lane", "type")}
    times: list[str] = []
    t = "nan"
    try:
        with gzip.open(p) if gzipped else open(p, "rb") as f:
            for ev, el in ET.iterparse(f, events=("start", "end")):
                if ev == "start" and el.tag == "timestep":
                    t = el.attrib.get("time", "nan")
                elif ev == "start" and el.tag == "vehicle":
                    a = el.attrib
                    for k in FCD_NUMBERS:
                        if k not in a:
                            raise _no_attribute(p, len(times) + 1, k)
                        cols[k].append(a[k])
                    cols["id"].append(a.get("id", ""))
                    cols["lane"].append(a.get("lane", ""))
                    cols["type"].append(a.get("type", ""))
                    times.append(t)
                elif ev == "end" and el.tag == "timestep":
                    el.clear()
    except ET.ParseError as e:
        raise IrlsimError(f"recording {p} is not valid XML ({e}): give SUMO's FCD output unchanged") from None
    except (OSError, EOFError) as e:  # a .gz that is not gzip, or cut short
        raise IrlsimError(f"recording {p} cannot be read ({e}): give SUMO's FCD output unchanged") from None
    try:
        tt, x, y, angle, speed = (
            np.array(c, dtype=np.float64) for c in (times, cols["x"], cols["y"], cols["angle"], cols["speed"])
        )
    except ValueError as e:
        raise IrlsimError(f"recording {p}: a time or <vehicle> attribute is not a number ({e})") from None
    n = len(x)
    lanes = np.array(cols["lane"], dtype=object)
    types = np.array(cols["type"], dtype=object)
    return Rows(
        path=p,
        id=np.array(cols["id"], dtype=object),
        t=tt,
        x=x,
        y=y,
        v=speed,
        heading=np.asarray(wrap_angle(np.radians(90.0 - angle))),
        lane=lanes if n and all(lanes) else None,
        row=np.arange(1, n + 1),
        fcd=True,
        vtype=types if n and all(types) else None,
    )


def _read_columns(p: Path, suffix: str) -> Rows:
    """A CSV or Parquet file with the columns ``COLUMNS`` (and ``lane``, ``type``, the sizes), or SUMO's
    FCD as a table (:func:`_fcd_table`), through pyarrow."""
    try:
        if suffix == ".csv":
            import pyarrow.csv as pacsv

            with open(p, encoding="utf-8", errors="replace") as f:
                header = f.readline()
            sep = ";" if header.count(";") > header.count(",") else ","  # SUMO's tables: ';'
            text = [f"{x}{c}" for x in ("", *FCD_PREFIXES) for c in TEXT]
            opts = pacsv.ConvertOptions(column_types=dict.fromkeys(text, "string"))
            table = pacsv.read_csv(p, parse_options=pacsv.ParseOptions(delimiter=sep), convert_options=opts)
            first = 2  # the header is line 1
        else:
            import pyarrow.parquet as pq

            table = pq.read_table(p)
            first = 0
    except Exception as e:  # pyarrow's own errors name the problem
        msg = str(e).strip().splitlines()
        raise IrlsimError(f"recording {p} cannot be read ({msg[0] if msg else type(e).__name__})") from None
    fcd = _fcd_table(table.column_names)
    if fcd:
        return _read_fcd_table(p, table, fcd, first)
    if "timestep_time" in table.column_names:  # SUMO's table (tag, auto and full headers), lacking some
        stripped = {c.removeprefix("timestep_").removeprefix("vehicle_") for c in table.column_names}
        lacking = [k for k in FCD_TABLE if k not in stripped]
        raise IrlsimError(
            f"recording {p} is SUMO's FCD output without {', '.join(lacking)}: record it with x, y, angle "
            "and speed (a --fcd-output.attributes list that names others leaves them out)"
        )
    missing = [c for c in COLUMNS[:-1] if c not in table.column_names]  # the heading may be derived
    if missing:
        raise IrlsimError(
            f"recording {p} lacks the column(s) {', '.join(missing)}: give id, t [s], x, y [m], v [m/s] "
            "(heading [rad], lane optional)"
        )
    n = table.num_rows
    given = [c for c in COLUMNS[1:] if c in table.column_names]
    num = {"heading": np.full(n, np.nan)} | {c: _numbers(table, c, p, "give numbers") for c in given}
    lane = None
    if "lane" in table.column_names:
        lane = _text(table.column("lane"))
    ids = _text(table.column("id"))
    size = {c: _numbers(table, c, p, "give metres") for c in SIZES if c in table.column_names}
    vtype = _text(table.column("type")) if "type" in table.column_names else None
    rows = (num["t"], num["x"], num["y"], num["v"], num["heading"], lane, np.arange(n) + first, False)
    return Rows(p, ids, *rows, size=size, no_heading="heading" not in given, vtype=vtype)


def _fcd_table(names: list[str]) -> dict[str, str]:
    """{SUMO's attribute: its column} where ``names`` are SUMO's FCD as a table (every attribute of
    ``FCD_TABLE`` there, under one of SUMO's header styles); {} otherwise."""
    for prefix in ("", *FCD_PREFIXES):
        found = {c.removeprefix(prefix): c for c in names if c.startswith(prefix)}
        found["time"] = next((c for c in names if c in ("time", "timestep_time")), "")
        if all(found.get(k) for k in FCD_TABLE):
            return found
    return {}


def _read_fcd_table(p: Path, table: Any, cols: dict[str, str], first: int) -> Rows:
    """SUMO's FCD as a table: the rows of vehicles (SUMO writes a row with the time alone for a step
    without any, and persons in their own columns), the angle to the ENU heading as for the XML."""
    ids = _text(table.column(cols["id"]))
    keep = np.flatnonzero(ids != "")
    table = table.take(keep)
    if not _is_numeric(table.column(cols["time"])) and table.num_rows:
        raise IrlsimError(
            f"recording {p}: its time column is not seconds ({table.column(cols['time'])[0]}): write the FCD "
            "output without --human-readable-time"
        )
    num = {k: _numbers(table, cols[k], p, "give SUMO's FCD output unchanged") for k in FCD_TABLE if k != "id"}
    text = {k: _text(table.column(cols[k])) if k in cols else None for k in ("lane", "type")}
    lane, vtype = (t if t is not None and len(t) and all(t) else None for t in (text["lane"], text["type"]))
    return Rows(
        path=p,
        id=ids[keep],
        t=num["time"],
        x=num["x"],
        y=num["y"],
        v=num["speed"],
        heading=np.asarray(wrap_angle(np.radians(90.0 - num["angle"]))),
        lane=lane,
        row=keep + first,
        fcd=True,
        vtype=vtype,
    )


def _is_numeric(column: Any) -> bool:
    """Whether a pyarrow column holds numbers."""
    import pyarrow.types as pat

    return bool(pat.is_integer(column.type) or pat.is_floating(column.type) or pat.is_null(column.type))


def _numbers(table: Any, c: str, p: Path, fix: str) -> np.ndarray:
    """Column ``c`` of a pyarrow ``table`` as float64; one line naming it where it is not numbers."""
    try:
        return np.asarray(table.column(c).to_numpy(zero_copy_only=False), dtype=np.float64)
    except (ValueError, TypeError) as e:
        raise IrlsimError(f"recording {p}: the column {c} is not numeric ({e}): {fix}") from None


def _text(column: Any) -> np.ndarray:
    """A pyarrow column as an object array of str (numbers as their text, nulls as '')."""
    import pyarrow as pa

    return np.asarray(column.cast(pa.string()).fill_null("").to_numpy(zero_copy_only=False), dtype=object)
