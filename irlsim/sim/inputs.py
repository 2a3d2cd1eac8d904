"""The files SUMO reads besides the network, checked before SUMO starts: each broken one is named as the
file at fault in one line, never blamed on the network or retried as a failed episode. And SUMO's own
reason when it stops an episode (:class:`SumoErrorLog`), which libsumo reduces to 'Process Error'."""

from __future__ import annotations

import functools
import os
import sys
import tempfile
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar
from xml.etree import ElementTree

from irlsim.errors import IrlsimError
from irlsim.road.network import sumo_binary
from irlsim.road.scenario import network_advice
from irlsim.sim.traffic import BG_TYPE

if TYPE_CHECKING:
    from irlsim.road.geometry import Road

#: how to get the shipped vehicle types back
RESTORE = "restore it ('git checkout sumo_net/vtypes.add.xml' or reinstall irlsim)"


def check_inputs(
    vtypes_file: Path | str, demand: tuple[Path, ...], additional: tuple[Path, ...] = ()
) -> None:
    """The vehicle types, a scenario's demand and its additional files are well-formed XML, and the
    vehicle types define the types irlsim inserts (``ego`` and the background's): else one IrlsimError
    line naming the file."""
    for path in (vtypes_file, *demand, *additional):
        try:
            tree = ElementTree.parse(path)
        except (ElementTree.ParseError, OSError) as e:
            what, fix = ("route file", "fix it or the scenario's [traffic] routes")
            if path == vtypes_file:
                what, fix = "vehicle types", RESTORE
            elif path in additional:
                what, fix = "additional file", "fix it or the scenario's [network] additional"
            raise IrlsimError(f"{what} {path} is not valid XML ({e}): {fix}") from None
        if path == vtypes_file:
            ids = {el.get("id") for el in tree.iter("vType")}  # the types the ego and the traffic use
            lacking = [t for t in ("ego", BG_TYPE) if t not in ids]
            if lacking:
                raise IrlsimError(
                    f"vehicle types {path} lacks vType '{lacking[0]}', which irlsim inserts (it needs "
                    f"ego, {BG_TYPE}): add it or {RESTORE}"
                )


def start_quietly(api: Any, cmd: list[str], quiet: bool = True, load: bool = False) -> str | None:
    """``api.start(cmd)`` (``load``: ``api.load(cmd[1:])``) with what SUMO writes to stderr caught
    (``quiet``): None when it started, else SUMO's message in one line (its exception's text, or the
    first 'Error:' line it wrote when the exception says only 'Process Error')."""
    run = (lambda: api.load(cmd[1:])) if load else (lambda: api.start(cmd))
    if not quiet:
        try:
            run()
        except Exception as e:  # libsumo / traci raise their own exception types
            return _message(e, "")
        return None
    with tempfile.TemporaryFile() as log:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(log.fileno(), 2)
        try:
            run()
            error = None
        except Exception as e:
            error = e
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        log.seek(0)
        return None if error is None else _message(error, log.read().decode(errors="replace"))


def _message(error: Exception, stderr: str) -> str:
    text = str(error).strip()
    if text in ("", "Process Error"):
        lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
        errors = sumo_errors(stderr)
        text = (errors[0] if errors else lines[0] if lines else "") or text or type(error).__name__
    return " ".join(text.split())


def sumo_errors(text: str) -> list[str]:
    """SUMO's 'Error:' lines in ``text`` (what it writes to stderr or its error log), without the prefix."""
    return [
        ln.strip().removeprefix("Error:").strip()
        for ln in text.splitlines()
        if ln.strip().startswith("Error:")
    ]


def additional_files(road: Road, *files: Path | str) -> str:
    """SUMO's ``--additional-files`` for ``road``: the scenario's own (its signal programs) first, then
    ``files`` (the vehicle types, a demonstrator's type)."""
    return ",".join(str(p) for p in (*road.additional, *files))


def refusal(api: Any, road: Road, vtypes_file: Path, why: str) -> IrlsimError:
    """The file SUMO refused, after it failed to start with ``why``: SUMO started again on the network
    alone, then with each of its additional files, then with the vehicle types, then with each route file
    in turn (every route read at once,
    ``--route-steps 0``); the first that fails is named with SUMO's message and the fix that fits it."""
    net, extra_files = str(road.net_file), [str(p) for p in road.additional]
    vtypes = ["--additional-files", additional_files(road, vtypes_file)]
    base = [sumo_binary("sumo"), "--net-file", net, *QUIET, "--route-steps", "0", "--begin", "0"]
    stages: list[tuple[str, list[str], str]] = [
        (f"network {net}", [], network_advice(road.net_file, road.scenario_file))
    ]
    for i, path in enumerate(extra_files):  # the network's additional files (its signal programs)
        fix = f"fix it or the [network] additional of {road.scenario_file}"
        stages.append(
            (f"additional file {path}", ["--additional-files", ",".join(extra_files[: i + 1])], fix)
        )
    stages.append((f"vehicle types {vtypes_file}", vtypes, f"fix it or {RESTORE}"))
    for i, route_file in enumerate(road.demand):
        files = ",".join(str(p) for p in road.demand[: i + 1])
        fix = f"fix it or the [traffic] routes of {road.scenario_file}"
        stages.append((f"route file {route_file}", [*vtypes, "--route-files", files], fix))
    for what, extra, fix in stages:
        refused = start_quietly(api, base + extra)
        _close(api)
        if refused is not None:
            return IrlsimError(f"{what}: SUMO refused it ({refused}): {fix}")
    return IrlsimError(f"SUMO failed to start on {net} ({why}), though it loads each of its input files")


def probe(api: Any, road: Road, vtypes_file: Path) -> None:
    """SUMO loads the road's network, the vehicle types and the scenario's demand (every route at once):
    else one IrlsimError line naming the file it refused, before any episode (collect, drive check this
    once, so that such an error is not an episode's, retried and marked failed)."""
    check_inputs(vtypes_file, road.demand, road.additional)
    files = additional_files(road, vtypes_file)
    cmd = [sumo_binary("sumo"), "--net-file", str(road.net_file), "--additional-files", files]
    if road.demand:
        cmd += ["--route-files", ",".join(str(p) for p in road.demand)]
    why = start_quietly(api, [*cmd, *QUIET, "--route-steps", "0", "--begin", "0"])
    _close(api)
    if why is not None:
        raise refusal(api, road, vtypes_file, why)


#: options that keep SUMO quiet
QUIET = ("--no-step-log", "true", "--no-warnings", "true")


def _close(api: Any) -> None:
    try:
        api.close()
    except Exception:  # not started, or gone: nothing to release
        pass


def sumo_stopped(error: BaseException) -> bool:
    """``error`` is libsumo's (or traci's) saying no more than that SUMO stopped: 'Process Error'."""
    return type(error).__module__.split(".")[0] in ("libsumo", "traci") and str(error).strip() in (
        "",
        "Process Error",
    )


#: a method of a simulation (:func:`reports_sumo_errors`)
F = TypeVar("F", bound=Callable[..., Any])


#: the name of a SUMO error log: the process that made it, and a unique part
LOG_PREFIX = "irlsim-sumo-"

#: whether this process removed the logs of ended processes yet (:func:`remove_stale_logs`)
_SWEPT = False


def _pid_of(log: Path) -> int | None:
    pid = log.name[len(LOG_PREFIX) :].split("-", 1)[0]
    return int(pid) if pid.isdigit() else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)  # signal 0: asks only whether the process exists
    except ProcessLookupError:
        return False
    except OSError:  # another user's process, or no such check here: kept
        return True
    return True


def remove_stale_logs(folder: Path | None = None) -> int:
    """Remove the SUMO error logs whose process is gone (a worker killed, or one that ended by
    ``os._exit``, cannot remove its own); POSIX only, elsewhere nothing is removed. The number removed."""
    if os.name != "posix":
        return 0
    removed = 0
    for log in Path(folder or tempfile.gettempdir()).glob(f"{LOG_PREFIX}*.log"):
        pid = _pid_of(log)
        if pid is not None and pid != os.getpid() and not _alive(pid):
            try:
                log.unlink(missing_ok=True)
            except OSError:  # another user's, in a shared temporary folder
                continue
            removed += 1
    return removed


class SumoErrorLog:
    """Where SUMO writes its errors (``--error-log``), read when libsumo stops an episode with nothing but
    'Process Error': SUMO's own reason is written to the process's stderr, where a progress bar hides it,
    and is lost to the line an episode's failure is reported by. A file in the temporary folder, unique
    to its simulation and named by its process; :meth:`remove` when the simulation closes (also when it
    is collected, at the latest at exit), and by the next process's first log where the process ended
    without (killed, or a worker's ``os._exit``)."""

    def __init__(self) -> None:
        global _SWEPT
        if not _SWEPT:
            _SWEPT = True
            remove_stale_logs()
        self.path = Path(tempfile.gettempdir()) / f"{LOG_PREFIX}{os.getpid()}-{uuid.uuid4().hex}.log"

    def option(self) -> dict[str, str]:
        return {"--error-log": str(self.path)}

    def explain(self, error: Exception) -> Exception:
        """``error`` as one IrlsimError line with SUMO's last error, when libsumo said no more than
        'Process Error' and SUMO wrote one; else ``error`` itself."""
        if not sumo_stopped(error):
            return error
        try:
            errors = sumo_errors(self.path.read_text(errors="replace"))
        except OSError:
            return error
        if not errors:
            return error
        return IrlsimError(
            f"SUMO stopped the episode: {errors[-1]} (SUMO's own words): check what SUMO runs here, the "
            "[demonstrator]'s models and attributes or the scenario's files"
        )

    def remove(self) -> None:
        self.path.unlink(missing_ok=True)


def reports_sumo_errors(method: F) -> F:
    """A simulation method whose libsumo 'Process Error' is re-raised with SUMO's reason (the
    simulation's ``errors``, a :class:`SumoErrorLog`): SUMO has quit, and the simulation is closed first,
    which flushes SUMO's log. Every other exception passes unchanged."""

    @functools.wraps(method)
    def wrapper(self: Any, *args: Any, **kwargs: Any) -> Any:
        try:
            return method(self, *args, **kwargs)
        except IrlsimError:
            raise
        except Exception as e:  # libsumo raises its own exception types
            if not sumo_stopped(e):
                raise
            log, self.errors = self.errors, SumoErrorLog()  # close() removes the new one, not this
            self.close()
            explained = log.explain(e)
            log.remove()
            if explained is e:
                raise
            raise explained from e

    return wrapper  # type: ignore[return-value]
