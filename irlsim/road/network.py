"""Building and locating SUMO networks: the shipped scenarios' folder and the one network builder.

Every network irlsim makes from sources (a scenario's netconvert, netgenerate, OpenStreetMap or
OpenDRIVE source, a generated sweep network) is made by :func:`build_net`: a SUMO tool writes the
``.net.xml`` under a temporary name, its time-stamped header is removed (the same sources give the same
bytes) and it is renamed into place; it is made again only when :func:`is_stale` (missing, or older than
a file it is made from).

SUMO is located only when needed (never at import): binaries come from the ``eclipse-sumo`` wheel
(``site-packages/sumo/bin``), found through ``sumolib.checkBinary`` with SUMO_HOME pointing at that wheel.
"""

from __future__ import annotations

import os
import re
import subprocess
from collections.abc import Iterable, Sequence
from pathlib import Path

import sumo_net
from irlsim.errors import IrlsimError
from irlsim.utils import atomic_path

#: the shipped scenarios, one folder each (the ``sumo_net`` package, installed beside irlsim)
SUMO_NET_DIR = Path(sumo_net.__file__).resolve().parent
#: irlsim's vehicle types (ego, background), shared by every scenario
VTYPES_FILE = "vtypes.add.xml"
VTYPES_PATH = SUMO_NET_DIR / VTYPES_FILE

_HEADER = re.compile(rb"<!-- generated on .*?-->\s*", re.DOTALL)


#: a file named ``sumo_tools/<path>`` (a scenario's route or additional file, a recording's vehicle types)
#: lies inside the installed eclipse-sumo wheel's tools folder
SUMO_TOOLS = "sumo_tools/"


def sumo_tools_path(name: str, base: Path | None = None) -> Path:
    """The path of a file a config names: ``sumo_tools/<path>`` inside the eclipse-sumo wheel's tools
    folder, anything else as it is (joined to ``base`` where given)."""
    if name.startswith(SUMO_TOOLS):
        return Path(sumo_home()) / "tools" / name.removeprefix(SUMO_TOOLS)
    return base / name if base is not None else Path(name)


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


def config_sources(config: Path) -> tuple[Path, ...]:
    """The files a SUMO configuration (netconvert's, netgenerate's) is built from: itself and every
    existing file its values name (relative to it, several separated by commas)."""
    text = config.read_text(errors="replace") if config.is_file() else ""
    named = (n for v in re.findall(r'value="([^"]+)"', text) for n in re.split(r"[,\s]+", v) if n)
    return (config, *(config.parent / n for n in named if (config.parent / n).is_file()))


def is_stale(target: Path, sources: Iterable[Path]) -> bool:
    """The one staleness rule of a network irlsim makes: it is missing, or older than a file it is made
    from (none for a network drawn from a seed: made once)."""
    if not target.is_file():
        return True
    t = target.stat().st_mtime
    return any(s.stat().st_mtime > t for s in sources)


def build_net(
    tool: str,
    args: Sequence[str],
    target: Path,
    *,
    subject: str,
    fix: str,
    sources: Sequence[Path] = (),
    cwd: Path | None = None,
    force: bool = False,
) -> Path:
    """The one network builder: SUMO's ``tool`` (``netconvert``, ``netgenerate``) run with ``args`` in
    ``cwd`` writes ``target``, unless it is up to date with ``sources`` (:func:`is_stale`) and not
    ``force``. The output is written under a temporary name without netconvert's header comment (a time
    stamp and the output path), then renamed: byte-identical across builds, never half-written. A tool
    that fails is one line: ``<tool> failed on <subject>: <its error line>; <fix>``."""
    if not force and not is_stale(target, sources):
        return target
    with atomic_path(target) as tmp:
        proc = subprocess.run(
            [sumo_binary(tool), *args, "-o", str(tmp)],
            cwd=cwd,
            capture_output=True,
            text=True,
            env={**os.environ, "SUMO_HOME": sumo_home()},
        )
        if proc.returncode != 0:
            raise IrlsimError(f"{tool} failed on {subject}: {tool_error(proc)}; {fix}")
        tmp.write_bytes(strip_header(tmp.read_bytes()))
    return target


def strip_header(data: bytes) -> bytes:
    """A netconvert output without its header comment (a timestamp and the output path)."""
    return _HEADER.sub(b"", data, count=1)


def tool_error(proc: subprocess.CompletedProcess[str]) -> str:
    """The line that says what went wrong: the tool's first 'Error:' line (netconvert's last line is
    only 'Quitting (on error).'), else its last line."""
    lines = [ln.strip() for ln in (proc.stderr + "\n" + proc.stdout).splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("Error:")]
    return errors[0] if errors else (lines[-1] if lines else f"exit status {proc.returncode}, no output")
