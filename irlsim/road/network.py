"""Building and locating SUMO networks: the shipped scenarios' folders, netconvert builds.

SUMO is located only when needed (never at import): binaries come from the ``eclipse-sumo`` wheel
(``site-packages/sumo/bin``), found through ``sumolib.checkBinary`` with SUMO_HOME pointing at that wheel.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import sumo_net
from irlsim.errors import IrlsimError
from irlsim.utils import atomic_path

#: the shipped scenarios, one folder each (the ``sumo_net`` package, installed beside irlsim)
SUMO_NET_DIR = Path(sumo_net.__file__).resolve().parent
#: the oval's plain-XML sources, in its scenario folder
OVAL_DIR = SUMO_NET_DIR / "oval"
NET_SOURCES = ("oval.nod.xml", "oval.edg.xml", "netconvert.cfg")
NET_FILE = "oval.net.xml"
#: irlsim's vehicle types (ego, background), shared by every scenario
VTYPES_FILE = "vtypes.add.xml"
VTYPES_PATH = SUMO_NET_DIR / VTYPES_FILE

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
    return Path(net_dir or OVAL_DIR) / NET_FILE


def _sources(d: Path, config: str) -> tuple[str, ...]:
    """The files a netconvert build in ``d`` reads: the oval's, or a configuration and its inputs."""
    if config == "netconvert.cfg" and all((d / s).is_file() for s in NET_SOURCES):
        return NET_SOURCES
    names = [config]
    text = (d / config).read_text() if (d / config).is_file() else ""
    names += [v for v in re.findall(r'value="([^"]+\.xml)"', text) if (d / v).is_file()]
    return tuple(names)


def net_is_stale(net_dir: str | Path | None = None, config: str = "netconvert.cfg") -> bool:
    """True when the .net.xml is missing or older than any of its sources."""
    d = Path(net_dir or OVAL_DIR)
    target = d / _target_name(d, config)
    if not target.is_file():
        return True
    t = target.stat().st_mtime
    return any((d / s).stat().st_mtime > t for s in _sources(d, config))


def _target_name(d: Path, config: str) -> str:
    return NET_FILE if (d / "oval.nod.xml").is_file() else f"{d.name}.net.xml"


def build_net(net_dir: str | Path | None = None, force: bool = False, config: str = "netconvert.cfg") -> Path:
    """Build the network of ``net_dir`` (default: the oval's folder) from its netconvert configuration,
    if stale (or ``force``): ``oval.net.xml`` for the oval, ``<folder name>.net.xml`` for others.

    The output is byte-identical across runs: netconvert's header comment (with a timestamp and the
    absolute output path) is removed. The file is written under a temporary name, then renamed.
    """
    d = Path(net_dir or OVAL_DIR)
    needed = NET_SOURCES if (d / "oval.nod.xml").is_file() or net_dir is None else (config,)
    for s in needed:
        if not (d / s).is_file():
            raise IrlsimError(f"network source {d / s} is missing: restore it from git ('git checkout {s}')")
    target = d / _target_name(d, config)
    if not force and not net_is_stale(d, config):
        return target
    netconvert = sumo_binary("netconvert")
    with atomic_path(target) as tmp:
        proc = subprocess.run(
            [netconvert, "-c", str(d / config), "-o", str(tmp)],
            cwd=d,
            capture_output=True,
            text=True,
            env={**os.environ, "SUMO_HOME": sumo_home()},
        )
        if proc.returncode != 0:
            raise IrlsimError(f"netconvert failed on {d}: {_netconvert_error(proc)}; fix the XML sources")
        tmp.write_bytes(strip_header(tmp.read_bytes()))
    return target


def strip_header(data: bytes) -> bytes:
    """A netconvert output without its header comment (a timestamp and the output path)."""
    return _HEADER.sub(b"", data, count=1)


def _netconvert_error(proc: subprocess.CompletedProcess[str]) -> str:
    """The line that says what went wrong: netconvert's first 'Error:' line (its last line is only
    'Quitting (on error).'), else its last line."""
    lines = [ln.strip() for ln in (proc.stderr + "\n" + proc.stdout).splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("Error:")]
    return errors[0] if errors else (lines[-1] if lines else f"exit status {proc.returncode}, no output")
