"""The vehicle types a recording was made with, asked of SUMO: each type's length, width and class.

SUMO's FCD output names each vehicle's type (``type``, an id of the user's files) and carries no size
or class. The files that define the types (a route file, an additional file: what the recording's SUMO
run loaded) are loaded with the recording's network by SUMO itself (libsumo, in a process of its own so
that the command's own simulation is untouched), and every type SUMO then knows is read back with what
SUMO makes of it: an attribute the file leaves out takes SUMO's default for the type's class (a truck
7.1 m, a bicycle 1.6 m in SUMO 1.28), which irlsim does not keep a list of. SUMO's own types
(``DEFAULT_VEHTYPE``, ``DEFAULT_BIKETYPE``, ...) are among them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from irlsim.errors import IrlsimError
from irlsim.road.network import sumo_tools_path
from irlsim.sim.libsumo_process import run_libsumo

#: [s] at most this long for SUMO to load the network and the files
PROBE_TIMEOUT_S = 120.0

_PROBE = """
import json, sys, libsumo
net, files = sys.argv[1], sys.argv[2]
try:
    libsumo.start(["sumo", "-n", net, "-a", files, "--begin", "0", "--no-step-log", "true",
                   "--no-warnings", "true", "--xml-validation", "never"])
except Exception as e:
    print(json.dumps({"error": str(e)}))
    sys.exit(0)
vt = libsumo.vehicletype
print(json.dumps({t: [vt.getLength(t), vt.getWidth(t), vt.getVehicleClass(t)] for t in vt.getIDList()}))
libsumo.close()
"""


@dataclass(frozen=True)
class VehicleType:
    """One type as SUMO makes it."""

    length: float  # [m]
    width: float  # [m]
    vclass: str  # SUMO's vehicle class


def type_file(name: str) -> Path:
    """The path of a vehicle-types file as a config names it (``sumo_tools/...``: inside the wheel);
    one line when it is not there."""
    p = sumo_tools_path(name)
    if not p.is_file():
        raise IrlsimError(
            f"demonstrator.vehicle_types: {p} not found: give the route or additional files the recording's "
            "SUMO run loaded its vehicle types from"
        )
    return p


def vehicle_types(net_file: str | Path, files: tuple[str, ...]) -> dict[str, VehicleType]:
    """Every vehicle type SUMO knows after loading ``files`` (paths as :func:`type_file` takes them) with
    ``net_file``, by id; SUMO's first error as one line naming the files."""
    paths = [type_file(f) for f in files]
    listed = ",".join(str(p.resolve()) for p in paths)
    task = "load demonstrator.vehicle_types"
    res, errors = run_libsumo(_PROBE, [str(net_file), listed], PROBE_TIMEOUT_S, task)
    out = res.stdout.strip().splitlines()
    answer = json.loads(out[-1]) if out and out[-1].startswith("{") else {}
    if errors or res.returncode != 0 or "error" in answer or not answer:
        why = errors[0] if errors else answer.get("error") or f"exit status {res.returncode}"
        raise IrlsimError(
            f"SUMO refuses demonstrator.vehicle_types {', '.join(map(str, paths))} ({why}): give files of "
            "<vType> definitions that load with the scenario's network"
        )
    return {t: VehicleType(float(a[0]), float(a[1]), str(a[2])) for t, a in answer.items()}
