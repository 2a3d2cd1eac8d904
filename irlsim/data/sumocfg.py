"""A SUMO configuration (``.sumocfg``) read for what a recording made with it needs: its network, the
files that define its vehicle types, the signal programs it ran with, and its time.

SUMO's configuration is XML: each option an element whose ``value`` (or ``v``) holds it, under any
section (``<input>``, ``<time>``); an option may be written by its name or one of SUMO's synonyms
(``net-file``, ``net``, ``n``). Lists are separated by commas (or spaces), and a relative path is relative
to the configuration file, as SUMO reads them. Times are seconds or SUMO's ``[[D:]H:]M:S``.

What irlsim takes from the files the configuration loads:

- the vehicle types: every ``<vType>`` of its route and additional files (also those inside a
  ``<vTypeDistribution>``: SUMO's FCD output names the member type), copied verbatim into one file of
  types alone, so that SUMO can load them with the network without the routes, stops or outputs around
  them (:func:`vtypes_xml`);
- the signal programs: the additional files that hold a ``<tlLogic>`` (:func:`signal_files`), which the
  replay runs with, as the recording did. Other additional content (detectors, outputs, rerouters) is
  left out: the recording is the traffic.
"""

from __future__ import annotations

import gzip
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from irlsim.errors import IrlsimError
from irlsim.road.network import sumo_tools_path

#: an option -> its names in a configuration (SUMO's own name first, then its synonyms)
NAMES = {
    "net": ("net-file", "net", "n"),
    "routes": ("route-files", "routes", "r"),
    "additional": ("additional-files", "additional", "a"),
    "begin": ("begin", "b"),
    "end": ("end", "e"),
    "step": ("step-length",),
}
#: SUMO's default step [s]
DEFAULT_STEP = 1.0


@dataclass(frozen=True)
class SumoConfig:
    """What irlsim reads of a SUMO configuration: every path absolute."""

    path: Path
    net: Path
    routes: tuple[Path, ...]
    additional: tuple[Path, ...]
    begin: float  # [s]
    end: float | None  # [s] None: until the last vehicle arrives
    step: float  # [s]


def sumo_time(text: str, what: str) -> float:
    """[s] a time of a SUMO configuration: seconds, or ``[[D:]H:]M:S``; one line where it is neither."""
    parts = text.strip().split(":")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if not values or len(values) > 4:
        raise IrlsimError(f"{what}: {text!r} is no time: give seconds or H:M:S")
    seconds = 0.0
    for value, unit in zip(reversed(values), (1, 60, 3600, 86400), strict=False):
        seconds += value * unit
    return seconds


def read_sumocfg(path: str | Path) -> SumoConfig:
    """``path`` read as a SUMO configuration; one line naming what is wrong (no file, no XML, no network,
    a file it names missing, a time that is none); ``sumo_tools/<path>`` is inside the SUMO wheel's tools
    folder (its game scenarios: ``sumo_tools/game/cross.sumocfg``)."""
    path = sumo_tools_path(str(path))
    if not path.is_file():
        raise IrlsimError(f"SUMO configuration {path} not found: give the .sumocfg your SUMO run used")
    root = xml_root(path, "SUMO configuration")
    values: dict[str, str] = {}
    for el in root.iter():
        for key, names in NAMES.items():
            if el.tag in names and key not in values:
                values[key] = el.get("value", el.get("v", ""))
    if not values.get("net"):
        raise IrlsimError(f"SUMO configuration {path} names no network (net-file): give one that does")
    net, *more = _paths(path, values["net"], "net-file")
    if more:
        raise IrlsimError(f"SUMO configuration {path} names {len(more) + 1} networks: give one")
    end = sumo_time(values["end"], f"{path}: end") if values.get("end") else None
    step = sumo_time(values["step"], f"{path}: step-length") if values.get("step") else DEFAULT_STEP
    if not step > 0:
        raise IrlsimError(f"SUMO configuration {path}: step-length must be > 0 s, got {values['step']}")
    return SumoConfig(
        path.resolve(),
        net,
        _paths(path, values.get("routes", ""), "route-files"),
        _paths(path, values.get("additional", ""), "additional-files"),
        sumo_time(values["begin"], f"{path}: begin") if values.get("begin") else 0.0,
        end if end is not None and end >= 0 else None,
        step,
    )


def _paths(config: Path, value: str, option: str) -> tuple[Path, ...]:
    """The files an option names, relative to the configuration; one line for one that is missing."""
    out = []
    for name in (n for n in re.split(r"[,\s]+", value) if n):
        p = (config.parent / name).resolve()
        if not p.is_file():
            raise IrlsimError(f"SUMO configuration {config}: {option} {name} not found at {p}: fix the path")
        out.append(p)
    return tuple(out)


def xml_root(path: Path, what: str) -> ET.Element:
    """The root element of an XML file (gzipped where its name ends in ``.gz``); one line where it is no
    XML."""
    try:
        if path.suffix == ".gz":
            with gzip.open(path, "rb") as f:
                return ET.parse(f).getroot()
        return ET.parse(path).getroot()
    except (ET.ParseError, OSError, EOFError) as e:
        raise IrlsimError(
            f"{what} {path} is no XML file SUMO reads ({e}): give the file SUMO loaded"
        ) from None


def vtypes_xml(files: tuple[Path, ...]) -> tuple[str, int]:
    """An additional file of every ``<vType>`` in ``files`` (in their order; a type defined twice is kept
    as first defined, as SUMO keeps one), and how many there are."""
    seen: dict[str, str] = {}
    for f in files:
        for el in xml_root(f, "SUMO file").iter("vType"):
            vid = el.get("id", "")
            if vid and vid not in seen:
                el.tail = None
                seen[vid] = ET.tostring(el, encoding="unicode").strip()
    body = "".join(f"    {text}\n" for text in seen.values())
    return f"<additional>\n{body}</additional>\n", len(seen)


def signal_files(files: tuple[Path, ...]) -> tuple[Path, ...]:
    """The files of ``files`` that hold a signal program (``<tlLogic>``)."""
    return tuple(f for f in files if next(xml_root(f, "SUMO file").iter("tlLogic"), None) is not None)
