"""Small shared helpers: atomic writes, an exclusive folder lock, seeding, JSON output, worker set-up."""

from __future__ import annotations

import json
import os
import random
import re
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from irlsim.errors import IrlsimError
from irlsim.outputs import check_output_file as check_output_file_


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _current_umask()


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path`` (atomic on POSIX).

    On any exception the temporary file is removed, so ``path`` is either the old file or the complete
    new one, never a half-written one. A killed process leaves at most a ``.*.tmp`` file that readers ignore.
    An OSError on the temporary file is re-raised naming ``path`` (what the user knows).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        if tmp.exists():  # mkstemp creates 0600; give the result the usual umask-based mode
            tmp.chmod(0o666 & ~_UMASK)
        os.replace(tmp, path)
    except OSError as e:  # an error on the temporary file (disk full, ...) names the file being written
        if str(e.filename) == str(tmp) or (e.filename is None and e.errno is not None):
            name_os_error(e, path)  # a write's ENOSPC has no file name
        raise
    finally:
        if tmp.exists():
            tmp.unlink()


@contextmanager
def naming(path: str | Path) -> Iterator[None]:
    """An OSError raised inside without a file name (``write`` or ``flush`` of an open file: a full disk,
    an I/O error) is given ``path``, the file being read or written, for its one line."""
    try:
        yield
    except OSError as e:
        if e.filename is None and e.errno is not None:  # an OS error, not one raised with a message only
            name_os_error(e, path)
        raise


def name_os_error(e: OSError, path: str | Path) -> None:
    """Give ``e`` the file ``path``; an error raised with a message only (pyarrow's: errno set, no
    strerror) keeps that message as its strerror, so that ``str(e)`` stays readable."""
    if e.strerror is None and e.args:
        e.strerror = re.sub(r"^\[Errno \d+\] ", "", str(e.args[0]))
    e.filename = str(path)


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def write_json(path: str | Path, obj: Any) -> None:
    """Write ``obj`` as indented JSON atomically (numpy scalars and arrays are converted)."""

    def default(o: Any) -> Any:
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, Path):
            return str(o)
        raise TypeError(f"not JSON serialisable: {type(o).__name__}")

    atomic_write_text(path, json.dumps(obj, indent=2, default=default, sort_keys=False) + "\n")


class LockBusy(Exception):
    """``exclusive_lock``: another process holds the lock; ``holder`` is its recorded pid ("?" if none)."""

    def __init__(self, path: Path, holder: str) -> None:
        super().__init__(f"{path} is locked by pid {holder}")
        self.path = path
        self.holder = holder


@contextmanager
def exclusive_lock(path: str | Path) -> Iterator[None]:
    """Hold an exclusive, non-blocking ``flock`` on ``path`` for the block, or raise ``LockBusy``.

    The file records the holder's pid for the error message of the next caller. It is written in place,
    not atomically, and never deleted: a lock needs one inode that every process opens (replacing or
    unlinking it would let two processes lock two different files). The kernel drops the lock when the
    process ends, however it ends, so a stale file never blocks. Without ``fcntl`` (not POSIX), no lock.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - irlsim runs on Linux; keep other platforms working
        yield
        return
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 32).decode(errors="replace").strip() or "?"
            raise LockBusy(path, holder) from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        try:
            yield
        finally:
            os.ftruncate(fd, 0)
    finally:
        os.close(fd)  # releases the lock


#: the lock file a command holds in the folder it writes (collect, train, evaluate, drive)
LOCK_NAME = ".lock"


@contextmanager
def owned_output(folder: str | Path, command: str) -> Iterator[None]:
    """Hold ``<folder>/.lock`` while ``irlsim <command>`` writes ``folder``: a second command writing the
    same folder is one line (IrlsimError) instead of two runs that both report success while one
    result is lost."""
    folder = Path(folder)
    try:
        with exclusive_lock(folder / LOCK_NAME):
            yield
    except LockBusy as busy:
        raise IrlsimError(
            f"another 'irlsim {command}' is writing {folder} (pid {busy.holder}): wait for it, or choose "
            "another --out"
        ) from None


def die_with_parent(parent_pid: int) -> None:
    """Worker-process set-up: ignore Ctrl-C (the parent reports it) and die when the parent dies.

    On Linux the kernel sends SIGKILL to this process when its parent exits (``PR_SET_PDEATHSIG``), so a
    SIGKILL of the parent leaves no orphan writing into a folder that a new run may then lock. Elsewhere
    only SIGINT is ignored. ``parent_pid`` closes the race of a parent that died before the call.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        import ctypes

        pr_set_pdeathsig = 1  # <linux/prctl.h>
        try:
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover - a libc without prctl
            return
        if os.getppid() != parent_pid:
            os._exit(1)


def seed_everything(seed: int) -> np.random.Generator:
    """Seed Python's and NumPy's global RNGs (and torch's, if imported); return a fresh Generator."""
    random.seed(seed)
    np.random.seed(seed % (2**32))  # noqa: NPY002 - seeds third-party code that uses the global state
    if "torch" in sys.modules:  # never imported here: torch costs ~1.5 s and most commands do not use it
        import torch

        torch.manual_seed(seed)
    return np.random.default_rng(seed)


def check_non_negative(name: str, value: int | float) -> None:
    if value < 0:
        raise IrlsimError(f"--{name} must be >= 0, got {value}")


def progress(iterable: Any = None, **kwargs: Any) -> Any:
    """A tqdm progress bar that stays quiet when stderr is not a terminal unless forced."""
    kwargs.setdefault("dynamic_ncols", True)
    kwargs.setdefault("mininterval", 1.0)
    return tqdm(iterable, **kwargs)


def timed(fn: Callable[[], Any], repeat: int) -> list[float]:
    """Run ``fn`` ``repeat`` times; return the wall times in seconds."""
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def check_output_file(path: Path, option: str, example: str) -> None:
    """A one-line IrlsimError now, before any work, when ``path`` cannot be written later: it is a
    directory, a folder on its way is a file, or the nearest existing folder takes no new file (tried
    with a temporary file that is removed at once). Missing folders are fine: the writer creates them.
    ``option`` names the command-line option in the message, ``example`` a file name to suggest."""
    check_output_file_(path, option, example)


@contextmanager
def time_limit(seconds: float, message: str) -> Iterator[None]:
    """Raise IrlsimError(``message``) when the block runs longer than ``seconds`` (SIGALRM, so only in
    the main thread; elsewhere the block is not limited). For a library call that can wait for ever
    (joining a Ray cluster that never answers)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum: int, frame: Any) -> None:
        raise TimeoutError

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    except TimeoutError:
        raise IrlsimError(message) from None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


#: an HTTP/2 client's first bytes (connection preface, an empty SETTINGS frame): Ray's GCS is a gRPC
#: server and answers with its own SETTINGS frame
_H2_HELLO = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])


def answers_http2(host: str, port: int, timeout: float) -> bool:
    """Whether ``host:port`` accepts a connection and answers an HTTP/2 greeting within ``timeout``
    seconds (OSError when it refuses), as a gRPC server such as Ray's GCS does: ``ray.init`` on a port
    that takes connections but never answers as Ray blocks in C++ where no signal interrupts it, so
    joining checks this first. With RAY_USE_TLS the greeting is not plain: only the connection is
    checked."""
    with socket.create_connection((host, port), timeout=timeout) as conn:
        if os.environ.get("RAY_USE_TLS", "0").lower() in ("1", "true"):
            return True
        conn.sendall(_H2_HELLO)
        try:
            head = conn.recv(9)
        except TimeoutError:
            return False
        return len(head) == 9 and head[3] == 4  # a SETTINGS frame


class _Missing:
    def __repr__(self) -> str:
        return "(not set)"


#: stands for a key one of two configs lacks
MISSING: Any = _Missing()


def first_difference(old: Any, new: Any, prefix: str = "") -> tuple[str, Any, Any] | None:
    """The first dotted key whose value differs between two nested dicts, with both values (a key
    missing on one side gives ``MISSING`` there), or None when they are equal."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in [*new, *(k for k in old if k not in new)]:
            diff = first_difference(old.get(key, MISSING), new.get(key, MISSING), f"{prefix}{key}.")
            if diff is not None:
                return diff
        return None
    return None if old == new else (prefix.rstrip("."), old, new)
