"""Run a list of episode jobs in parallel processes: a local spawn pool or Ray tasks, one behaviour.

``run_jobs(fn, jobs, ...)`` calls the top-level (picklable) function ``fn(job.arg)`` for every job and
reports each result to ``on_result`` as it arrives, in completion order. Two executors:

- ``local``: ``workers`` spawned processes of our own (``workers == 1`` or a single job, without a
  ``timeout``: in this process). Each worker is
  one single-threaded process (``THREAD_VARS`` = 1) that ignores Ctrl-C and dies with its parent
  (:func:`irlsim.utils.die_with_parent`) and runs one job at a time, so one libsumo per process. The
  parent watches every worker's pipe *and* its process sentinel: a worker that dies (``kill -9``, the
  OOM killer, a segfault in SUMO) is noticed at once, its job is counted as a failed attempt and a fresh
  worker takes its place. (``multiprocessing.Pool`` never notices a dead worker: its job just never
  returns, and the run hangs; that is why this module does not use it.)
- ``ray``: every job is a Ray task (``num_cpus=1``, ``THREAD_VARS`` = 1 in its runtime environment) in a
  Ray worker process, which runs one task at a time: one libsumo per process here too. At most
  ``workers`` tasks are in flight. ``address`` None starts a local Ray of ``workers`` CPUs (stopped at the
  end); ``"auto"`` or ``"host:port"`` joins a running cluster. A Ray already initialised in this process
  (a test fixture, a notebook) is used as it is. Ray's own task retries are off: retries are ours.

Failures are handled the same way by both: a job that raises or whose worker dies is retried once
(``retries``); a job that fails again is reported in ``RunResult.failed`` with a one-line reason, and the
other jobs run to the end. Nothing here hangs on a dead process, and nothing is written here: the jobs
write their own outputs (atomically), so a run started with one executor resumes with the other.

``timeout`` (seconds, None: no limit) bounds each attempt's wall-clock time, so a worker that hangs
without dying (stopped, deadlocked in libsumo) does not hang the run: a local worker that has not
answered ``timeout`` seconds after its job was sent is terminated (SIGTERM, then SIGKILL after
``KILL_GRACE_S``) and replaced, and a Ray task not finished ``timeout`` seconds after its submission is
cancelled with ``ray.cancel(force=True)`` (which kills its worker process); either way the attempt fails
like a dead worker's (retried once, then in ``failed``). The job running in this process cannot be
stopped safely, so a ``timeout`` always runs the jobs in worker processes, even one job with
``workers == 1``. With Ray the clock starts at submission: a task that waits for a free CPU of a busy
cluster (``workers`` above its free CPUs) spends its limit waiting too.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import signal
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import wait
from typing import Any

from irlsim import THREAD_VARS
from irlsim.errors import IrlsimError
from irlsim.utils import answers_http2, die_with_parent, time_limit

EXECUTORS = ("local", "ray")
#: attempts after the first for a job that raises or whose worker dies
RETRIES = 1
#: seconds a timed-out local worker gets between SIGTERM and SIGKILL (a stopped process ignores SIGTERM)
KILL_GRACE_S = 2.0
#: seconds to wait for a cancelled Ray task's worker to be gone before its job is tried again
RAY_CANCEL_WAIT_S = 30.0
#: the longest single wait of the scheduling loops (a longer timeout is waited for in several)
_MAX_WAIT_S = 3600.0
RAY_EXTRA = "pip install -e '.[ray]'"


@dataclass(frozen=True)
class Job:
    """One unit of work: ``key`` names it in messages (e.g. ``train/3``), ``arg`` is passed to the
    function (picklable)."""

    key: str
    arg: Any


@dataclass
class RunResult:
    results: dict[str, Any] = field(default_factory=dict)  # key -> the function's return value
    failed: dict[str, str] = field(default_factory=dict)  # key -> one-line reason of the last attempt
    retried: dict[str, str] = field(default_factory=dict)  # key -> one-line reason of the failed attempt


def one_line(exc: BaseException) -> str:
    """An exception as one line: its type and the first line of its message."""
    msg = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {msg[0]}" if msg else type(exc).__name__


def check_executor(executor: str, workers: int, address: str | None = None) -> None:
    """One-line IrlsimErrors for a bad ``--executor`` / ``--workers`` / ``--address``, before any work."""
    if executor not in EXECUTORS:
        raise IrlsimError(f"--executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    if workers < 1:
        raise IrlsimError(f"--workers must be >= 1, got {workers}")
    if address is not None and executor != "ray":
        raise IrlsimError("--address joins a Ray cluster: use it with --executor ray")
    if executor == "ray":
        _import_ray()
        if address is not None:
            join_ray(address)


#: seconds joining a Ray cluster (--address) may take: reaching its port, then Ray's own handshake
RAY_JOIN_TIMEOUT_S = 30.0
_RAY_INIT: dict[str, Any] = {
    "include_dashboard": False,
    "log_to_driver": False,
    "logging_level": logging.WARNING,
}
_joined: list[str] = []  # the address check_executor joined: the next run_jobs uses it, then leaves it


def join_ray(address: str, timeout: float | None = None) -> None:
    """Join the Ray cluster at ``address`` ('auto' or host:port) within ``timeout`` seconds (default
    ``RAY_JOIN_TIMEOUT_S``), or one IrlsimError line: a malformed or empty address, no cluster found for
    'auto', a port nobody listens on, a listener that does not answer as Ray (``ray.init`` alone waits
    for ever). Done by :func:`check_executor`, before a command writes anything."""
    ray, limit = _import_ray(), RAY_JOIN_TIMEOUT_S if timeout is None else timeout
    if ray.is_initialized():
        return
    fix = "check --address, or start the cluster ('ray start --head') and pass the address it prints"
    try:
        from ray._private.services import get_ray_address_from_environment  # lazy: Ray is optional

        resolved = get_ray_address_from_environment(address, None)
    except (ImportError, ConnectionError):
        resolved = None if address == "auto" else address
    host, _, port = str(resolved or "").removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        found = "no running Ray cluster found" if resolved is None else f"{resolved!r} is not host:port"
        raise IrlsimError(f"--address {address!r}: {found}: {fix}")
    try:
        answered = answers_http2(host.strip("[]"), int(port), limit)
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        raise IrlsimError(f"cannot reach the Ray cluster at {resolved} ({why}): {fix}") from None
    if not answered:
        raise IrlsimError(f"{resolved} did not answer as a Ray cluster within {limit:g} s: {fix}")
    with time_limit(limit, f"the Ray cluster at {resolved} did not answer as Ray within {limit:g} s: {fix}"):
        try:
            ray.init(address=resolved, **_RAY_INIT)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise IrlsimError(f"cannot join the Ray cluster at {resolved} ({one_line(exc)}): {fix}") from None
    _joined.append(str(resolved))


def _import_ray() -> Any:
    try:
        import ray  # lazy: the optional extra 'ray', and slow to import; only --executor ray needs it
    except ImportError:
        raise IrlsimError(
            f"--executor ray needs Ray, which is not installed: {RAY_EXTRA} (or use --executor local)"
        ) from None
    return ray


def run_jobs(
    fn: Callable[[Any], Any],
    jobs: Sequence[Job],
    *,
    executor: str = "local",
    workers: int = 1,
    address: str | None = None,
    retries: int = RETRIES,
    on_result: Callable[[Job, Any], None] | None = None,
    on_retry: Callable[[Job, str], None] | None = None,
    timeout: float | None = None,
) -> RunResult:
    """Run ``fn(job.arg)`` for every job (see the module docstring); never raises for a failed job.
    ``timeout``: seconds an attempt may take (None: no limit; then ``workers == 1`` runs in this process)."""
    check_executor(executor, workers, address)
    if len({j.key for j in jobs}) != len(jobs):
        raise ValueError("job keys must be unique")
    if timeout is not None and not timeout > 0:  # also refuses nan
        raise ValueError(f"timeout must be > 0 seconds, got {timeout}")
    state = _State(list(jobs), retries, on_result, on_retry)
    if not jobs:
        return state.result
    if executor == "ray":
        _run_ray(fn, state, workers, address, timeout)
    elif timeout is None and (workers == 1 or len(jobs) == 1):
        _run_inline(fn, state)
    else:
        _run_local(fn, state, min(workers, len(jobs)), timeout)
    return state.result


#: how the reason of an attempt that ran out of time begins
TIMED_OUT = "no result within "


def timed_out(timeout: float, what: str) -> str:
    """The one-line reason of an attempt that ran out of time (``what``: what was done about it)."""
    return f"{TIMED_OUT}{timeout:g} s: {what}"


def _wait_s(deadlines: list[float]) -> float | None:
    """Seconds until the earliest deadline (never negative, at most ``_MAX_WAIT_S``); None: no deadline."""
    if not deadlines:
        return None
    return min(max(0.0, min(deadlines) - time.monotonic()), _MAX_WAIT_S)


class _State:
    """The queue of jobs with their attempt counts, and what came back."""

    def __init__(self, jobs: list[Job], retries: int, on_result: Any, on_retry: Any) -> None:
        self.queue = list(reversed(jobs))  # pop() takes the first job first
        self.attempts: dict[str, int] = {}
        self.retries = retries
        self.on_result = on_result
        self.on_retry = on_retry
        self.result = RunResult()

    def next(self) -> Job | None:
        if not self.queue:
            return None
        job = self.queue.pop()
        self.attempts[job.key] = self.attempts.get(job.key, 0) + 1
        return job

    def ok(self, job: Job, value: Any) -> None:
        self.result.results[job.key] = value
        if self.on_result is not None:
            self.on_result(job, value)

    def fail(self, job: Job, reason: str) -> None:
        if self.attempts[job.key] <= self.retries:
            self.result.retried[job.key] = reason
            if self.on_retry is not None:
                self.on_retry(job, reason)
            self.queue.append(job)  # next in line
        else:
            self.result.failed[job.key] = reason


# ------------------------------------------------------------------------------------------ in process


def _run_inline(fn: Callable[[Any], Any], state: _State) -> None:
    while (job := state.next()) is not None:
        try:
            value = fn(job.arg)
        except Exception as exc:  # KeyboardInterrupt and SystemExit end the run
            state.fail(job, one_line(exc))
        else:
            state.ok(job, value)


# ------------------------------------------------------------------------------------- local processes


def _worker_main(conn: Any, parent_pid: int) -> None:  # top level: the spawn target
    die_with_parent(parent_pid)
    while True:
        try:
            msg = conn.recv()
        except EOFError:  # the parent is gone
            return
        if msg is None:
            return
        fn, arg = msg
        try:
            reply: tuple[Any, ...] = ("ok", fn(arg))
        except Exception as exc:
            reply = ("error", one_line(exc), traceback.format_exc())
        try:
            conn.send(reply)
        except Exception as exc:  # an unpicklable result: report it instead of dying
            conn.send(("error", f"result not picklable: {one_line(exc)}", ""))


class _Worker:
    def __init__(self, ctx: Any) -> None:
        parent, child = ctx.Pipe()
        self.conn = parent
        self.process = ctx.Process(target=_worker_main, args=(child, os.getpid()), daemon=True)
        self.process.start()
        child.close()
        self.job: Job | None = None
        self.deadline: float | None = None  # time.monotonic() by which the job's answer is due

    def terminate(self) -> None:
        """End a worker that does not answer: SIGTERM, then SIGKILL after ``KILL_GRACE_S`` (a stopped
        process keeps SIGTERM pending; SIGKILL ends it too). Returns once the process is gone."""
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(timeout=KILL_GRACE_S)
        self.stop(kill=True)

    def stop(self, kill: bool) -> None:
        if kill and self.process.is_alive():
            self.process.kill()
        else:
            try:
                self.conn.send(None)
            except OSError:
                pass
        self.process.join(timeout=None if kill else 10)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()


def _death_reason(process: Any) -> str:
    code = process.exitcode
    if code is not None and code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"worker process {process.pid} died ({name})"
    return f"worker process {process.pid} exited with status {code}"


def _start_workers(ctx: Any, n: int) -> list[_Worker]:
    """``n`` workers with single-threaded BLAS/OpenMP (read by the children at start-up; this process's
    values are restored), started while this process ignores SIGINT: the children inherit that until
    their own set-up, so a Ctrl-C during their start-up prints no traceback from them."""
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: signals are not ours to change
        previous = None
    saved = {var: os.environ.get(var) for var in THREAD_VARS}
    os.environ.update({var: "1" for var in THREAD_VARS})
    try:
        return [_Worker(ctx) for _ in range(n)]
    finally:
        for var, value in saved.items():
            if value is None:
                os.environ.pop(var, None)
            else:
                os.environ[var] = value
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _run_local(fn: Callable[[Any], Any], state: _State, n: int, timeout: float | None = None) -> None:
    ctx = mp.get_context("spawn")
    pool = _start_workers(ctx, n)
    clean = False
    try:
        for w in pool:
            _assign(w, fn, state, timeout)
        while any(w.job is not None for w in pool):
            busy = [w for w in pool if w.job is not None]
            ready = wait(
                [w.conn for w in busy] + [w.process.sentinel for w in busy],
                timeout=_wait_s([w.deadline for w in busy if w.deadline is not None]),
            )
            for i, w in enumerate(pool):
                if w.job is None:
                    continue
                job = w.job
                if w.conn in ready or w.conn.poll():
                    try:
                        reply = w.conn.recv()
                    except (EOFError, OSError):
                        reply = None  # it died while sending
                    if reply is not None:
                        w.job = None
                        if reply[0] == "ok":
                            state.ok(job, reply[1])
                        else:
                            state.fail(job, reply[1])
                        _assign(w, fn, state, timeout)
                        continue
                if w.process.sentinel in ready or not w.process.is_alive():
                    w.process.join()
                    reason = _death_reason(w.process)
                    w.stop(kill=True)
                elif w.deadline is not None and time.monotonic() >= w.deadline:
                    # alive but silent past its limit (stopped, deadlocked): a dead worker from here on
                    assert timeout is not None
                    w.terminate()
                    reason = timed_out(timeout, f"worker process {w.process.pid} killed")
                else:
                    continue
                w.job = None
                state.fail(job, reason)
                pool[i] = _start_workers(ctx, 1)[0]
                _assign(pool[i], fn, state, timeout)
        clean = True
    finally:
        for w in pool:
            w.stop(kill=not clean)


def _assign(w: _Worker, fn: Callable[[Any], Any], state: _State, timeout: float | None) -> None:
    job = state.next()
    if job is None:
        return
    w.job = job
    w.deadline = None if timeout is None else time.monotonic() + timeout
    # into the socket's buffer (~176 KiB on Linux; a drive job with the expert's progress curve of a
    # 900 s episode is ~150 KB): only a larger job sent to a worker hung before it reads would block here
    try:
        w.conn.send((fn, job.arg))
    except (OSError, EOFError):  # dead already: the sentinel reports it in the loop
        pass


# ----------------------------------------------------------------------------------------------- Ray


def _ray_call(fn: Callable[[Any], Any], arg: Any) -> Any:  # top level: the task function
    return fn(arg)


def _run_ray(
    fn: Callable[[Any], Any], state: _State, workers: int, address: str | None, timeout: float | None = None
) -> None:
    ray = _import_ray()
    started = bool(_joined) and ray.is_initialized()  # joined by check_executor: left at the end
    _joined.clear()
    if not ray.is_initialized():  # a new local Ray, even where another one runs on this machine (an
        # --address was joined by check_executor, within its time limit)
        try:
            ray.init(address="local", num_cpus=workers, **_RAY_INIT)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise IrlsimError(f"cannot start a local Ray ({one_line(exc)}): use --executor local") from None
        started = True
    task = ray.remote(
        num_cpus=1,
        max_retries=0,  # retries are ours, counted the same way as with the local pool
        retry_exceptions=False,
        runtime_env={"env_vars": {var: "1" for var in THREAD_VARS}},
    )(_ray_call)
    fn_ref = ray.put(fn)
    in_flight: dict[Any, Job] = {}
    deadlines: dict[Any, float] = {}  # ref -> time.monotonic() by which it is due (with a timeout)
    try:
        while True:
            while len(in_flight) < workers and (job := state.next()) is not None:
                ref = task.remote(fn_ref, job.arg)
                in_flight[ref] = job
                if timeout is not None:
                    deadlines[ref] = time.monotonic() + timeout
            if not in_flight:
                break
            done, _ = ray.wait(list(in_flight), num_returns=1, timeout=_wait_s(list(deadlines.values())))
            for ref in done:
                job = in_flight.pop(ref)
                deadlines.pop(ref, None)
                try:
                    value = ray.get(ref)
                except ray.exceptions.RayTaskError as exc:  # the job raised
                    cause = exc.cause if isinstance(exc.cause, BaseException) else exc
                    state.fail(job, one_line(cause))
                except ray.exceptions.RayError as exc:  # its worker or node died
                    state.fail(job, _ray_reason(exc))
                else:
                    state.ok(job, value)
            late = [ref for ref, due in deadlines.items() if time.monotonic() >= due]
            if late:  # one that finished anyway (its result on any node) is taken by the next ray.wait
                _, late = ray.wait(late, num_returns=len(late), timeout=0, fetch_local=False)
            for ref in late:  # still running past its limit (stopped, deadlocked): cancelled, then retried
                job = in_flight.pop(ref)
                del deadlines[ref]
                _cancel(ray, ref)
                assert timeout is not None
                state.fail(job, timed_out(timeout, "Ray task cancelled, its worker process killed"))
    finally:
        for ref in in_flight:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def _cancel(ray: Any, ref: Any) -> None:
    """Cancel a running task and kill its worker process; wait (at most ``RAY_CANCEL_WAIT_S``) until it
    is gone, so that its retry does not run beside it (Ray kills a stopped worker after a few seconds)."""
    try:
        ray.cancel(ref, force=True)
    except Exception as exc:  # finished in the meantime, or its node is gone: nothing left to stop
        logging.getLogger(__name__).debug("ray.cancel: %s", one_line(exc))
    ray.wait([ref], num_returns=1, timeout=RAY_CANCEL_WAIT_S)


def _ray_reason(exc: BaseException) -> str:
    name = type(exc).__name__
    if "WorkerCrashed" in name or "ActorDied" in name:
        return "Ray worker process died"
    if "NodeDied" in name or "ObjectLost" in name:
        return "Ray node died"
    return one_line(exc)


def describe_failures(failed: dict[str, str], limit: int = 5) -> str:
    """``train/3 (worker process 123 died (SIGKILL)), validation/0 and test/0 (...)``: the jobs with one
    reason named together, in the order they failed, at most ``limit`` jobs named."""
    groups: dict[str, list[str]] = {}
    for key, reason in list(failed.items())[:limit]:
        groups.setdefault(reason, []).append(key)
    named = [(", ".join(keys[:-1]) + " and " if len(keys) > 1 else "") + keys[-1] for keys in groups.values()]
    more = f" and {len(failed) - limit} more" if len(failed) > limit else ""
    return ", ".join(f"{k} ({r})" for k, r in zip(named, groups, strict=True)) + more
