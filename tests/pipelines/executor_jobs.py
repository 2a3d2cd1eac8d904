"""The job functions of the executor's tests (tests/pipelines/test_executor.py): top level, so picklable,
and in a module of their own that imports nothing heavy, because every worker process (a local spawn
worker, a Ray worker) imports the module of the function it runs, and the test module pulls in pandas
and the CLI (about 1 s a worker on a busy 2-core machine)."""

from __future__ import annotations

import os
import signal
from pathlib import Path


def double(x: int) -> int:
    return 2 * x


def die_once(arg: tuple[str, int]) -> int:
    """SIGKILL its own process on the first attempt (a marker file remembers it), then succeed."""
    marker, x = arg
    if not os.path.exists(marker):
        Path(marker).write_text("died")
        os.kill(os.getpid(), signal.SIGKILL)
    return 2 * x


def stops_itself(arg: tuple[int, int]) -> int:
    """Job 7 stops its own process (SIGSTOP) on every attempt: alive and silent, as a worker deadlocked
    in libsumo. ``arg[0]`` is the test's pid, which is never stopped (a timeout runs no job in it)."""
    test_pid, x = arg
    if x == 7:
        if os.getpid() == test_pid:
            raise RuntimeError("a job with a timeout ran in the test's own process")
        os.kill(os.getpid(), signal.SIGSTOP)
    return 2 * x


def pid_and_double(x: int) -> tuple[int, int]:
    return os.getpid(), 2 * x


def always_fails(x: int) -> int:
    if x == 1:
        return 2
    raise RuntimeError(f"episode {x} cannot be driven\nsecond line of the message")
