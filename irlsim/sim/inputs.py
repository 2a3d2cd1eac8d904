"""The files SUMO reads besides the network, checked before SUMO starts: each broken one is named as the
file at fault in one line, never blamed on the network or retried as a failed episode."""

from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

from irlsim.errors import IrlsimError
from irlsim.sim.traffic import BG_TYPE

#: how to get the shipped vehicle types back
RESTORE = "restore it ('git checkout sumo_net/vtypes.add.xml' or reinstall irlsim)"


def check_inputs(vtypes_file: Path | str, demand: tuple[Path, ...]) -> None:
    """The vehicle types and a scenario's demand are well-formed XML, and the vehicle types define the
    types irlsim inserts (``ego`` and the background's): else one IrlsimError line naming the file."""
    for path in (vtypes_file, *demand):
        try:
            tree = ElementTree.parse(path)
        except (ElementTree.ParseError, OSError) as e:
            what = "vehicle types" if path == vtypes_file else "route file"
            fix = RESTORE if path == vtypes_file else "fix it or the scenario's [traffic] routes"
            raise IrlsimError(f"{what} {path} is not valid XML ({e}): {fix}") from None
        if path == vtypes_file:
            ids = {el.get("id") for el in tree.iter("vType")}  # the types the ego and the traffic use
            lacking = [t for t in ("ego", BG_TYPE) if t not in ids]
            if lacking:
                raise IrlsimError(
                    f"vehicle types {path} lacks vType '{lacking[0]}', which irlsim inserts (it needs "
                    f"ego, {BG_TYPE}): add it or {RESTORE}"
                )
