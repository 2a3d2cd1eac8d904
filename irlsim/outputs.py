"""Output checks every command makes before any work, and OS errors as one line.

``check_output_dir`` / ``check_output_file``: the place can be written (not a file, no file on the way, a
new file can be created there: tried and removed at once) and its disk has room for what the command
knows it will write. ``os_error_message`` turns an OSError met on the way (disk full included) into one
line naming the path; the CLI prints it (exit 1). Writers go through ``irlsim.utils.atomic_path``, which
removes its temporary file when the write fails, so a failed write leaves the old file or nothing.
"""

from __future__ import annotations

import errno
import shutil
import tempfile
from pathlib import Path

from irlsim.errors import IrlsimError

#: headroom [bytes] every output check asks for besides what the command estimates (logs, JSON, pictures)
MIN_FREE_BYTES = 1 << 20
_SPACE_FIX = "free disk space or choose another place"


def _nearest_existing(path: Path) -> Path:
    folder = path.absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return folder


def _probe(folder: Path) -> None:
    """Create and remove a temporary file in ``folder`` (the OS call that proves it takes new files)."""
    with tempfile.TemporaryFile(dir=folder):
        pass


def free_bytes(folder: Path) -> int:
    return int(shutil.disk_usage(folder).free)


def _check_place(
    path: Path, option: str, folder: Path, need_bytes: int, fix: str, space_fix: str = _SPACE_FIX
) -> None:
    try:
        _probe(folder)
    except OSError as e:
        raise IrlsimError(
            f"{option} {path} cannot be written ({e.strerror or type(e).__name__} in {folder}): {fix}"
        ) from None
    need = int(need_bytes) + MIN_FREE_BYTES
    have = free_bytes(folder)
    if have < need:
        raise IrlsimError(
            f"{option} {path}: {folder} has {human_size(have)} free, this needs about {human_size(need)}: "
            f"{space_fix}"
        )


def check_output_dir(
    path: str | Path,
    option: str,
    need_bytes: int = 0,
    fix: str = "choose a writable place",
    space_fix: str = _SPACE_FIX,
) -> None:
    """A one-line IrlsimError now, before any work, when folder ``path`` cannot take the outputs: it is a
    file, a folder on its way is a file, the folder (or its nearest existing parent, for a new one) takes
    no new file (``fix`` says what to do), or its disk has less than ``need_bytes`` (+1 MiB) free
    (``space_fix``). Missing folders are fine."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise IrlsimError(f"{option} {path} is a file, not a folder: choose a folder")
    folder = _nearest_existing(path)
    if not folder.is_dir():
        raise IrlsimError(f"{option} {path}: {folder} is a file, not a folder: choose another path")
    _check_place(path, option, folder, need_bytes, fix, space_fix)


def check_output_file(path: str | Path, option: str, example: str, need_bytes: int = 0) -> None:
    """Like :func:`check_output_dir` for a file ``path`` (a folder there is refused, naming ``example``)."""
    path = Path(path)
    if path.is_dir():
        raise IrlsimError(f"{option} {path} is a directory: pass a file name such as {path / example}")
    folder = _nearest_existing(path.absolute().parent)
    if not folder.is_dir():
        raise IrlsimError(f"{option} {path}: {folder} is a file, not a folder: choose another path")
    _check_place(path, option, folder, need_bytes, "choose a writable place")


def os_error_message(e: OSError) -> str:
    """One line for an OSError met while working: what failed, on which path, and what to do."""
    path = e.filename if e.filename is not None else "(a file the OS did not name)"
    if e.filename2 is not None:
        path = f"{path} -> {e.filename2}"
    what = e.strerror or type(e).__name__
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        fix = "free disk space and re-run the command (finished files are kept, it resumes)"
    elif e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        fix = "make it writable or choose another place"
    else:
        fix = "check the path and re-run the command"
    return f"{what}: {path}: {fix}"


def human_size(n: int) -> str:
    """``n`` bytes in binary units, e.g. '1.5 GiB'."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024  # type: ignore[assignment]
    return f"{n} B"  # pragma: no cover
