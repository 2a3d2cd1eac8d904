"""Building and locating the SUMO network of the oval course.

SUMO is located only when needed (never at import): binaries come from the ``eclipse-sumo`` wheel
(``site-packages/sumo/bin``), found through ``sumolib.checkBinary`` with SUMO_HOME pointing at that wheel.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

from irlsim.errors import IrlsimError
from irlsim.utils import atomic_path

#: the folder with the plain-XML sources of the course
SUMO_NET_DIR = Path(__file__).resolve().parents[2] / "sumo_net"
NET_SOURCES = ("oval.nod.xml", "oval.edg.xml", "netconvert.cfg")
NET_FILE = "oval.net.xml"
VTYPES_FILE = "vtypes.add.xml"

_HEADER = re.compile(rb"<!-- generated on .*?-->\s*", re.DOTALL)


def sumo_home() -> str:
    """SUMO_HOME of the eclipse-sumo wheel; raises a one-line error when it is not installed."""
    try:
        import sumo  # the eclipse-sumo wheel
    except ImportError:
        raise IrlsimError(
            "SUMO binaries not found: the 'eclipse-sumo' package is missing; run 'make setup' "
            "(or pip install 'eclipse-sumo==1.28.*')"
        ) from None
    home = str(sumo.SUMO_HOME)
    # A stale SUMO_HOME of another version would win in checkBinary: point it at the wheel.
    os.environ["SUMO_HOME"] = home
    return home


def sumo_binary(name: str) -> str:
    """Absolute path of a SUMO binary (``netconvert``, ``sumo``, ``sumo-gui``) from the eclipse-sumo wheel."""
    home = sumo_home()
    path = Path(home) / "bin" / name
    if not path.is_file():
        raise IrlsimError(
            f"SUMO binary '{name}' not found in {home}/bin: reinstall eclipse-sumo ('make setup')"
        )
    return str(path)


def net_path(net_dir: str | Path | None = None) -> Path:
    return Path(net_dir or SUMO_NET_DIR) / NET_FILE


def net_is_stale(net_dir: str | Path | None = None) -> bool:
    """True when the .net.xml is missing or older than any of its sources."""
    d = Path(net_dir or SUMO_NET_DIR)
    target = d / NET_FILE
    if not target.is_file():
        return True
    t = target.stat().st_mtime
    return any((d / s).stat().st_mtime > t for s in NET_SOURCES)


def build_net(net_dir: str | Path | None = None, force: bool = False) -> Path:
    """Build ``oval.net.xml`` from the plain-XML sources with netconvert, if stale (or ``force``).

    The output is byte-identical across runs: netconvert's header comment (with a timestamp and the
    absolute output path) is removed. The file is written under a temporary name, then renamed.
    """
    d = Path(net_dir or SUMO_NET_DIR)
    for s in NET_SOURCES:
        if not (d / s).is_file():
            raise IrlsimError(f"network source {d / s} is missing: restore it from git ('git checkout {s}')")
    target = d / NET_FILE
    if not force and not net_is_stale(d):
        return target
    netconvert = sumo_binary("netconvert")
    with atomic_path(target) as tmp:
        proc = subprocess.run(
            [netconvert, "-c", str(d / "netconvert.cfg"), "-o", str(tmp)],
            cwd=d,
            capture_output=True,
            text=True,
            env={**os.environ, "SUMO_HOME": sumo_home()},
        )
        if proc.returncode != 0:
            raise IrlsimError(f"netconvert failed on {d}: {_netconvert_error(proc)}; fix the XML sources")
        data = _HEADER.sub(b"", tmp.read_bytes(), count=1)
        tmp.write_bytes(data)
    return target


def _netconvert_error(proc: subprocess.CompletedProcess[str]) -> str:
    """The line that says what went wrong: netconvert's first 'Error:' line (its last line is only
    'Quitting (on error).'), else its last line."""
    lines = [ln.strip() for ln in (proc.stderr + "\n" + proc.stdout).splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("Error:")]
    return errors[0] if errors else (lines[-1] if lines else f"exit status {proc.returncode}, no output")
