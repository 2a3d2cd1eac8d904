"""The vehicle type of a SUMO demonstrator: SUMO's car-following and lane-change models, with any vType
attributes, at the ego's wheel (:class:`irlsim.sim.drivers.SumoDriver` with ``Simulation(demo_vtype=)``).

SUMO itself decides what is valid: :func:`check_vtype` loads the type with the scenario's network in the
``sumo`` binary of the eclipse-sumo wheel, with XML schema validation on, and turns SUMO's first error
into one line. Measured on SUMO 1.28: an unknown model (``carFollowModel="IDX"``) and an invalid value
(``tau="abc"``, ``tau="-1"``) are errors of SUMO's vType parser; an attribute SUMO does not know at all
(``foo="3"``) is an error only of the schema (without validation SUMO ignores it); an attribute of
another model (``delta`` on Krauss) is valid to both and ignored by SUMO.
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from pathlib import Path
from typing import Any
from xml.etree import ElementTree
from xml.sax.saxutils import quoteattr

from irlsim.errors import IrlsimError
from irlsim.road.network import VTYPES_PATH, sumo_binary, sumo_home
from irlsim.sim.sumo_ego import EGO_SPEED_FACTOR

#: the demonstrator's vehicle type id (``vehicle.setType`` when SUMO takes the ego over)
DEMO_TYPE = "irlsim_demo"
#: the type the ego is inserted with under a demonstrator: the demonstrator's, with the placed ego's speed
#: attributes (:func:`placed_attributes`). SUMO builds a vehicle's lane-change model once, at insertion,
#: from its type: ``vehicle.setType`` changes the car following but keeps the lane-change model and its
#: parameters (measured on SUMO 1.28: an ego inserted with irlsim's ego type kept LC2013 with
#: ``lcSpeedGain`` 1 after ``setType`` to a type with SL2015 or ``lcSpeedGain`` 7)
PLACED_TYPE = "irlsim_demo_placed"
#: the vType attributes of the two models (the config's ``car_follow_model`` / ``lane_change_model``)
MODEL_KEYS = ("carFollowModel", "laneChangeModel")
_SCHEMA = (
    'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" '
    'xsi:noNamespaceSchemaLocation="http://sumo.dlr.de/xsd/additional_file.xsd"'
)
#: [s] at most this long for SUMO to load the network and the type
CHECK_TIMEOUT_S = 120.0


def ego_type_attributes() -> dict[str, str]:
    """The attributes of irlsim's ego type (sumo_net/vtypes.add.xml) a demonstrator starts from: its
    size, acceleration, deceleration, no driver imperfection (``sigma`` 0); ``speedFactor`` 1 (the ego
    type's 2 serves only the placed ego), without ``id`` and ``color``."""
    root = ElementTree.parse(VTYPES_PATH).getroot()
    ego = next(v for v in root.iter("vType") if v.get("id") == "ego")
    out = {k: v for k, v in ego.attrib.items() if k not in ("id", "color")}
    out["speedFactor"] = "1"
    return out


def vtype_attributes(params: dict[str, Any], max_speed: float) -> dict[str, str]:
    """The demonstrator's vType attributes: the ego type's (:func:`ego_type_attributes`), ``maxSpeed``
    the scenario's target speed [m/s], then ``params`` (models included) over them."""
    out = {**ego_type_attributes(), "maxSpeed": f"{max_speed:g}"}
    out.update({str(k): _text(v) for k, v in params.items()})
    return out


def _text(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v).lower() if isinstance(v, bool) else str(v)


def placed_attributes(attrs: dict[str, str]) -> dict[str, str]:
    """The attributes of ``PLACED_TYPE``: the demonstrator's ``attrs`` (its lane-change model and every
    attribute), with the ego type's ``speedFactor`` 2 and no ``maxSpeed``, so that the ego placed by
    ``moveToXY`` before SUMO takes it over reports its real speed unclipped, as with the ego type."""
    out = {k: v for k, v in attrs.items() if k != "maxSpeed"}
    out["speedFactor"] = f"{EGO_SPEED_FACTOR:g}"
    return out


def vtype_xml(attrs: dict[str, str]) -> str:
    """An additional file holding the vType ``DEMO_TYPE`` with ``attrs`` and ``PLACED_TYPE`` with
    :func:`placed_attributes`."""
    lines = []
    for vid, a in ((DEMO_TYPE, attrs), (PLACED_TYPE, placed_attributes(attrs))):
        body = " ".join(f"{k}={quoteattr(v)}" for k, v in a.items())
        lines.append(f'    <vType id="{vid}" {body}/>')
    return f"<additional {_SCHEMA}>\n" + "\n".join(lines) + "\n</additional>\n"


def read_vtype_file(path: str | Path) -> dict[str, str]:
    """The attributes (without ``id``) of the one vType of the additional file ``path``; one line when
    the file is missing, not XML, or holds no vType or several."""
    p = Path(path)
    if not p.is_file():
        raise IrlsimError(f"demonstrator.vtype_file {p} not found: give the path of a file with one <vType>")
    try:
        types = list(ElementTree.parse(p).getroot().iter("vType"))
    except ElementTree.ParseError as e:
        raise IrlsimError(f"demonstrator.vtype_file {p} is not XML ({e}): fix or replace it") from None
    if len(types) != 1:
        raise IrlsimError(
            f"demonstrator.vtype_file {p} holds {len(types)} <vType> elements: give a file with exactly one"
        )
    return {k: v for k, v in types[0].attrib.items() if k != "id"}


def check_vtype(net_file: Path, attrs: dict[str, str], workdir: Path) -> None:
    """Ask SUMO whether the vType ``attrs`` is valid: load it with ``net_file`` (no step) in the sumo
    binary, first by SUMO's own parser (its errors name the model or attribute), then with schema
    validation (attributes SUMO does not know); SUMO's first error as one line naming the fix."""
    path = workdir / "demonstrator.add.xml"
    path.write_text(vtype_xml(attrs))
    cmd = [sumo_binary("sumo"), "-n", str(net_file), "-a", str(path), "--begin", "0", "--end", "0"]
    cmd += ["--no-step-log", "true", "--xml-validation.net", "never", "--xml-validation"]
    env = {**os.environ, "SUMO_HOME": sumo_home()}
    for validation in ("never", "always"):
        try:
            res = subprocess.run(
                [*cmd, validation], capture_output=True, text=True, timeout=CHECK_TIMEOUT_S, env=env
            )
        except subprocess.TimeoutExpired:
            raise IrlsimError(
                f"SUMO took over {CHECK_TIMEOUT_S:g} s to load the demonstrator's vType"
            ) from None
        errors = [ln for ln in (res.stderr + res.stdout).splitlines() if ln.startswith("Error:")]
        if res.returncode != 0 or errors:
            why = errors[0][len("Error:") :].strip() if errors else f"exit status {res.returncode}"
            raise IrlsimError(
                f"SUMO refuses the demonstrator's vehicle type ({why}): fix [demonstrator] (models: SUMO's "
                "carFollowModel / laneChangeModel names; params: vType attributes)"
            )


class DemoTypeFile:
    """The demonstrator's vType as a temporary additional file for SUMO's command line: written on first
    use, kept while SUMO may reload it (every reset), removed by :meth:`cleanup`."""

    def __init__(self, attrs: dict[str, str]):
        self.attrs = dict(attrs)
        self._dir: tempfile.TemporaryDirectory[str] | None = None

    def path(self) -> str:
        if self._dir is None:
            self._dir = tempfile.TemporaryDirectory(prefix="irlsim-demo-")
            (Path(self._dir.name) / "demonstrator.add.xml").write_text(vtype_xml(self.attrs))
        return str(Path(self._dir.name) / "demonstrator.add.xml")

    def cleanup(self) -> None:
        if self._dir is not None:
            self._dir.cleanup()
            self._dir = None
