"""How a recording's file is read: the point of a vehicle its positions give, and its vehicles' types.

- ``position`` (``demonstrator.position``): SUMO and irlsim place a vehicle by its front bumper's centre;
  most public datasets' tracks give the centre of its box. 'centre' moves each row half its vehicle's
  length along its heading (:func:`to_front`); SUMO's FCD is the front bumper by definition.
- ``coordinates`` (``demonstrator.coordinates``): what x, y are: the network's coordinates (SUMO's FCD,
  irlsim's), longitude and latitude ('geo': ``sumo --fcd-output.geo``, a GPS track), placed on the
  network by SUMO through the network's projection (:func:`irlsim.sim.geo.geo_to_network`), or the
  network's projected coordinates before its ``netOffset`` ('utm': ``sumo --fcd-output.utm``)
  (:func:`to_network`).
- ``vehicle_types`` (``demonstrator.vehicle_types``): the files defining the types a recording names
  (FCD's ``type``, a ``type`` column), loaded by SUMO (:mod:`irlsim.sim.vehicle_types`): each vehicle's
  length, width and class are then its type's (:func:`typed`).
- ``ego_classes`` and ``ego_size`` (``demonstrator.ego_classes``, ``demonstrator.ego_size``): which of its
  vehicles may be egos (their types' SUMO classes; a car's by default), and whether an ego is planned and
  driven at the scenario's ego size or at its own recorded one
  (:func:`irlsim.data.recorded.recorded_episode`).

Each refusal is one line naming the file (and the row), before any work.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from irlsim.data.recording_read import Rows
from irlsim.errors import IrlsimError
from irlsim.sim.geo import geo_to_network
from irlsim.sim.vehicle_types import VehicleType
from irlsim.sim.vtype import ego_type_attributes

#: the point of a vehicle a recording's x, y give (``demonstrator.position``): its front bumper's centre
#: (SUMO's convention, the FCD's by definition) or the centre of its box (most public datasets' tracks)
FRONT, CENTRE = "front", "centre"
POSITIONS = (FRONT, CENTRE)
#: what a recording's x, y are (``demonstrator.coordinates``): the network's coordinates (SUMO's FCD), its
#: longitude and latitude (SUMO's --fcd-output.geo) or its projection's before the netOffset (.utm)
NETWORK, GEO, UTM = "network", "geo", "utm"
COORDINATES = (NETWORK, GEO, UTM)
#: the class a recorded vehicle's type has to be an ego by default: irlsim's ego type's
#: (sumo_net/vtypes.add.xml, a passenger car)
EGO_CLASS = ego_type_attributes()["vClass"]
#: the size an ego is planned and driven at (``demonstrator.ego_size``): the scenario's ego size, or the
#: ego's own recorded length and width
SCENARIO_SIZE, RECORDED_SIZE = "scenario", "recorded"
EGO_SIZES = (SCENARIO_SIZE, RECORDED_SIZE)


@dataclass(frozen=True)
class ReadAs:
    """How a recording's file is read (``demonstrator.position``, ``demonstrator.vehicle_types``)."""

    #: the point of a vehicle its x, y give (:data:`POSITIONS`)
    position: str = FRONT
    #: the files that define its vehicles' types (FCD's ``type``, a ``type`` column), as the config names
    #: them: each vehicle's size and class are its type's, as SUMO makes it
    #: (:mod:`irlsim.sim.vehicle_types`); empty: not read
    vehicle_types: tuple[str, ...] = ()
    #: what its x, y are (:data:`COORDINATES`), turned into the network's before anything else
    coordinates: str = NETWORK
    #: the SUMO classes (its types') whose vehicles may be egos
    ego_classes: tuple[str, ...] = (EGO_CLASS,)
    #: the size an ego is planned and driven at (:data:`EGO_SIZES`)
    ego_size: str = SCENARIO_SIZE


#: a file read as it is: front bumpers, no types
AS_RECORDED = ReadAs()


def check_position(rows: Rows, position: str) -> None:
    """Refuse, in one line, a reference point the rows cannot be read at: SUMO's FCD is the front bumper
    by definition, and a box's centre moves to the front bumper by the vehicle's length."""
    if position not in POSITIONS:
        raise IrlsimError(
            f"recording {rows.path}: position {position!r} is not one of {', '.join(POSITIONS)}: give the "
            "point of the vehicle its x, y are"
        )
    if position == CENTRE and rows.fcd:
        raise IrlsimError(
            f"recording {rows.path} is SUMO's FCD output, whose x, y are the front bumper by definition: "
            "drop demonstrator.position (or set it to 'front')"
        )
    if position == CENTRE and "length" not in rows.size:
        raise IrlsimError(
            f"recording {rows.path} has no length column, which position = 'centre' needs (the front "
            "bumper is the centre plus half the length along the heading): add each vehicle's length [m]"
        )


def to_network(rows: Rows, coordinates: str, net: Any, net_file: str | Path | None) -> Rows:
    """The rows with x, y in the network's coordinates (``net``: a sumolib network, read from
    ``net_file``): 'geo' places longitude x and latitude y through the network's projection, by SUMO;
    'utm' adds the network's netOffset; 'network' leaves them. Headings stay as recorded (the network's
    frame, as SUMO's FCD writes its angle with either option). One line before any work where the rows
    cannot be such coordinates or the network has no projection."""
    if coordinates not in COORDINATES:
        raise IrlsimError(
            f"recording {rows.path}: coordinates {coordinates!r} is not one of "
            f"{', '.join(COORDINATES)}: give what its x, y are"
        )
    if coordinates == NETWORK:
        return rows
    if coordinates == UTM:
        dx, dy = (float(v) for v in net.getLocationOffset())
        return dataclasses.replace(rows, x=rows.x + dx, y=rows.y + dy)
    i = int(np.argmax((np.abs(rows.x) > 180.0) | (np.abs(rows.y) > 90.0)))
    if abs(rows.x[i]) > 180.0 or abs(rows.y[i]) > 90.0:
        raise IrlsimError(
            f"{rows.where(i)}: x {rows.x[i]:g}, y {rows.y[i]:g} are no longitude (-180..180) and latitude "
            "(-90..90), which coordinates = 'geo' reads: drop demonstrator.coordinates for the network's "
            "metres"
        )
    if net_file is None or not net.hasGeoProj():
        raise IrlsimError(
            f"recording {rows.path}: coordinates = 'geo', but the network {net_file or ''} has no "
            "geographic projection (its location's projParameter is '!'): give the scenario the "
            "recording was made on (imported from OpenStreetMap or built with a projection), or x, y in "
            "the network's coordinates"
        )
    x, y = geo_to_network(net_file, rows.x, rows.y)
    return dataclasses.replace(rows, x=x, y=y)


def to_front(rows: Rows, position: str) -> Rows:
    """The rows with x, y at the front bumper's centre (SUMO's point): ``position`` 'centre' moves each
    row half its vehicle's length along its heading; 'front' leaves them as they are."""
    if position == FRONT:
        return rows
    half = 0.5 * rows.size["length"]
    return dataclasses.replace(
        rows, x=rows.x + half * np.cos(rows.heading), y=rows.y + half * np.sin(rows.heading)
    )


def typed(rows: Rows, types: Mapping[str, VehicleType]) -> tuple[Rows, np.ndarray]:
    """The rows with each vehicle's length and width its type's (a size column of the file wins), and
    per row its type's class; a recording that names no types, or a type ``types`` lacks, is one line."""
    if rows.vtype is None:
        raise IrlsimError(
            f"recording {rows.path} names no vehicle types (FCD's type attribute, a type column), which "
            "demonstrator.vehicle_types reads: record them, or drop vehicle_types"
        )
    blank = np.flatnonzero(rows.vtype == "")
    if len(blank):
        raise IrlsimError(
            f"{rows.where(int(blank[0]))}: vehicle {rows.id[blank[0]]} has no type, which "
            "demonstrator.vehicle_types reads: give every row its vehicle's type"
        )
    names, which = np.unique(rows.vtype.astype(str), return_inverse=True)  # the loop: over the names
    unknown = np.flatnonzero([str(n) not in types for n in names])
    if len(unknown):
        i = int(np.flatnonzero(np.isin(which, unknown))[0])  # the first row of a type not defined
        shown = ", ".join(sorted(t for t in types if not t.startswith("DEFAULT_"))[:6])
        raise IrlsimError(
            f"{rows.where(i)}: type {rows.vtype[i]!r} is not defined in demonstrator.vehicle_types (it "
            f"defines {shown or 'only SUMO defaults'}): give the files the recording's SUMO run loaded"
        )
    table = [types[str(n)] for n in names]
    size = {
        "length": np.array([vt.length for vt in table])[which],
        "width": np.array([vt.width for vt in table])[which],
    }
    vclass = np.array([vt.vclass for vt in table], dtype=object)[which]
    return dataclasses.replace(rows, size=size | rows.size), vclass
